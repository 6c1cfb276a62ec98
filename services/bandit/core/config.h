// Configuration of one user's bandit: which learner, which exploration
// strategy, the hyperparameters of docs/algorithms.md and the problem's
// dimensions. Plain data with the researchers' defaults; no flags here.
#ifndef BITEWISE_SERVICES_BANDIT_CORE_CONFIG_H_
#define BITEWISE_SERVICES_BANDIT_CORE_CONFIG_H_

#include <cstdint>
#include <string>
#include <vector>

#include "absl/status/status.h"

namespace bitewise::bandit {

enum class Learner {
  kPostHoc = 1,      // post hoc augmented LinUCB (Gordon et al. 2021)
  kContextOnly = 2,  // classic LinUCB on the visual context
  kPoLinUcb = 3,     // poLinUCB (Wang et al. 2023), post-serving contexts
};

// Whether the learner learns from the post hoc context (needs
// posthoc_dim >= 1 and one in every Update); from learners.h's table.
bool UsesPosthoc(Learner learner);

enum class Strategy {
  kLinUcb = 1,  // argmin lcb_a, ties to the lowest index
  kGreedy = 2,  // argmin predicted loss (alpha = 0)
  kEpsilonGreedy = 3,
  kThompson = 4,  // draw theta ~ N(theta_a, alpha^2 Sigma_a)
  kUniform = 5,
};

// The learner's name in learners.h's table ("unknown" for none).
const char* LearnerName(Learner learner);
const char* StrategyName(Strategy strategy);

// The six skewering actions of the paper (docs/robot.md), in index order.
std::vector<std::string> DefaultActionNames();

// An opt-in population prior (docs/algorithms.md, "Population prior"): the
// ridges are centred on a population mean built from other users'
// sufficient statistics instead of on zero. With kappa_c = rounds *
// context_msn and kappa_p = rounds * posthoc_msn:
//   A_a = (lambda_c + kappa_c) I + sum w c c^T,  b_a = kappa_c theta0_a + ...
//   M_a = (lambda_p + kappa_p) I + sum w p p^T,  r_a = kappa_p phi0_a + ...
// (S_pp and S_pc are unchanged): the ridge lambda_c ||theta||^2 gains
// kappa_c ||theta - theta0||^2 and the post hoc ridge gains
// kappa_p ||H theta - phi0||^2, a prior worth `rounds` observations.
struct PopulationPrior {
  int64_t pool_version = 0;  // the pool it came from; 0: no prior
  double rounds = 0.0;       // n_0, what the prior is worth, >= 0
  double context_msn = 0.0;  // pooled E[w ||c||^2] / E[w]
  double posthoc_msn = 0.0;  // pooled E[w ||p||^2] / E[w]
  std::vector<std::vector<double>> theta0;  // K x d
  std::vector<std::vector<double>> phi0;    // K x q (post hoc learner)

  bool enabled() const { return pool_version > 0 && rounds > 0.0; }
  double kappa_c() const { return enabled() ? rounds * context_msn : 0.0; }
  double kappa_p() const { return enabled() ? rounds * posthoc_msn : 0.0; }
};

struct BanditConfig {
  Learner learner = Learner::kPostHoc;
  Strategy strategy = Strategy::kLinUcb;
  // Exploration weight: lcb = predicted - alpha * width. Also the scale v of
  // Thompson sampling.
  double alpha = 0.01;
  // Ridge on the visual model theta_a (A_a = lambda_c I + ...).
  double lambda_c = 1000.0;
  // Ridge on the post hoc terms (S_pp and M_a = lambda_p I + ...).
  double lambda_p = 1.0;
  // poLinUCB: the post hoc context a Select predicts, p_hat(c), is trusted
  // to a ball of radius phi_radius * sqrt(c^T X^-1 c) (docs/algorithms.md).
  // 0.1: the best of 0-10 in simulated meals on tuning seeds (seed 1001;
  // docs/experiments.md).
  double phi_radius = 0.1;
  // Probability of a uniform random action under epsilon-greedy.
  double epsilon = 0.1;
  // Weight each round by 1/propensity of the action taken.
  bool importance_weighting = false;
  int context_dim = 2048;                                        // d = d_c
  int posthoc_dim = 4;                                           // q = d_p
  std::vector<std::string> action_names = DefaultActionNames();  // K names
  // Seeds the user's random generator (epsilon-greedy, Thompson, uniform).
  uint64_t seed = 0;
  // Opt-in; none by default.
  PopulationPrior prior;

  int num_actions() const { return static_cast<int>(action_names.size()); }
};

// Returns INVALID_ARGUMENT naming the first field that is out of range.
absl::Status ValidateConfig(const BanditConfig& config);

// Longest accepted action name (bytes): names, not documents, so that
// every page of ListUsers stays small.
constexpr size_t kMaxActionNameBytes = 64;

}  // namespace bitewise::bandit

#endif  // BITEWISE_SERVICES_BANDIT_CORE_CONFIG_H_
