// The learners' table (services/bandit/core/learners.h): numbers, names and
// factories agree, every learner's model comes back the same from its log
// and from its saved state, and a number or name no learner has is refused.
#include "services/bandit/core/learners.h"

#include <cmath>
#include <memory>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "tests/bandit/dense_reference.h"
#include "tests/common/near.h"

namespace bitewise::bandit {
namespace {

using ::testing::HasSubstr;

BanditConfig SmallConfig(Learner learner) {
  BanditConfig config;
  config.learner = learner;
  config.context_dim = 6;
  config.posthoc_dim = 3;
  config.lambda_c = 2.0;
  return config;
}

std::vector<Round> RandomRounds(const BanditConfig& config, int n,
                                std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<Round> rounds(n);
  for (Round& r : rounds) {
    r.context.resize(config.context_dim);
    for (double& v : r.context) v = u(rng);
    r.posthoc.resize(config.posthoc_dim);
    for (double& v : r.posthoc) v = u(rng) - 0.5;
    r.action = static_cast<int>(u(rng) * config.num_actions());
    r.loss = u(rng) < 0.4 ? 1.0 : 0.0;
  }
  return rounds;
}

TEST(LearnersTest, NumbersNamesAndLookupsAgree) {
  std::set<std::string> names;
  int previous = 0;
  for (const LearnerSpec& spec : Learners()) {
    EXPECT_GT(static_cast<int>(spec.learner), previous) << spec.name;
    previous = static_cast<int>(spec.learner);
    EXPECT_EQ(FindLearner(spec.learner), &spec);
    EXPECT_EQ(FindLearnerByName(spec.name), &spec);
    EXPECT_STREQ(LearnerName(spec.learner), spec.name);
    EXPECT_THAT(LearnerNames(), HasSubstr(spec.name));
    EXPECT_GT(std::string(spec.described).size(), 0u);
    names.insert(spec.name);
  }
  EXPECT_EQ(names.size(), Learners().size());
  EXPECT_EQ(FindLearner(static_cast<Learner>(0)), nullptr);
  EXPECT_EQ(FindLearner(static_cast<Learner>(99)), nullptr);
  EXPECT_EQ(FindLearnerByName("linucb"), nullptr);
  EXPECT_EQ(FindLearnerByName(""), nullptr);
  EXPECT_FALSE(FindLearnerByName("context_only")->uses_posthoc);
  EXPECT_TRUE(FindLearnerByName("posthoc")->uses_posthoc);
  EXPECT_TRUE(FindLearnerByName("polinucb")->uses_posthoc);
}

// Each factory makes its own learner, and the three ways to a model (round
// by round, rebuilt from the log, loaded from a saved state) agree.
TEST(LearnersTest, CreateRebuildAndLoadAgreeForEveryLearner) {
  for (const LearnerSpec& spec : Learners()) {
    SCOPED_TRACE(spec.name);
    const BanditConfig config = SmallConfig(spec.learner);
    std::mt19937_64 rng(17);
    const std::vector<Round> rounds = RandomRounds(config, 40, rng);
    absl::StatusOr<std::unique_ptr<LearnerModel>> live = CreateModel(config);
    ASSERT_TRUE(live.ok()) << live.status();
    EXPECT_EQ((*live)->config().learner, spec.learner);
    for (const Round& r : rounds) (*live)->Update(r, nullptr);
    absl::StatusOr<std::unique_ptr<LearnerModel>> rebuilt =
        RebuildModel(config, rounds);
    ASSERT_TRUE(rebuilt.ok()) << rebuilt.status();
    std::string state;
    (*live)->SaveState(&state);
    absl::StatusOr<std::unique_ptr<LearnerModel>> loaded =
        LoadModel(config, state);
    ASSERT_TRUE(loaded.ok()) << loaded.status();
    EXPECT_EQ((*loaded)->TotalRounds(), 40);
    const std::vector<double> probe = RandomRounds(config, 1, rng)[0].context;
    const std::vector<ActionEstimate> a = (*live)->Estimate(probe, nullptr);
    const std::vector<ActionEstimate> b = (*rebuilt)->Estimate(probe, nullptr);
    const std::vector<ActionEstimate> c = (*loaded)->Estimate(probe, nullptr);
    for (int i = 0; i < config.num_actions(); ++i) {
      EXPECT_TRUE(bitewise::testing::RelNear(a[i].lcb, b[i].lcb, 1e-10)) << i;
      EXPECT_EQ(a[i].lcb, c[i].lcb) << i;  // a saved state is exact
    }
    // Another learner's state is refused, not misread.
    for (const LearnerSpec& other : Learners()) {
      if (other.learner == spec.learner) continue;
      EXPECT_FALSE(LoadModel(SmallConfig(other.learner), state).ok())
          << other.name;
    }
  }
}

// A tiny ridge with large inputs: a Cholesky pivot lambda + |x|^2 - |l|^2
// cancels to rounding noise when lambda / |x|^2 nears 1e-16 (with
// lambda = 1e-6 and values of 1e6 every learner gave NaN within ten
// rounds). Requests beyond kMaxSquaredNormPerRidge * lambda are refused,
// naming the ridge; at the bound, live and rebuilt, every estimate stays
// finite, and so does a log beyond it replayed (the pivots' floors).
TEST(LearnersTest, ATinyRidgeRefusesWhatItCannotKeepExact) {
  for (const LearnerSpec& spec : Learners()) {
    SCOPED_TRACE(spec.name);
    BanditConfig config = SmallConfig(spec.learner);
    config.context_dim = 3;
    config.lambda_c = 1e-6;
    config.lambda_p = 1e-6;
    absl::StatusOr<std::unique_ptr<LearnerModel>> live = CreateModel(config);
    ASSERT_TRUE(live.ok()) << live.status();
    const std::vector<double> huge = {1e6, -1e6, 1e6};
    // Within the magnitude bound, so the model itself takes it (a stored
    // event is replayed under the rules of its day); a request is refused.
    EXPECT_TRUE((*live)->ValidateContext(huge).ok());
    absl::Status refused = ValidateInputScale(config, huge, {});
    EXPECT_EQ(refused.code(), absl::StatusCode::kInvalidArgument);
    EXPECT_THAT(refused.message(),
                HasSubstr("context: squared norm 3e+12 is over 1e+10 times "
                          "lambda_c (1e-06)"));
    if (spec.uses_posthoc) {
      refused = ValidateInputScale(config, {}, huge);
      EXPECT_EQ(refused.code(), absl::StatusCode::kInvalidArgument);
      EXPECT_THAT(refused.message(), HasSubstr("posthoc: squared norm"));
      EXPECT_THAT(refused.message(), HasSubstr("lambda_p (1e-06)"));
    }
    // Every value at the bound: |x|^2 = 1e10 * lambda.
    const double edge = std::sqrt(kMaxSquaredNormPerRidge * 1e-6 / 3) * 0.999;
    std::mt19937_64 rng(29);
    std::uniform_int_distribution<int> sign(0, 1);
    std::vector<Round> rounds = RandomRounds(config, 60, rng);
    for (Round& r : rounds) {
      for (double& v : r.context) v = sign(rng) ? edge : -edge;
      for (double& v : r.posthoc) v = sign(rng) ? edge : -edge;
    }
    auto finite = [&](const LearnerModel& model, int round) {
      for (const Round& probe : rounds) {
        for (const ActionEstimate& e : model.Estimate(probe.context)) {
          ASSERT_TRUE(std::isfinite(e.predicted_loss) &&
                      std::isfinite(e.width) && std::isfinite(e.lcb))
              << "after round " << round << ": " << e.predicted_loss << " "
              << e.width;
        }
      }
    };
    for (size_t i = 0; i < rounds.size(); ++i) {
      ASSERT_TRUE((*live)->ValidateRound(rounds[i]).ok()) << i;
      ASSERT_TRUE(
          ValidateInputScale(config, rounds[i].context, rounds[i].posthoc).ok())
          << i;
      (*live)->Update(rounds[i], nullptr);
      finite(**live, static_cast<int>(i));
      if (::testing::Test::HasFatalFailure()) return;
    }
    absl::StatusOr<std::unique_ptr<LearnerModel>> rebuilt =
        RebuildModel(config, rounds);
    ASSERT_TRUE(rebuilt.ok()) << rebuilt.status();
    finite(**rebuilt, -1);
    if (spec.learner != Learner::kPoLinUcb) {
      // Against the dense float64 reference: the condition number here
      // (about 1e10 times the rounds) leaves fewer digits than the 1e-8 of
      // ordinary problems, but six digits.
      const std::vector<testing::DenseActionModel> ref =
          testing::DenseReference(config, rounds);
      double worst = 0.0;
      for (const Round& probe : rounds) {
        const std::vector<ActionEstimate> est =
            (*live)->Estimate(probe.context);
        for (int a = 0; a < config.num_actions(); ++a) {
          const double want = ref[a].theta.dot(AsVector(probe.context));
          worst = std::max(worst, std::abs(est[a].predicted_loss - want) /
                                      std::max(1.0, std::abs(want)));
        }
      }
      EXPECT_LT(worst, 1e-4);  // measured 1.2e-6
    }
    // Beyond the bound, as an old log replayed: the floors keep it finite.
    std::vector<Round> beyond = rounds;
    for (Round& r : beyond) {
      for (double& v : r.context) v = v > 0 ? 1e6 : -1e6;
      for (double& v : r.posthoc) v = v > 0 ? 1e6 : -1e6;
    }
    absl::StatusOr<std::unique_ptr<LearnerModel>> replayed =
        RebuildModel(config, beyond);
    ASSERT_TRUE(replayed.ok()) << replayed.status();
    finite(**replayed, -2);
  }
}

TEST(LearnersTest, AnUnknownLearnerIsRefusedByTheFactories) {
  BanditConfig config = SmallConfig(static_cast<Learner>(42));
  const absl::Status created = CreateModel(config).status();
  EXPECT_EQ(created.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(created.message(), HasSubstr("learner"));
  EXPECT_EQ(RebuildModel(config, {}).status().code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(LoadModel(config, "").status().code(),
            absl::StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace bitewise::bandit
