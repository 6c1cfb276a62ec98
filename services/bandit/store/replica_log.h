// ReplicaLog: the store's role for several processes serving the same
// users from one store (PostgreSQL replicas): where a user's log stands,
// and writes conditioned on it. The defaults named below are EventStore's,
// for a store one process writes (SQLite).
#ifndef BITEWISE_SERVICES_BANDIT_STORE_REPLICA_LOG_H_
#define BITEWISE_SERVICES_BANDIT_STORE_REPLICA_LOG_H_

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/time/time.h"
#include "services/bandit/store/store_records.h"

namespace bitewise::bandit {

class ReplicaLog {
 public:
  virtual ~ReplicaLog() = default;

  // Whether several processes may serve the same users from this store at
  // once (PostgreSQL replicas). The engine then writes a user's events only
  // where its cached model says the log stands (AppendPendingAt,
  // CompleteEventAt) and, when another process has written there since,
  // brings the model up to the log (LogPosition and the new events) and
  // tries again. Default: no (one process per store).
  virtual bool shared() const = 0;
  // Where the user's log stands now. NOT_FOUND for an unknown user.
  // Default: from GetUser.
  virtual absl::StatusOr<UserLogPosition> LogPosition(
      const std::string& user_id) = 0;
  // AppendPending, only if the user's log stands at `at` (its version,
  // pending events and incarnation): ABORTED naming the user, with nothing
  // written, if another process has written to it since. Default (a store
  // only one process writes): AppendPending.
  virtual absl::StatusOr<int64_t> AppendPendingAt(
      const EventRecord& event, const UserLogPosition& at) = 0;
  // CompleteEvent, only if the event is `user_id`'s and the user's log
  // stands at `at`'s version and incarnation: otherwise ABORTED, nothing
  // written (NOT_FOUND and FAILED_PRECONDITION as CompleteEvent). Default:
  // CompleteEvent.
  virtual absl::StatusOr<EventRecord> CompleteEventAt(
      const std::string& user_id, int64_t event_id, double loss,
      const std::vector<double>& posthoc, double weight, absl::Time updated_at,
      const UserLogPosition& at) = 0;
};

}  // namespace bitewise::bandit

#endif  // BITEWISE_SERVICES_BANDIT_STORE_REPLICA_LOG_H_
