// Population prior: what the facility has learned from everyone, as a
// starting point for a new person (docs/algorithms.md, "Population prior").
// The physics of skewering is largely person-independent, so a new user's
// first meal need not start from zero: the pool averages other users'
// per-action models, weighted by how often each user tried each action,
// with the pooled scale of their inputs. It reads only each model's
// sufficient statistics (theta_a, phi_a, counts, input sums), never their
// raw events. No gRPC here.
#ifndef BITEWISE_SERVICES_BANDIT_CORE_POPULATION_PRIOR_H_
#define BITEWISE_SERVICES_BANDIT_CORE_POPULATION_PRIOR_H_

#include <cstdint>
#include <vector>

#include "Eigen/Core"
#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "services/bandit/core/config.h"
#include "services/bandit/core/learner_model.h"

namespace bitewise::bandit {

// Pools models one at a time (so a service can hold one user's model at a
// time): theta0_a = sum_u n_{a,u} theta_{a,u} / sum_u n_{a,u} (0 when
// nobody tried a), phi0_a likewise from phi_{a,u}, context_msn =
// sum_u sum w ||c||^2 / sum_u sum w, posthoc_msn likewise.
// Thread-compatible.
class PriorPool {
 public:
  // Models like `config` (learner, dimensions, action names) may be added.
  explicit PriorPool(const BanditConfig& config);

  // Whether `model` can join this pool.
  bool Accepts(const LearnerModel& model) const;
  // INVALID_ARGUMENT if !Accepts(model).
  absl::Status Add(const LearnerModel& model);
  int64_t users() const { return users_; }

  // The prior worth `rounds` observations, recorded as pool
  // `pool_version`. INVALID_ARGUMENT when no added model has a round, or
  // for pool_version < 1 or rounds < 0 or not finite.
  absl::StatusOr<PopulationPrior> Finish(double rounds,
                                         int64_t pool_version) const;

 private:
  BanditConfig config_;
  int64_t users_ = 0;
  std::vector<Eigen::VectorXd> theta_sum_;  // sum_u n_{a,u} theta_{a,u}
  std::vector<Eigen::VectorXd> phi_sum_;
  std::vector<int64_t> counts_;
  InputScale scale_;
};

// PriorPool over `models` in one call. INVALID_ARGUMENT when `models` is
// empty or the models differ in learner, dimensions or actions (naming the
// first that differs), and as PriorPool::Finish.
absl::StatusOr<PopulationPrior> PooledPrior(
    const std::vector<const LearnerModel*>& models, double rounds,
    int64_t pool_version);

}  // namespace bitewise::bandit

#endif  // BITEWISE_SERVICES_BANDIT_CORE_POPULATION_PRIOR_H_
