#include "experiments/mnist_experiment.h"

#include <memory>
#include <random>

#include "Eigen/Dense"
#include "absl/strings/str_cat.h"
#include "experiments/pca.h"
#include "services/bandit/core/learners.h"
#include "services/bandit/core/policy.h"
#include "services/common/status_macros.h"
#include "services/domain/random.h"

namespace bitewise::experiments {
namespace {

constexpr int kDigits = 10;

absl::StatusOr<Eigen::MatrixXd> OneMinusOneHot(
    const std::vector<uint8_t>& labels) {
  Eigen::MatrixXd losses = Eigen::MatrixXd::Ones(labels.size(), kDigits);
  for (size_t i = 0; i < labels.size(); ++i) {
    if (labels[i] >= kDigits) {
      return absl::InvalidArgumentError(absl::StrCat(
          "label ", int{labels[i]}, " at index ", i, " is not a digit"));
    }
    losses(i, labels[i]) = 0.0;
  }
  return losses;
}

Eigen::MatrixXd WithIntercept(const Eigen::MatrixXd& x, bool intercept) {
  if (!intercept) return x;
  Eigen::MatrixXd out(x.rows(), x.cols() + 1);
  out << x, Eigen::VectorXd::Ones(x.rows());
  return out;
}

bandit::BanditConfig LearnerConfig(const MnistProblem& problem,
                                   const MnistConfig& config,
                                   bandit::Learner learner) {
  bandit::BanditConfig bc;
  bc.learner = learner;
  bc.strategy = bandit::Strategy::kLinUcb;
  bc.alpha = config.alpha;
  bc.lambda_c = config.lambda_c;
  bc.lambda_p = config.lambda_p;
  bc.phi_radius = config.phi_radius;
  bc.context_dim = static_cast<int>(problem.train_contexts.cols());
  bc.posthoc_dim = config.posthoc_dim;
  bc.action_names.clear();
  for (int a = 0; a < problem.num_actions; ++a) {
    bc.action_names.push_back(absl::StrCat("digit", a));
  }
  return bc;
}

std::vector<double> Row(const Eigen::MatrixXd& m, int i) {
  std::vector<double> v(m.cols());
  for (int j = 0; j < m.cols(); ++j) v[j] = m(i, j);
  return v;
}

double ContextModelTestMse(const bandit::LearnerModel& model,
                           const MnistProblem& problem) {
  Eigen::MatrixXd theta(problem.test_contexts.cols(), problem.num_actions);
  for (int a = 0; a < problem.num_actions; ++a) theta.col(a) = model.Theta(a);
  return (problem.test_contexts * theta - problem.test_losses).squaredNorm() /
         static_cast<double>(problem.test_losses.size());
}

}  // namespace

Eigen::MatrixXd ImagesToMatrix(const IdxImages& images) {
  const int dim = images.rows * images.cols;
  Eigen::MatrixXd out(images.count, dim);
  for (int i = 0; i < images.count; ++i) {
    for (int j = 0; j < dim; ++j) {
      out(i, j) = images.pixels[static_cast<size_t>(i) * dim + j] / 255.0;
    }
  }
  return out;
}

absl::StatusOr<MnistProblem> BuildMnistProblem(
    const IdxImages& train_images, const std::vector<uint8_t>& train_labels,
    const IdxImages& test_images, const std::vector<uint8_t>& test_labels,
    const MnistConfig& config) {
  if (static_cast<size_t>(train_images.count) != train_labels.size() ||
      static_cast<size_t>(test_images.count) != test_labels.size()) {
    return absl::InvalidArgumentError("image and label counts differ");
  }
  if (train_images.rows != test_images.rows ||
      train_images.cols != test_images.cols) {
    return absl::InvalidArgumentError("train and test image sizes differ");
  }
  if (test_images.count < 1) {
    return absl::InvalidArgumentError("the test set is empty");
  }
  MnistProblem problem;
  problem.num_actions = kDigits;
  ASSIGN_OR_RETURN(problem.train_losses, OneMinusOneHot(train_labels));
  ASSIGN_OR_RETURN(problem.test_losses, OneMinusOneHot(test_labels));
  ASSIGN_OR_RETURN(const Pca pca, Pca::Fit(ImagesToMatrix(train_images),
                                           config.pca_components));
  problem.pca_variances = pca.variances();
  problem.train_contexts = WithIntercept(
      pca.Transform(ImagesToMatrix(train_images)), config.intercept);
  problem.test_contexts = WithIntercept(
      pca.Transform(ImagesToMatrix(test_images)), config.intercept);
  return problem;
}

Eigen::MatrixXd DrawPosthocMap(int num_actions, int posthoc_dim,
                               uint64_t seed) {
  std::mt19937_64 rng(seed);
  Eigen::MatrixXd a(num_actions, posthoc_dim);
  for (int i = 0; i < num_actions; ++i) {
    for (int j = 0; j < posthoc_dim; ++j) a(i, j) = random::Uniform01(rng);
  }
  return a.completeOrthogonalDecomposition().pseudoInverse();
}

double BestLinearTestMse(const MnistProblem& problem, double ridge) {
  const Eigen::MatrixXd& c = problem.train_contexts;
  Eigen::MatrixXd gram = c.transpose() * c;
  gram.diagonal().array() += ridge;
  const Eigen::MatrixXd theta =
      gram.llt().solve(c.transpose() * problem.train_losses);
  return (problem.test_contexts * theta - problem.test_losses).squaredNorm() /
         static_cast<double>(problem.test_losses.size());
}

absl::StatusOr<LearningCurve> RunLearningSpeedTrial(const MnistProblem& problem,
                                                    const MnistConfig& config,
                                                    uint64_t seed) {
  if (config.eval_every < 1) {
    return absl::InvalidArgumentError("eval_every must be positive");
  }
  const Eigen::MatrixXd b =
      DrawPosthocMap(problem.num_actions, config.posthoc_dim, seed);
  // The post hoc context of every test digit, for the post hoc model's MSE.
  const Eigen::MatrixXd test_posthoc = problem.test_losses * b.transpose();
  ASSIGN_OR_RETURN(std::unique_ptr<bandit::LearnerModel> context_owned,
                   bandit::CreateModel(LearnerConfig(
                       problem, config, bandit::Learner::kContextOnly)));
  ASSIGN_OR_RETURN(std::unique_ptr<bandit::LearnerModel> posthoc_owned,
                   bandit::CreateModel(LearnerConfig(
                       problem, config, bandit::Learner::kPostHoc)));
  bandit::LearnerModel& context_only = *context_owned;
  bandit::LearnerModel& posthoc = *posthoc_owned;
  std::mt19937_64 rng(random::MixSeed(seed, 1));
  LearningCurve curve;
  auto evaluate = [&](int round) {
    curve.rounds.push_back(round);
    curve.context_only_mse.push_back(
        ContextModelTestMse(context_only, problem));
    curve.posthoc_mse.push_back(ContextModelTestMse(posthoc, problem));
    Eigen::MatrixXd phi(config.posthoc_dim, problem.num_actions);
    for (int a = 0; a < problem.num_actions; ++a) phi.col(a) = posthoc.Phi(a);
    curve.posthoc_model_mse.push_back(
        (test_posthoc * phi - problem.test_losses).squaredNorm() /
        static_cast<double>(problem.test_losses.size()));
  };
  evaluate(0);
  const int n = static_cast<int>(problem.train_contexts.rows());
  for (int t = 1; t <= config.exploration_rounds; ++t) {
    const int i = random::UniformIndex(rng, n);
    bandit::Round round;
    round.context = Row(problem.train_contexts, i);
    round.action = random::UniformIndex(rng, problem.num_actions);
    round.loss = problem.train_losses(i, round.action);
    context_only.Update(round);
    const Eigen::VectorXd p = b * problem.train_losses.row(i).transpose();
    round.posthoc.assign(p.data(), p.data() + p.size());
    RETURN_IF_ERROR(posthoc.ValidateRound(round));
    posthoc.Update(round);
    if (t % config.eval_every == 0) evaluate(t);
  }
  return curve;
}

absl::StatusOr<std::vector<double>> RunMnistRegretTrial(
    const MnistProblem& problem, const MnistConfig& config,
    bandit::Learner learner, uint64_t seed) {
  const Eigen::MatrixXd b =
      DrawPosthocMap(problem.num_actions, config.posthoc_dim, seed);
  ASSIGN_OR_RETURN(
      std::unique_ptr<bandit::LearnerModel> owned,
      bandit::CreateModel(LearnerConfig(problem, config, learner)));
  bandit::LearnerModel& model = *owned;
  std::mt19937_64 rng(random::MixSeed(seed, 2));
  const int n = static_cast<int>(problem.test_contexts.rows());
  const int rounds = config.regret_rounds > 0 ? config.regret_rounds : n;
  std::vector<double> cumulative(rounds);
  double total = 0.0;
  for (int t = 0; t < rounds; ++t) {
    const int i = random::UniformIndex(rng, n);
    bandit::Round round;
    round.context = Row(problem.test_contexts, i);
    std::vector<double> lcb;
    for (const auto& e : model.Estimate(round.context)) lcb.push_back(e.lcb);
    round.action = bandit::ArgMin(lcb);
    round.loss = problem.test_losses(i, round.action);
    total += round.loss - problem.test_losses.row(i).minCoeff();
    cumulative[t] = total;
    if (bandit::UsesPosthoc(learner)) {
      const Eigen::VectorXd p = b * problem.test_losses.row(i).transpose();
      round.posthoc.assign(p.data(), p.data() + p.size());
    }
    RETURN_IF_ERROR(model.ValidateRound(round));
    model.Update(round);
  }
  return cumulative;
}

}  // namespace bitewise::experiments
