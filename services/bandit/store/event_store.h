// EventStore: the durable truth of the BanditService. It keeps each user's
// configuration and event log (context, action, propensity, loss, post hoc
// context, meal, times); models are derived from it. Select writes a pending
// event; Update completes it in one transaction, exactly once.
//
// Implementations must be thread-safe. The SQLite store is the embedded
// default; the PostgreSQL store serves a facility (open_store.h picks one
// from --db).
#ifndef BITEWISE_SERVICES_BANDIT_STORE_EVENT_STORE_H_
#define BITEWISE_SERVICES_BANDIT_STORE_EVENT_STORE_H_

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/time/time.h"
#include "services/bandit/core/config.h"
#include "services/bandit/core/linucb.h"
#include "services/common/audit.h"

namespace bitewise::bandit {

struct UserRecord {
  std::string user_id;
  BanditConfig config;
  absl::Time created_at;
  // Number of completed events since creation or the last reset.
  int64_t model_version = 0;
  int64_t pending_events = 0;
  // Changes whenever the user's log starts over (CreateUser, ResetUser) in
  // a store several processes share (PostgreSQL), so a process can tell
  // its cached model belongs to an older log; always 0 in SQLite.
  int64_t incarnation = 0;
};

struct EventRecord {
  int64_t event_id = 0;  // assigned by the store, > 0, unique across users
  std::string user_id;
  std::string meal_id;
  std::string item_label;
  std::vector<double> context;
  int action = 0;
  double propensity = 1.0;
  absl::Time selected_at;
  bool completed = false;
  // Set when completed.
  double loss = 0.0;
  std::vector<double> posthoc;
  double weight = 1.0;        // importance weight applied to this round
  int64_t model_version = 0;  // user's model_version after this update
  absl::Time updated_at;
};

// The round a completed event adds to its user's model (the log a model is
// rebuilt from); the second form takes the event's vectors instead of
// copying them.
inline Round EventRound(const EventRecord& event) {
  Round round;
  round.context = event.context;
  round.action = event.action;
  round.loss = event.loss;
  round.posthoc = event.posthoc;
  round.weight = event.weight;
  return round;
}
inline Round EventRound(EventRecord&& event) {
  Round round;
  round.context = std::move(event.context);
  round.action = event.action;
  round.loss = event.loss;
  round.posthoc = std::move(event.posthoc);
  round.weight = event.weight;
  return round;
}

// A population pool: the pooled models of like users (same learner,
// dimensions and actions), from which new users' priors are made.
struct PoolRecord {
  int64_t pool_version = 0;  // assigned by the store, increasing from 1
  absl::Time created_at;
  int64_t users = 0;  // how many users were pooled
  Learner learner = Learner::kPostHoc;
  int context_dim = 0;
  int posthoc_dim = 0;
  std::vector<std::string> action_names;
  // theta0, phi0 and the input scale; rounds is 0 (each user chooses how
  // much it is worth) and pool_version equals the record's.
  PopulationPrior prior;
};

// A saved model (LinUcbModel::SaveState) and the part of the log it covers:
// a cold load reads it and the events after it instead of the whole log.
struct ModelCheckpoint {
  int64_t model_version = 0;  // completed events it covers, > 0
  int64_t last_event_id = 0;  // the event at model_version: ties it to the log
  std::string state;
  absl::Time created_at;
};

// One administrative call as the audit log keeps it: the trail's own
// record (services/common/audit.h, a plain struct) with its id in the log.
struct AuditEntry : AuditEvent {
  int64_t audit_id = 0;  // assigned by the store, increasing from 1
};

// What a full storage check found.
struct StoreCheckReport {
  std::vector<std::string> findings;  // empty when all is well (at most 100)
  int64_t users_checked = 0;
  int64_t events_checked = 0;
};

struct Page {
  int page_size = 100;     // clamped to [1, 1000]
  std::string page_token;  // empty: from the start
  // Also ends the page before the items' encoded size (about) passes this,
  // after at least one item; 0: no limit. Services set it below their
  // message limit so every page can be sent.
  int64_t max_bytes = 0;
};

template <typename T>
struct PageResult {
  std::vector<T> items;
  std::string next_page_token;  // empty: no more
};

// Durable writes of the hot path since the store was opened (for metrics):
// each AppendPending (a Select's event) and CompleteEvent (an Update), with
// the time until it was committed (waiting for its group included); and the
// commits that carried them: how many, how many writes, and their time.
struct StoreWriteStats {
  int64_t appends = 0;
  double append_seconds = 0.0;
  int64_t completions = 0;
  double completion_seconds = 0.0;
  int64_t commits = 0;
  int64_t committed_writes = 0;
  double commit_seconds = 0.0;
  // Writes that failed, or were refused, for a storage reason
  // (write_faults.h): counted by FaultWatchStore.
  int64_t write_faults = 0;
};

// Where a user's log stands: what a process sharing the store compares its
// cached model with (EventStore::LogPosition), and conditions its writes on
// (AppendPendingAt, CompleteEventAt).
struct UserLogPosition {
  int64_t model_version = 0;
  int64_t pending_events = 0;
  int64_t incarnation = 0;
};

class EventStore {
 public:
  virtual ~EventStore() = default;

