// EventStore: the durable truth of the BanditService, all of its roles in
// one object: the event log (event_log.h), replica positions
// (replica_log.h), model checkpoints (checkpoint_store.h), population pools
// (population_pools.h) and the audit log (audit_log.h), with what the
// service needs to watch it (health, write faults, commit metrics) and a
// full check. Models are derived from the log. Code that needs one role
// takes that role's interface.
//
// Implementations must be thread-safe. The SQLite store is the embedded
// default; the PostgreSQL store serves a facility (open_store.h picks one
// from --db); FaultWatchStore (write_faults.h) wraps either.
#ifndef BITEWISE_SERVICES_BANDIT_STORE_EVENT_STORE_H_
#define BITEWISE_SERVICES_BANDIT_STORE_EVENT_STORE_H_

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/time/time.h"
#include "services/bandit/store/audit_log.h"
#include "services/bandit/store/checkpoint_store.h"
#include "services/bandit/store/event_log.h"
#include "services/bandit/store/population_pools.h"
#include "services/bandit/store/replica_log.h"
#include "services/bandit/store/store_records.h"

namespace bitewise::bandit {

class EventStore : public EventLog,
                   public ReplicaLog,
                   public CheckpointStore,
                   public PopulationPools,
                   public AuditLog {
 public:
  ~EventStore() override = default;

  // OK while the store can durably accept writes; otherwise the reason
  // (for the service's health). Default: always OK.
  virtual absl::Status CheckHealth() { return absl::OkStatus(); }

  // A small durable write that touches what the hot path writes (SQLite:
  // the database, its log and the contexts file; PostgreSQL: a commit), so
  // a store whose writes failed for a storage reason (write_faults.h) can
  // tell when they succeed again. Default: OK (nothing to probe).
  virtual absl::Status ProbeWrite() { return absl::OkStatus(); }
  // The checks an open deferred because they read the whole store (SQLite
  // with check_at_open false: its integrity check, then erasing what no row
  // of the contexts file points at). Run once, before the first write;
  // reads may run meanwhile. DATA_LOSS naming the file when it is damaged.
  // Default: OK (nothing deferred).
  virtual absl::Status RunDeferredChecks() { return absl::OkStatus(); }
  // Called with the fault when a write first fails for a storage reason
  // (FaultWatchStore), so health can drop at once instead of at its next
  // poll. Set once, before the store is used. Default: never called.
  using FaultObserver = std::function<void(const absl::Status& fault)>;
  virtual void SetFaultObserver(FaultObserver observer) {}

  // Called after every commit of the hot path's writes with its time and
  // the number of writes it carried (a group; 1 where each write is its own
  // commit), for metrics. Set once, before the store is used; it must be
  // thread-safe. Default: never called.
  using CommitObserver = std::function<void(double seconds, int64_t writes)>;
  virtual void SetCommitObserver(CommitObserver observer) {}

  // The hot path's write counters (StoreWriteStats). Default: none.
  virtual StoreWriteStats write_stats() const { return {}; }

  // The full check, on demand: the storage's own consistency check over
  // everything, and every user and event read back as the service would
  // (action names, priors, vectors, checksums). Problems are findings, not
  // errors; an error means the check itself could not run.
  virtual absl::StatusOr<StoreCheckReport> CheckStore() = 0;

  // ReplicaLog for a store only one process writes.
  bool shared() const override { return false; }
  absl::StatusOr<UserLogPosition> LogPosition(
      const std::string& user_id) override {
    absl::StatusOr<UserRecord> user = GetUser(user_id);
    if (!user.ok()) return user.status();
    return UserLogPosition{user->model_version, user->pending_events,
                           user->incarnation};
  }
  absl::StatusOr<int64_t> AppendPendingAt(const EventRecord& event,
                                          const UserLogPosition& at) override {
    return AppendPending(event);
  }
  absl::StatusOr<EventRecord> CompleteEventAt(
      const std::string& user_id, int64_t event_id, double loss,
      const std::vector<double>& posthoc, double weight, absl::Time updated_at,
      const UserLogPosition& at) override {
    return CompleteEvent(event_id, loss, posthoc, weight, updated_at);
  }
};

}  // namespace bitewise::bandit

#endif  // BITEWISE_SERVICES_BANDIT_STORE_EVENT_STORE_H_
