// PopulationPools: the store's role that keeps the pooled models of like
// users, from which new users' priors are made.
#ifndef BITEWISE_SERVICES_BANDIT_STORE_POPULATION_POOLS_H_
#define BITEWISE_SERVICES_BANDIT_STORE_POPULATION_POOLS_H_

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/time/time.h"
#include "services/bandit/store/store_records.h"

namespace bitewise::bandit {

class PopulationPools {
 public:
  virtual ~PopulationPools() = default;

  // Durably stores a new pool (pool_version ignored) and returns its
  // version.
  virtual absl::StatusOr<int64_t> AddPool(const PoolRecord& pool) = 0;
  // The newest pool for users like `config` (learner, context_dim,
  // posthoc_dim, action names). NOT_FOUND if there is none.
  virtual absl::StatusOr<PoolRecord> LatestPool(const BanditConfig& config) = 0;
};

}  // namespace bitewise::bandit

#endif  // BITEWISE_SERVICES_BANDIT_STORE_POPULATION_POOLS_H_
