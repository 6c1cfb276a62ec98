// The records the bandit store keeps and returns: users, events, pools,
// checkpoints, audit entries, pages, and the counters and positions its
// roles report (event_log.h, checkpoint_store.h, population_pools.h,
// audit_log.h, replica_log.h). Plain structs, no behaviour beyond
// EventRound.
#ifndef BITEWISE_SERVICES_BANDIT_STORE_STORE_RECORDS_H_
#define BITEWISE_SERVICES_BANDIT_STORE_STORE_RECORDS_H_

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "absl/time/time.h"
#include "services/bandit/core/config.h"
#include "services/bandit/core/linucb.h"
#include "services/bandit/core/population_prior.h"
#include "services/common/audit.h"

namespace bitewise::bandit {

struct UserRecord {
  std::string user_id;
  BanditConfig config;
  absl::Time created_at;
  // Number of completed events since creation or the last reset.
  int64_t model_version = 0;
  int64_t pending_events = 0;
  // Changes whenever the user's log starts over or is to be learned anew
  // (CreateUser, ResetUser, SetLearner) in
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

// A saved model (LearnerModel::SaveState) and the part of the log it covers:
// a cold load reads it and the events after it instead of the whole log.
struct ModelCheckpoint {
  int64_t model_version = 0;  // completed events it covers, > 0
  int64_t last_event_id = 0;  // the event at model_version: ties it to the log
  // Written: the model's learner, checked against the user's (a model from
  // before SetLearner is not current). Not stored: a checkpoint read back
  // leaves it unset here (LoadModel checks the state against the config).
  Learner learner = Learner::kPostHoc;
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

}  // namespace bitewise::bandit

#endif  // BITEWISE_SERVICES_BANDIT_STORE_STORE_RECORDS_H_
