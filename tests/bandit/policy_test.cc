// The action choice (services/bandit/core/policy.h) of every strategy:
// LinUCB's lowest lcb with ties to the lowest index, epsilon-greedy's and
// Thompson sampling's propensities and frequencies, uniform, greedy; each
// draw reproducible from its select index.
#include "services/bandit/core/policy.h"

#include <limits>
#include <random>
#include <vector>

#include "gtest/gtest.h"
#include "services/bandit/core/config.h"
#include "services/bandit/core/rounds.h"

namespace bitewise::bandit {
namespace {

TEST(PolicyTest, LinUcbTiesGoToTheLowestIndex) {
  BanditConfig config;
  std::mt19937_64 rng = SelectRng(1, 0);
  std::vector<ActionEstimate> est(6, ActionEstimate{0.5, 0.1, 0.4});
  est[3].lcb = 0.3;
  est[5].lcb = 0.3;
  const Choice choice = ChooseAction(config, est, rng);
  EXPECT_EQ(choice.action, 3);
  EXPECT_EQ(choice.propensity, 1.0);
}

// A NaN estimate loses every comparison: an argmin would pick action 0 (or
// never the NaN action) without a word. The engine checks first.
TEST(PolicyTest, ANonFiniteEstimateIsRefusedNamingTheAction) {
  std::vector<ActionEstimate> est(6);
  for (int a = 0; a < 6; ++a) est[a].lcb = est[a].predicted_loss = 0.1 * a;
  EXPECT_TRUE(CheckEstimatesFinite(est).ok());
  est[3].width = std::numeric_limits<double>::quiet_NaN();
  absl::Status refused = CheckEstimatesFinite(est);
  EXPECT_EQ(refused.code(), absl::StatusCode::kInternal);
  EXPECT_NE(refused.message().find("estimate for action 3 is not finite"),
            absl::string_view::npos)
      << refused.message();
  est[3].width = 0;
  est[5].lcb = -std::numeric_limits<double>::infinity();
  EXPECT_EQ(CheckEstimatesFinite(est).code(), absl::StatusCode::kInternal);
}

TEST(PolicyTest, EpsilonGreedyPropensityAndFrequency) {
  BanditConfig config;
  config.strategy = Strategy::kEpsilonGreedy;
  config.epsilon = 0.3;
  std::vector<ActionEstimate> est(6, ActionEstimate{0.5, 0.0, 0.5});
  est[2].predicted_loss = 0.1;
  int greedy = 0;
  const int n = 20000;
  for (int i = 0; i < n; ++i) {
    std::mt19937_64 rng = SelectRng(7, i);
    const Choice choice = ChooseAction(config, est, rng);
    if (choice.action == 2) {
      ++greedy;
      EXPECT_DOUBLE_EQ(choice.propensity, 0.7 + 0.05);
    } else {
      EXPECT_DOUBLE_EQ(choice.propensity, 0.05);
    }
  }
  EXPECT_NEAR(static_cast<double>(greedy) / n, 0.75, 0.015);
}

TEST(PolicyTest, ThompsonMeanIsThetaAndDrawsAreReproducible) {
  BanditConfig config;
  config.strategy = Strategy::kThompson;
  config.alpha = 1.0;
  // Two actions with equal width: the lower mean wins more often, in
  // proportion to P(N(0.4, 0.2^2) < N(0.5, 0.2^2)) = Phi(0.1/0.2828).
  config.action_names = {"a", "b"};
  std::vector<ActionEstimate> est = {{0.5, 0.2, 0.3}, {0.4, 0.2, 0.2}};
  int b_wins = 0;
  const int n = 20000;
  for (int i = 0; i < n; ++i) {
    std::mt19937_64 rng = SelectRng(11, i);
    const Choice choice = ChooseAction(config, est, rng);
    if (choice.action == 1) ++b_wins;
    std::mt19937_64 again = SelectRng(11, i);
    EXPECT_EQ(ChooseAction(config, est, again).action, choice.action);
    if (i < 50) {
      const double expected = choice.action == 1 ? 0.6382 : 0.3618;
      EXPECT_NEAR(choice.propensity, expected, 0.04);
    }
  }
  EXPECT_NEAR(static_cast<double>(b_wins) / n, 0.6382, 0.015);
}

TEST(PolicyTest, UniformIsUniform) {
  BanditConfig config;
  config.strategy = Strategy::kUniform;
  std::vector<ActionEstimate> est(6);
  std::vector<int> counts(6, 0);
  for (int i = 0; i < 12000; ++i) {
    std::mt19937_64 rng = SelectRng(3, i);
    const Choice choice = ChooseAction(config, est, rng);
    EXPECT_DOUBLE_EQ(choice.propensity, 1.0 / 6);
    ++counts[choice.action];
  }
  for (int c : counts) EXPECT_NEAR(c, 2000, 150);
}

TEST(PolicyTest, GreedyIgnoresWidth) {
  BanditConfig config;
  config.strategy = Strategy::kGreedy;
  std::vector<ActionEstimate> est = {{0.2, 0.0, 0.2}, {0.3, 5.0, -4.7}};
  config.action_names = {"a", "b"};
  std::mt19937_64 rng = SelectRng(0, 0);
  EXPECT_EQ(ChooseAction(config, est, rng).action, 0);
}

}  // namespace
}  // namespace bitewise::bandit
