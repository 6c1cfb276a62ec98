// A user's bandit configuration (services/bandit/core/config.h): the
// defaults are valid, every out-of-range field is refused naming it, and
// the names of learners, strategies and the default actions.
#include "services/bandit/core/config.h"

#include <cmath>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "services/domain/skewering_actions.h"
#include "tests/common/status_matchers.h"

namespace bitewise::bandit {
namespace {

using ::bitewise::testing::IsOk;
using ::bitewise::testing::StatusIs;
using ::testing::ElementsAre;
using ::testing::HasSubstr;

constexpr double kInf = std::numeric_limits<double>::infinity();
const double kNan = std::nan("");

TEST(ConfigTest, TheDefaultsAreThePapersAndValid) {
  const BanditConfig config;
  EXPECT_THAT(ValidateConfig(config), IsOk());
  EXPECT_EQ(config.learner, Learner::kPostHoc);
  EXPECT_EQ(config.strategy, Strategy::kLinUcb);
  EXPECT_EQ(config.context_dim, 2048);
  EXPECT_EQ(config.posthoc_dim, 4);
  EXPECT_EQ(config.num_actions(), 6);
  EXPECT_FALSE(config.prior.enabled());
  EXPECT_EQ(config.prior.kappa_c(), 0.0);
}

TEST(ConfigTest, TheDefaultActionsAreTheSixSkeweringActionsInOrder) {
  EXPECT_THAT(DefaultActionNames(),
              ElementsAre("VS0", "VS90", "TV0", "TV90", "TA0", "TA90"));
  const std::vector<std::string> names = DefaultActionNames();
  ASSERT_EQ(names.size(), domain::kSkeweringActions.size());
  for (size_t i = 0; i < names.size(); ++i) {
    EXPECT_EQ(names[i], domain::kSkeweringActions[i].name);
  }
}

TEST(ConfigTest, StrategiesAndLearnersHaveNamesAndUnknownOnesSaySo) {
  EXPECT_STREQ(StrategyName(Strategy::kLinUcb), "linucb");
  EXPECT_STREQ(StrategyName(Strategy::kGreedy), "greedy");
  EXPECT_STREQ(StrategyName(Strategy::kEpsilonGreedy), "epsilon_greedy");
  EXPECT_STREQ(StrategyName(Strategy::kThompson), "thompson");
  EXPECT_STREQ(StrategyName(Strategy::kUniform), "uniform");
  EXPECT_STREQ(StrategyName(static_cast<Strategy>(0)), "unknown");
  EXPECT_STREQ(StrategyName(static_cast<Strategy>(6)), "unknown");
  EXPECT_STREQ(LearnerName(static_cast<Learner>(0)), "unknown");
  EXPECT_TRUE(UsesPosthoc(Learner::kPostHoc));
  EXPECT_FALSE(UsesPosthoc(Learner::kContextOnly));
  EXPECT_TRUE(UsesPosthoc(Learner::kPoLinUcb));
  EXPECT_FALSE(UsesPosthoc(static_cast<Learner>(42)));
}

// One field out of range, and the words its refusal must contain.
struct BadField {
  std::string field;
  std::function<void(BanditConfig&)> spoil;
};

TEST(ConfigTest, EachOutOfRangeFieldIsRefusedNamingIt) {
  const std::vector<BadField> cases = {
      {"learner: unknown value 7",
       [](BanditConfig& c) { c.learner = static_cast<Learner>(7); }},
      {"strategy: unknown value 0",
       [](BanditConfig& c) { c.strategy = static_cast<Strategy>(0); }},
      {"strategy: unknown value 6",
       [](BanditConfig& c) { c.strategy = static_cast<Strategy>(6); }},
      {"alpha", [](BanditConfig& c) { c.alpha = -0.001; }},
      {"alpha", [](BanditConfig& c) { c.alpha = kNan; }},
      {"alpha", [](BanditConfig& c) { c.alpha = kInf; }},
      {"lambda_c", [](BanditConfig& c) { c.lambda_c = 0.0; }},
      {"lambda_c", [](BanditConfig& c) { c.lambda_c = kInf; }},
      {"lambda_p", [](BanditConfig& c) { c.lambda_p = -1.0; }},
      {"lambda_p", [](BanditConfig& c) { c.lambda_p = kNan; }},
      {"phi_radius", [](BanditConfig& c) { c.phi_radius = -0.1; }},
      {"phi_radius", [](BanditConfig& c) { c.phi_radius = kNan; }},
      {"epsilon", [](BanditConfig& c) { c.epsilon = 1.0000001; }},
      {"epsilon", [](BanditConfig& c) { c.epsilon = -0.1; }},
      {"epsilon", [](BanditConfig& c) { c.epsilon = kNan; }},
      {"context_dim: must be in [1, 65536], got 0",
       [](BanditConfig& c) { c.context_dim = 0; }},
      {"context_dim: must be in [1, 65536], got 65537",
       [](BanditConfig& c) { c.context_dim = 65537; }},
      {"posthoc_dim: must be in [0, 1024], got -1",
       [](BanditConfig& c) { c.posthoc_dim = -1; }},
      {"posthoc_dim: must be in [0, 1024], got 1025",
       [](BanditConfig& c) { c.posthoc_dim = 1025; }},
      {"posthoc_dim: the posthoc learner needs posthoc_dim >= 1",
       [](BanditConfig& c) { c.posthoc_dim = 0; }},
      {"action_names: need between 1 and 256 actions, got 0",
       [](BanditConfig& c) { c.action_names.clear(); }},
      {"action_names: need between 1 and 256 actions, got 257",
       [](BanditConfig& c) {
         c.action_names.clear();
         for (int i = 0; i < 257; ++i) {
           c.action_names.push_back("a" + std::to_string(i));
         }
       }},
      {"action_names[2]: must be 1-64 bytes, got 0",
       [](BanditConfig& c) { c.action_names[2] = ""; }},
      {"action_names[1]: must be 1-64 bytes, got 65",
       [](BanditConfig& c) { c.action_names[1] = std::string(65, 'x'); }},
      {"action_names[4]: duplicate name \"VS90\"",
       [](BanditConfig& c) { c.action_names[4] = "VS90"; }},
      {"prior.pool_version: must be >= 0, got -1",
       [](BanditConfig& c) { c.prior.pool_version = -1; }},
      {"prior.rounds", [](BanditConfig& c) { c.prior.rounds = -1.0; }},
      {"prior.rounds", [](BanditConfig& c) { c.prior.rounds = kNan; }},
      // Its ridge rounds x msn would overflow to an infinite model.
      {"prior.rounds: must be in [0, 1e+06], got 1e+300",
       [](BanditConfig& c) { c.prior.rounds = 1e300; }},
  };
  for (const BadField& bad : cases) {
    BanditConfig config;
    bad.spoil(config);
    EXPECT_THAT(
        ValidateConfig(config),
        StatusIs(absl::StatusCode::kInvalidArgument, HasSubstr(bad.field)))
        << bad.field;
  }
}

TEST(ConfigTest, TheEdgesOfEachRangeAreAccepted) {
  const std::vector<std::function<void(BanditConfig&)>> edges = {
      [](BanditConfig& c) { c.alpha = 0.0; },
      [](BanditConfig& c) { c.lambda_c = std::numeric_limits<double>::min(); },
      [](BanditConfig& c) { c.phi_radius = 0.0; },
      [](BanditConfig& c) { c.epsilon = 0.0; },
      [](BanditConfig& c) { c.epsilon = 1.0; },
      [](BanditConfig& c) { c.context_dim = 1; },
      [](BanditConfig& c) { c.context_dim = 65536; },
      [](BanditConfig& c) { c.posthoc_dim = 1024; },
      [](BanditConfig& c) { c.action_names = {"only"}; },
      [](BanditConfig& c) { c.action_names[0] = std::string(64, 'x'); },
      [](BanditConfig& c) {
        c.action_names.clear();
        for (int i = 0; i < 256; ++i) {
          c.action_names.push_back("a" + std::to_string(i));
        }
      },
      // The context-only learner needs no post hoc context.
      [](BanditConfig& c) {
        c.learner = Learner::kContextOnly;
        c.posthoc_dim = 0;
      },
      // A prior of no rounds is off: its vectors are not looked at.
      [](BanditConfig& c) {
        c.prior.pool_version = 3;
        c.prior.rounds = 0.0;
      },
  };
  for (size_t i = 0; i < edges.size(); ++i) {
    BanditConfig config;
    edges[i](config);
    EXPECT_THAT(ValidateConfig(config), IsOk()) << "edge " << i;
  }
}

BanditConfig WithPrior(Learner learner) {
  BanditConfig config;
  config.learner = learner;
  config.context_dim = 3;
  config.posthoc_dim = 2;
  config.action_names = {"a", "b"};
  config.prior.pool_version = 1;
  config.prior.rounds = 4.0;
  config.prior.context_msn = 0.5;
  config.prior.posthoc_msn = 2.0;
  config.prior.theta0 = {{1, 2, 3}, {4, 5, 6}};
  config.prior.phi0 = {{1, 2}, {3, 4}};
  return config;
}

TEST(ConfigTest, AnEnabledPriorMustFitTheActionsAndDimensions) {
  ASSERT_THAT(ValidateConfig(WithPrior(Learner::kPostHoc)), IsOk());
  const BanditConfig base = WithPrior(Learner::kPostHoc);
  EXPECT_DOUBLE_EQ(base.prior.kappa_c(), 4.0 * 0.5);
  EXPECT_DOUBLE_EQ(base.prior.kappa_p(), 4.0 * 2.0);

  const std::vector<BadField> cases = {
      {"prior.theta0: expected 2 actions, got 1",
       [](BanditConfig& c) { c.prior.theta0.pop_back(); }},
      {"prior.theta0[1]: expected 3 values, got 2",
       [](BanditConfig& c) { c.prior.theta0[1].pop_back(); }},
      {"prior.theta0[0]: must be finite",
       [](BanditConfig& c) { c.prior.theta0[0][2] = kInf; }},
      {"prior.phi0: expected 2 actions, got 3",
       [](BanditConfig& c) {
         c.prior.phi0.push_back({5, 6});
       }},
      {"prior.phi0[0]: expected 2 values, got 3",
       [](BanditConfig& c) { c.prior.phi0[0].push_back(1); }},
      {"prior.phi0[1]: must be finite",
       [](BanditConfig& c) { c.prior.phi0[1][0] = kNan; }},
      {"context_msn", [](BanditConfig& c) { c.prior.context_msn = 0.0; }},
      {"context_msn", [](BanditConfig& c) { c.prior.context_msn = kNan; }},
      {"posthoc_msn", [](BanditConfig& c) { c.prior.posthoc_msn = -1.0; }},
      {"prior.rounds", [](BanditConfig& c) { c.prior.rounds = kInf; }},
  };
  for (const BadField& bad : cases) {
    BanditConfig config = WithPrior(Learner::kPostHoc);
    bad.spoil(config);
    EXPECT_THAT(
        ValidateConfig(config),
        StatusIs(absl::StatusCode::kInvalidArgument, HasSubstr(bad.field)))
        << bad.field;
  }

  // The context-only learner's prior has no post hoc part to check.
  BanditConfig context_only = WithPrior(Learner::kContextOnly);
  context_only.prior.phi0.clear();
  context_only.prior.posthoc_msn = 0.0;
  EXPECT_THAT(ValidateConfig(context_only), IsOk());
  context_only.prior.theta0[0].push_back(7);
  EXPECT_THAT(ValidateConfig(context_only),
              StatusIs(absl::StatusCode::kInvalidArgument,
                       HasSubstr("prior.theta0[0]: expected 3 values")));
}

}  // namespace
}  // namespace bitewise::bandit
