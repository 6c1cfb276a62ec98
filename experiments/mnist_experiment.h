// The MNIST experiment of docs/experiments.md (Gordon et al. 2021, Sec. V-B):
// digit classification as a K = 10 armed bandit. The context is the PCA
// projection of the image (fitted on the training images), action a means
// "this is digit a" with loss 1 when wrong, and the post hoc context is a
// hidden random linear map of the full loss vector, so the post hoc model is
// exactly linear and easy to learn. Two measurements:
//  - learning speed under uniform exploration: test MSE of the context model
//    of both learners, of the post hoc model, and of the best linear model
//    (least squares with full feedback on all training data);
//  - cumulative regret of LinUCB with either learner on the test digits.
#ifndef BITEWISE_EXPERIMENTS_MNIST_EXPERIMENT_H_
#define BITEWISE_EXPERIMENTS_MNIST_EXPERIMENT_H_

#include <cstdint>
#include <vector>

#include "Eigen/Core"
#include "absl/status/statusor.h"
#include "experiments/idx.h"
#include "services/bandit/core/config.h"

namespace bitewise::experiments {

struct MnistConfig {
  int pca_components = 200;
  // Appends a constant 1 to every context. The learners have no intercept
  // and the PCA coordinates are centred, while the mean loss is 0.9: without
  // it even the best linear model predicts badly.
  bool intercept = true;
  int posthoc_dim = 10;  // d_p
  // Learning speed: rounds of uniform exploration, evaluated every
  // `eval_every` rounds (and at round 0).
  int exploration_rounds = 2000;
  int eval_every = 10;
  // Regret: rounds drawn with replacement from the test set; 0 = its size.
  int regret_rounds = 0;
  double alpha = 0.01;
  double lambda_c = 1000.0;
  double lambda_p = 1.0;
  // poLinUCB's phi_radius (BanditConfig::phi_radius).
  double phi_radius = bandit::BanditConfig().phi_radius;
  // Ridge of the full-feedback "best linear model" (tiny: it only has to
  // keep the solve well posed).
  double best_ridge = 1e-6;
};

// Contexts and full loss vectors of both splits.
struct MnistProblem {
  int num_actions = 10;
  Eigen::MatrixXd train_contexts;  // n_train x d_c
  Eigen::MatrixXd train_losses;    // n_train x K, 1 - one-hot(label)
  Eigen::MatrixXd test_contexts;
  Eigen::MatrixXd test_losses;
  Eigen::VectorXd pca_variances;  // of the kept components
};

// Pixels scaled to [0, 1], one image per row.
Eigen::MatrixXd ImagesToMatrix(const IdxImages& images);

// INVALID_ARGUMENT for mismatched counts, labels outside [0, 10) or too few
// samples for the PCA.
absl::StatusOr<MnistProblem> BuildMnistProblem(
    const IdxImages& train_images, const std::vector<uint8_t>& train_labels,
    const IdxImages& test_images, const std::vector<uint8_t>& test_labels,
    const MnistConfig& config);

// The hidden post hoc map B (d_p x K), p = B l: B = pinv(A) for A uniform
// in [0,1)^{K x d_p}, as in the researchers' MNIST script.
Eigen::MatrixXd DrawPosthocMap(int num_actions, int posthoc_dim, uint64_t seed);

// Test MSE of least squares with full feedback on all training data.
double BestLinearTestMse(const MnistProblem& problem, double ridge);

struct LearningCurve {
  std::vector<double> rounds;
  std::vector<double> context_only_mse;   // theta_a of context-only LinUCB
  std::vector<double> posthoc_mse;        // theta_a of the post hoc learner
  std::vector<double> posthoc_model_mse;  // phi_a^T p of the post hoc learner
};

// One trial of uniform exploration over training digits drawn with
// replacement; both learners see the same digits and actions.
absl::StatusOr<LearningCurve> RunLearningSpeedTrial(const MnistProblem& problem,
                                                    const MnistConfig& config,
                                                    uint64_t seed);

// Cumulative regret (= mistakes, since the best loss is 0) after each round
// of LinUCB with `learner` on test digits drawn with replacement.
absl::StatusOr<std::vector<double>> RunMnistRegretTrial(
    const MnistProblem& problem, const MnistConfig& config,
    bandit::Learner learner, uint64_t seed);

}  // namespace bitewise::experiments

#endif  // BITEWISE_EXPERIMENTS_MNIST_EXPERIMENT_H_
