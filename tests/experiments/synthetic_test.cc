#include "experiments/synthetic.h"

#include <vector>

#include "experiments/trial_stats.h"
#include "gtest/gtest.h"
#include "services/domain/random.h"

namespace bitewise::experiments {
namespace {

using bandit::Learner;

TEST(SyntheticTest, WorldIsAPureFunctionOfTheSeedAndLossesLieInUnitRange) {
  SyntheticConfig config;
  config.context_dim = 20;
  config.rounds = 50;
  const SyntheticWorld a = DrawSyntheticWorld(config, 7);
  const SyntheticWorld b = DrawSyntheticWorld(config, 7);
  const SyntheticWorld c = DrawSyntheticWorld(config, 8);
  EXPECT_EQ(a.contexts, b.contexts);
  EXPECT_EQ(a.phi, b.phi);
  EXPECT_NE(a.contexts, c.contexts);
  for (int t = 0; t < config.rounds; ++t) {
    const Eigen::VectorXd mean =
        a.phi * a.contexts.row(t).head(config.posthoc_dim).transpose();
    EXPECT_GE(mean.minCoeff(), 0.0);
    EXPECT_LT(mean.maxCoeff(), 1.0);
  }
}

TEST(SyntheticTest, CumulativeRegretIsNonNegativeAndNondecreasing) {
  SyntheticConfig config;
  config.context_dim = 20;
  config.rounds = 300;
  for (SyntheticLoss loss :
       {SyntheticLoss::kLinear, SyntheticLoss::kBernoulli}) {
    config.loss = loss;
    const SyntheticWorld world = DrawSyntheticWorld(config, 3);
    for (Learner learner : {Learner::kContextOnly, Learner::kPostHoc}) {
      auto regret = RunSyntheticTrial(config, world, learner);
      ASSERT_TRUE(regret.ok()) << regret.status();
      ASSERT_EQ(regret->size(), 300u);
      EXPECT_GE(regret->front(), 0.0);
      for (size_t t = 1; t < regret->size(); ++t) {
        EXPECT_GE((*regret)[t], (*regret)[t - 1]) << "round " << t;
      }
      // Per-round regret is a difference of expected losses in [0, 1).
      EXPECT_LT(regret->back(), 300.0);
    }
  }
}

// The paper's claim in its easiest form: with d_c = 100 the context-only
// learner must learn 100 coordinates per action, the post hoc learner only
// the 3 that matter. Seeded, so the margin is a fixed property of the code.
TEST(SyntheticTest, PostHocBeatsContextOnlyAtHighDimensionByAMargin) {
  SyntheticConfig config;
  config.context_dim = 100;
  config.rounds = 1000;
  std::vector<std::vector<double>> diff;
  double context_only_total = 0.0;
  for (int trial = 0; trial < 8; ++trial) {
    const SyntheticWorld world =
        DrawSyntheticWorld(config, random::MixSeed(11, trial));
    auto c = RunSyntheticTrial(config, world, Learner::kContextOnly);
    auto p = RunSyntheticTrial(config, world, Learner::kPostHoc);
    ASSERT_TRUE(c.ok() && p.ok());
    diff.push_back(Difference(*c, *p));
    context_only_total += c->back();
  }
  const CurveSummary d = SummarizeCurves(diff);
  // At least 15% less regret, and the gain is several standard errors.
  EXPECT_GT(d.mean.back(), 0.15 * context_only_total / 8);
  EXPECT_GT(d.mean.back(), 3.0 * d.standard_error.back());
}

TEST(TrialStatsTest, MeanAndStandardErrorMatchHandComputation) {
  const CurveSummary s = SummarizeCurves({{1.0, 2.0}, {3.0, 2.0}, {5.0, 2.0}});
  EXPECT_DOUBLE_EQ(s.mean[0], 3.0);
  EXPECT_DOUBLE_EQ(s.standard_error[0], 2.0 / std::sqrt(3.0));
  EXPECT_DOUBLE_EQ(s.mean[1], 2.0);
  EXPECT_DOUBLE_EQ(s.standard_error[1], 0.0);
}

}  // namespace
}  // namespace bitewise::experiments