  // ALREADY_EXISTS if the id is taken.
  virtual absl::Status CreateUser(const UserRecord& user) = 0;
  // NOT_FOUND if unknown.
  virtual absl::StatusOr<UserRecord> GetUser(const std::string& user_id) = 0;
  // Ordered by user_id.
  virtual absl::StatusOr<PageResult<UserRecord>> ListUsers(
      const Page& page) = 0;
  // Deletes the user and all of its events. NOT_FOUND if unknown.
  virtual absl::Status DeleteUser(const std::string& user_id) = 0;
  // Deletes all of the user's events and sets model_version to 0; keeps the
  // configuration. NOT_FOUND if unknown.
  virtual absl::Status ResetUser(const std::string& user_id) = 0;

  // Durably appends a pending event (event_id, completed and the outcome
  // fields of `event` are ignored) and returns its new event_id.
  // NOT_FOUND if the user is unknown.
  virtual absl::StatusOr<int64_t> AppendPending(const EventRecord& event) = 0;

  // In one transaction: marks the pending event completed with this outcome,
  // increments the user's model_version and stores it on the event. Returns
  // the completed event. NOT_FOUND for an unknown event; FAILED_PRECONDITION
  // if it is already completed (nothing is written).
  virtual absl::StatusOr<EventRecord> CompleteEvent(
      int64_t event_id, double loss, const std::vector<double>& posthoc,
      double weight, absl::Time updated_at) = 0;

  // NOT_FOUND if unknown.
  virtual absl::StatusOr<EventRecord> GetEvent(int64_t event_id) = 0;

  // A user's events in event_id order, optionally only one meal's.
  virtual absl::StatusOr<PageResult<EventRecord>> ListEvents(
      const std::string& user_id, const std::string& meal_id,
      const Page& page) = 0;

  // Every completed event of the user in model_version order: the log the
  // model is rebuilt from.
  virtual absl::StatusOr<std::vector<EventRecord>> CompletedEvents(
      const std::string& user_id) = 0;

  // Completed events of the user with model_version >= `from_version`, in
  // model_version order.
  virtual absl::StatusOr<std::vector<EventRecord>> CompletedEventsFrom(
      const std::string& user_id, int64_t from_version) = 0;

  // Durably replaces the user's checkpoint. Large states are written in
  // chunks, each its own transaction, so other calls are not held up; the
  // checkpoint counts once its header is written. FAILED_PRECONDITION if the
  // log no longer has `last_event_id` at `model_version` (the user was reset
  // meanwhile): nothing is kept. NOT_FOUND for an unknown user.
  virtual absl::Status PutCheckpoint(const std::string& user_id,
                                     const ModelCheckpoint& checkpoint) = 0;
  // The user's checkpoint. NOT_FOUND if there is none; DATA_LOSS naming the
  // user if its bytes are incomplete or do not match their checksum.
  virtual absl::StatusOr<ModelCheckpoint> GetCheckpoint(
      const std::string& user_id) = 0;
  // Removes the user's checkpoint, if any (ResetUser and DeleteUser do too).
  virtual absl::Status DeleteCheckpoint(const std::string& user_id) = 0;

