// Configuration of one user's bandit: which learner, which exploration
// strategy, the hyperparameters of SPEC section 2 and the problem's
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
};

enum class Strategy {
  kLinUcb = 1,  // argmin lcb_a, ties to the lowest index
  kGreedy = 2,  // argmin predicted loss (alpha = 0)
  kEpsilonGreedy = 3,
  kThompson = 4,  // draw theta ~ N(theta_a, alpha^2 Sigma_a)
  kUniform = 5,
};

const char* LearnerName(Learner learner);
const char* StrategyName(Strategy strategy);

// The six skewering actions of SPEC section 1, in index order.
std::vector<std::string> DefaultActionNames();

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
  // Probability of a uniform random action under epsilon-greedy.
  double epsilon = 0.1;
  // Weight each round by 1/propensity of the action taken.
  bool importance_weighting = false;
  int context_dim = 2048;                                        // d = d_c
  int posthoc_dim = 4;                                           // q = d_p
  std::vector<std::string> action_names = DefaultActionNames();  // K names
  // Seeds the user's random generator (epsilon-greedy, Thompson, uniform).
  uint64_t seed = 0;

  int num_actions() const { return static_cast<int>(action_names.size()); }
};

// Returns INVALID_ARGUMENT naming the first field that is out of range.
absl::Status ValidateConfig(const BanditConfig& config);

}  // namespace bitewise::bandit

#endif  // BITEWISE_SERVICES_BANDIT_CORE_CONFIG_H_
