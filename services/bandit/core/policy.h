// Exploration strategies on top of either learner: turn per-action estimates
// into a choice and its propensity, with a per-user seeded generator so that
// every run is reproducible.
#ifndef BITEWISE_SERVICES_BANDIT_CORE_POLICY_H_
#define BITEWISE_SERVICES_BANDIT_CORE_POLICY_H_

#include <cstdint>
#include <random>
#include <vector>

#include "absl/status/status.h"
#include "services/bandit/core/config.h"
#include "services/bandit/core/linucb.h"

namespace bitewise::bandit {

struct Choice {
  int action = 0;
  // Probability that the strategy picks this action given the estimates
  // (1 for LinUCB and greedy; Monte Carlo estimate for Thompson sampling).
  double propensity = 1.0;
};

// The generator for a user's `select_index`-th Select (0-based since the
// user was created or reset): a pure function of the seed and the index, so
// a restarted service draws exactly what it would have drawn.
std::mt19937_64 SelectRng(uint64_t seed, int64_t select_index);

// Index of the smallest value, ties to the lowest index.
int ArgMin(const std::vector<double>& values);

// INTERNAL naming the action and its numbers unless every estimate is
// finite. ChooseAction must not see a NaN: every comparison with it is
// false, so an argmin would pick action 0, or never the NaN one, silently.
absl::Status CheckEstimatesFinite(const std::vector<ActionEstimate>& estimates);

// Chooses an action by `config.strategy` (estimates that pass
// CheckEstimatesFinite):
//  - LinUCB: argmin lcb; greedy: argmin predicted loss;
//  - epsilon-greedy: uniform with probability epsilon, else greedy;
//  - Thompson: argmin of theta~^T c with theta~ ~ N(theta_a, v^2 Sigma_a),
//    v = alpha and Sigma_a the matrix under the width. Only theta~^T c
//    matters, and it is N(predicted_loss, (v width)^2): drawing that scalar
//    is exact and keeps the mean at theta_a;
//  - uniform: each action with probability 1/K.
Choice ChooseAction(const BanditConfig& config,
                    const std::vector<ActionEstimate>& estimates,
                    std::mt19937_64& rng);

}  // namespace bitewise::bandit

#endif  // BITEWISE_SERVICES_BANDIT_CORE_POLICY_H_
