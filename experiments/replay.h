// Offline tuning by replay: choose LinUCB's alpha and ridges for a user
// from what was already logged, without more robot time. Each candidate
// setting is replayed over bootstrap resamples of the log; where it picks an
// action other than the logged one, the loss is imputed:
//  - direct method (DM): the mean logged loss of that action on that food
//    (falling back to the action's mean over all foods, then to the overall
//    mean);
//  - doubly robust (DR): DM plus, for the logged action only, the correction
//    w (l - l_hat), with w = K (the paper's rule, right when the log was
//    collected uniformly at random) or w = 1/propensity as logged.
// A labelled dataset has every action's loss, so nothing is imputed there.
#ifndef BITEWISE_EXPERIMENTS_REPLAY_H_
#define BITEWISE_EXPERIMENTS_REPLAY_H_

#include <cstdint>
#include <vector>

#include "Eigen/Core"
#include "absl/status/statusor.h"
#include "experiments/event_log.h"
#include "services/bandit/core/config.h"

namespace bitewise::experiments {

enum class DrWeight {
  kNumActions,         // K
  kInversePropensity,  // 1 / logged propensity
};

// Full loss vectors for every row of the log (n x K).
struct ImputedLosses {
  Eigen::MatrixXd direct;
  Eigen::MatrixXd doubly_robust;
};

// INVALID_ARGUMENT for an empty log.
absl::StatusOr<ImputedLosses> ImputeLosses(const EventLog& log,
                                           DrWeight weight);

struct ReplaySetting {
  bandit::Learner learner = bandit::Learner::kPostHoc;
  double alpha = 0.01;
  double lambda_c = 1000.0;
  double lambda_p = 1.0;
};

struct Interval {
  double mean = 0.0;
  double lower = 0.0;  // 2.5th percentile over replays
  double upper = 0.0;  // 97.5th percentile over replays
};

struct ReplayEstimate {
  ReplaySetting setting;
  // Estimated cumulative loss over one pass of the log's length.
  Interval direct;
  Interval doubly_robust;
};

// Replays `setting` (LinUCB) `replays` times over bootstrap resamples of the
// log, the resample of replay r fixed by (seed, r) so every setting faces
// the same orders. The learner is told the logged loss when it picks the
// logged action and the direct estimate otherwise (a labelled dataset tells
// it the true loss). INVALID_ARGUMENT for an empty log, replays < 1, or a
// post hoc setting on a log without post hoc contexts.
absl::StatusOr<ReplayEstimate> ReplaySettingOnLog(const EventLog& log,
                                                  const ImputedLosses& imputed,
                                                  const ReplaySetting& setting,
                                                  int replays, uint64_t seed);

}  // namespace bitewise::experiments

#endif  // BITEWISE_EXPERIMENTS_REPLAY_H_