  // OK while the store can durably accept writes; otherwise the reason
  // (for the service's health). Default: always OK.
  virtual absl::Status CheckHealth() { return absl::OkStatus(); }

  // A small durable write that touches what the hot path writes (SQLite:
  // the database, its log and the contexts file; PostgreSQL: a commit), so
  // a store whose writes failed for a storage reason (write_faults.h) can
  // tell when they succeed again. Default: OK (nothing to probe).
  virtual absl::Status ProbeWrite() { return absl::OkStatus(); }
  // Called with the fault when a write first fails for a storage reason
  // (FaultWatchStore), so health can drop at once instead of at its next
  // poll. Set once, before the store is used. Default: never called.
  using FaultObserver = std::function<void(const absl::Status& fault)>;
  virtual void SetFaultObserver(FaultObserver observer) {}

  // Whether several processes may serve the same users from this store at
  // once (PostgreSQL replicas). The engine then writes a user's events only
  // where its cached model says the log stands (AppendPendingAt,
  // CompleteEventAt) and, when another process has written there since,
  // brings the model up to the log (LogPosition and the new events) and
  // tries again. Default: no (one process per store).
  virtual bool shared() const { return false; }
  // Where the user's log stands now. NOT_FOUND for an unknown user.
  // Default: from GetUser.
  virtual absl::StatusOr<UserLogPosition> LogPosition(
      const std::string& user_id) {
    absl::StatusOr<UserRecord> user = GetUser(user_id);
    if (!user.ok()) return user.status();
    return UserLogPosition{user->model_version, user->pending_events,
                           user->incarnation};
  }
  // AppendPending, only if the user's log stands at `at` (its version,
  // pending events and incarnation): ABORTED naming the user, with nothing
  // written, if another process has written to it since. Default (a store
  // only one process writes): AppendPending.
  virtual absl::StatusOr<int64_t> AppendPendingAt(const EventRecord& event,
                                                  const UserLogPosition& at) {
    return AppendPending(event);
  }
  // CompleteEvent, only if the event is `user_id`'s and the user's log
  // stands at `at`'s version and incarnation: otherwise ABORTED, nothing
  // written (NOT_FOUND and FAILED_PRECONDITION as CompleteEvent). Default:
  // CompleteEvent.
  virtual absl::StatusOr<EventRecord> CompleteEventAt(
      const std::string& user_id, int64_t event_id, double loss,
      const std::vector<double>& posthoc, double weight, absl::Time updated_at,
      const UserLogPosition& at) {
    return CompleteEvent(event_id, loss, posthoc, weight, updated_at);
  }

  // Called after every commit of the hot path's writes with its time and
  // the number of writes it carried (a group; 1 where each write is its own
  // commit), for metrics. Set once, before the store is used; it must be
  // thread-safe. Default: never called.
  using CommitObserver = std::function<void(double seconds, int64_t writes)>;
  virtual void SetCommitObserver(CommitObserver observer) {}

  // The hot path's write counters (StoreWriteStats). Default: none.
  virtual StoreWriteStats write_stats() const { return {}; }

  // Durably stores a new pool (pool_version ignored) and returns its
  // version.
  virtual absl::StatusOr<int64_t> AddPool(const PoolRecord& pool) = 0;
  // The newest pool for users like `config` (learner, context_dim,
  // posthoc_dim, action names). NOT_FOUND if there is none.
  virtual absl::StatusOr<PoolRecord> LatestPool(const BanditConfig& config) = 0;

  // Durably appends an audit entry (audit_id ignored) and returns its id.
  virtual absl::StatusOr<int64_t> AppendAudit(const AuditEntry& entry) = 0;
  // The audit log in audit_id order (oldest first).
  virtual absl::StatusOr<PageResult<AuditEntry>> ListAudit(
      const Page& page) = 0;

  // The full check, on demand: the storage's own consistency check over
  // everything, and every user and event read back as the service would
  // (action names, priors, vectors, checksums). Problems are findings, not
  // errors; an error means the check itself could not run.
  virtual absl::StatusOr<StoreCheckReport> CheckStore() = 0;
};

}  // namespace bitewise::bandit

#endif  // BITEWISE_SERVICES_BANDIT_STORE_EVENT_STORE_H_
