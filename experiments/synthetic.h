// The synthetic experiment of docs/experiments.md (Gordon et al. 2021, Sec.
// V-A): K actions, contexts uniform in [0,1)^d_c, the post hoc context is the
// first d_p coordinates of the context, and each action's expected loss is a
// fixed hidden linear map of the post hoc context. It measures how much faster
// the post hoc learner finds the best action than context-only LinUCB, and how
// that gain grows with d_c.
#ifndef BITEWISE_EXPERIMENTS_SYNTHETIC_H_
#define BITEWISE_EXPERIMENTS_SYNTHETIC_H_

#include <cstdint>
#include <vector>

#include "Eigen/Core"
#include "absl/status/statusor.h"
#include "services/bandit/core/config.h"

namespace bitewise::experiments {

enum class SyntheticLoss {
  // The loss is the expected loss phi_a^T p itself (noise-free), as in the
  // researchers' synthetic script.
  kLinear,
  // The loss is Bernoulli(phi_a^T p): binary like a bite's success, same mean.
  kBernoulli,
};

struct SyntheticConfig {
  int num_actions = 10;  // K
  int context_dim = 10;  // d_c
  int posthoc_dim = 3;   // d_p (<= d_c)
  int rounds = 1000;
  SyntheticLoss loss = SyntheticLoss::kLinear;
  // Learner hyperparameters (docs/algorithms.md defaults).
  double alpha = 0.01;
  double lambda_c = 1000.0;
  double lambda_p = 1.0;
  // poLinUCB's phi_radius (BanditConfig::phi_radius).
  double phi_radius = bandit::BanditConfig().phi_radius;
};

// One trial's world, fixed by its seed: hidden loss map and every round's
// draws, so both learners can face exactly the same rounds.
struct SyntheticWorld {
  // phi.row(a) . p is action a's expected loss. Entries are uniform in
  // [0, 1/d_p) so expected losses lie in [0, 1), as the core requires.
  Eigen::MatrixXd phi;       // K x d_p
  Eigen::MatrixXd contexts;  // rounds x d_c
  // Uniform draws that turn an expected loss into a Bernoulli loss.
  Eigen::VectorXd coins;  // rounds
};

SyntheticWorld DrawSyntheticWorld(const SyntheticConfig& config, uint64_t seed);

// Plays LinUCB with `learner` on `world` and returns the cumulative
// (expected-loss) regret after each round: element t is
// sum_{s<=t} (mu_{a_s}(p_s) - min_a mu_a(p_s)).
absl::StatusOr<std::vector<double>> RunSyntheticTrial(
    const SyntheticConfig& config, const SyntheticWorld& world,
    bandit::Learner learner);

}  // namespace bitewise::experiments

#endif  // BITEWISE_EXPERIMENTS_SYNTHETIC_H_
