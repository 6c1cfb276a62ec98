#include "experiments/mnist_experiment.h"

#include <random>
#include <vector>

#include "Eigen/Dense"
#include "gtest/gtest.h"
#include "services/domain/random.h"

namespace bitewise::experiments {
namespace {

// Tiny "digits": 10x10 images where class k lights a class-specific set of
// pixels, plus noise, so a linear model separates them well.
void MakeDigits(int count, uint64_t seed, IdxImages& images,
                std::vector<uint8_t>& labels) {
  std::mt19937_64 rng(seed);
  images.count = count;
  images.rows = 10;
  images.cols = 10;
  images.pixels.assign(count * 100, 0);
  labels.resize(count);
  for (int i = 0; i < count; ++i) {
    const int digit = random::UniformIndex(rng, 10);
    labels[i] = digit;
    for (int j = 0; j < 100; ++j) {
      const bool lit = (j % 10 == digit) || (j / 10 == digit);
      images.pixels[i * 100 + j] =
          static_cast<uint8_t>((lit ? 200 : 0) + random::UniformIndex(rng, 50));
    }
  }
}

class MnistExperimentTest : public ::testing::Test {
 protected:
  void SetUp() override {
    IdxImages train, test;
    std::vector<uint8_t> train_labels, test_labels;
    MakeDigits(600, 1, train, train_labels);
    MakeDigits(200, 2, test, test_labels);
    config_.pca_components = 60;
    config_.exploration_rounds = 200;
    config_.eval_every = 50;
    config_.regret_rounds = 300;
    config_.lambda_c = 10.0;
    auto problem =
        BuildMnistProblem(train, train_labels, test, test_labels, config_);
    ASSERT_TRUE(problem.ok()) << problem.status();
    problem_ = *std::move(problem);
  }

  MnistConfig config_;
  MnistProblem problem_;
};

TEST_F(MnistExperimentTest, ProblemHasPcaContextsWithInterceptAndLosses) {
  EXPECT_EQ(problem_.train_contexts.cols(), 61);  // 60 PCA + intercept
  EXPECT_EQ(problem_.train_losses.cols(), 10);
  // Exactly one zero loss (the right digit) per row.
  for (int i = 0; i < problem_.test_losses.rows(); ++i) {
    EXPECT_DOUBLE_EQ(problem_.test_losses.row(i).sum(), 9.0);
  }
  EXPECT_DOUBLE_EQ(problem_.train_contexts.col(60).minCoeff(), 1.0);
}

TEST_F(MnistExperimentTest, PosthocMapIsInvertibleSoLossIsLinearInIt) {
  const Eigen::MatrixXd b = DrawPosthocMap(10, 10, 3);
  const Eigen::VectorXd loss = problem_.test_losses.row(0).transpose();
  const Eigen::VectorXd p = b * loss;
  EXPECT_TRUE(b.fullPivLu().solve(p).isApprox(loss, 1e-8));
}

TEST_F(MnistExperimentTest, LearningCurvesStartAtZeroModelAndImprove) {
  auto curve = RunLearningSpeedTrial(problem_, config_, 4);
  ASSERT_TRUE(curve.ok()) << curve.status();
  ASSERT_EQ(curve->rounds.size(), 5u);  // rounds 0, 50, ..., 200
  // Untrained models predict 0 for a loss that is 1 nine times in ten.
  EXPECT_DOUBLE_EQ(curve->context_only_mse.front(), 0.9);
  EXPECT_DOUBLE_EQ(curve->posthoc_mse.front(), 0.9);
  EXPECT_DOUBLE_EQ(curve->posthoc_model_mse.front(), 0.9);
  // With 61 context dimensions and about 20 rounds per action, only the
  // learner that every round teaches (through the post hoc model) gets far.
  EXPECT_LT(curve->posthoc_model_mse.back(), 0.5 * 0.9);
  EXPECT_LT(curve->posthoc_mse.back(), curve->context_only_mse.back());
  // Nothing trained on bandit feedback beats least squares on full feedback
  // by more than noise.
  const double best = BestLinearTestMse(problem_, 1e-6);
  EXPECT_LT(best, 0.1);
  EXPECT_GT(curve->posthoc_mse.back(), best - 0.01);
}

TEST_F(MnistExperimentTest, RegretCountsMistakesAndPostHocMakesFewer) {
  auto c =
      RunMnistRegretTrial(problem_, config_, bandit::Learner::kContextOnly, 5);
  auto p = RunMnistRegretTrial(problem_, config_, bandit::Learner::kPostHoc, 5);
  ASSERT_TRUE(c.ok() && p.ok());
  for (const auto* r : {&*c, &*p}) {
    ASSERT_EQ(r->size(), 300u);
    for (size_t t = 0; t < r->size(); ++t) {
      // Integral and growing by 0 or 1 per round: a mistake count.
      const double prev = t == 0 ? 0.0 : (*r)[t - 1];
      EXPECT_TRUE((*r)[t] == prev || (*r)[t] == prev + 1.0) << t;
    }
  }
  EXPECT_LT(p->back(), c->back());
}

}  // namespace
}  // namespace bitewise::experiments
