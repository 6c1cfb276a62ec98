// The learners' table (services/bandit/core/learners.h): numbers, names and
// factories agree, every learner's model comes back the same from its log
// and from its saved state, and a number or name no learner has is refused.
#include "services/bandit/core/learners.h"

#include <memory>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "gmock/gmock.h"
#include "gtest/gtest.h"
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
