// SqliteEventStore: the embedded EventStore, one SQLite file per service.
//
// The file is opened in WAL mode with foreign keys on, so readers never block
// the writer and deleting a user cascades to its events. Every mutation is one
// SQLite transaction: an OK return means the change is on disk (with
// synchronous_full, even across a power loss), and a failure leaves nothing
// half-written.
//
// One connection serves the whole process, guarded by a mutex: the store is
// bound by fsync on commit, not by parallel reads, and a single connection
// keeps transactions trivially isolated from each other. The hot path's
// writes (AppendPending, CompleteEvent) are committed in groups: concurrent
// callers queue their writes, one of them runs every queued write in one
// transaction, each in its own savepoint (a write that fails leaves no
// trace and fails alone), commits once (one fsync for all), and each caller
// returns its own result only after that commit. Their statements are
// prepared once. One process serves a file (a lock of its own keeps a
// second store out); a program that writes it anyway (a sqlite3 shell) is
// waited for up to busy_timeout.
//
// Behaviour beyond the EventStore contract:
//  - Timestamps are stored in whole microseconds since the Unix epoch.
//  - Doubles round-trip bit for bit (including -0.0, denormals and, inside
//    vectors, NaN payloads). A NaN scalar (propensity, loss, weight) cannot be
//    stored and is rejected with INVALID_ARGUMENT.
//  - CreateUser rejects an invalid config (ValidateConfig) or an empty user_id
//    with INVALID_ARGUMENT.
//  - A pending event reads back with the EventRecord defaults for its outcome
//    fields (loss 0, no posthoc, weight 1, model_version 0, updated_at epoch).
//  - ListEvents and CompletedEvents return NOT_FOUND for an unknown user rather
//    than an empty list; an empty meal_id lists every meal.
//  - Event ids are never reused, even after ResetUser or DeleteUser, so a
//    stale id held by a client can only ever be NOT_FOUND.
//  - Unreadable stored data is DATA_LOSS, and storage that refuses a write
//    a storage fault naming the cause and the file (write_faults.h):
//    RESOURCE_EXHAUSTED for a full disk or a file-size limit, UNAVAILABLE
//    for a read-only file, an I/O error, or a lock another program held
//    past busy_timeout. The write probe does not wait for such a lock (it
//    would hold the store's mutex, and every read, that long).
#ifndef BITEWISE_SERVICES_BANDIT_STORE_SQLITE_EVENT_STORE_H_
#define BITEWISE_SERVICES_BANDIT_STORE_SQLITE_EVENT_STORE_H_

#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "absl/base/thread_annotations.h"
#include "absl/functional/function_ref.h"
#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/synchronization/mutex.h"
#include "absl/time/time.h"
#include "services/bandit/store/event_store.h"
#include "services/bandit/store/sqlite_store_options.h"

struct sqlite3;

namespace bitewise::bandit::sqlite {
class StatementCache;
}  // namespace bitewise::bandit::sqlite

namespace bitewise::bandit {

class ContextFile;

class SqliteEventStore final : public EventStore {
 public:
  // Opens or creates the store. FAILED_PRECONDITION, naming the path, if the
  // file is not a SQLite database, belongs to another application, has a
  // schema version this build does not know, or is already open in another
  // process (an advisory lock on "<path>.lock"); DATA_LOSS if SQLite's
  // integrity check finds it damaged (at open unless check_at_open is false;
  // then RunDeferredChecks does), or if its contexts file is missing
  // while the database refers to it, or is not ours; INVALID_ARGUMENT for
  // an empty path.
  static absl::StatusOr<std::unique_ptr<SqliteEventStore>> Open(
      const SqliteStoreOptions& options);

  SqliteEventStore(const SqliteEventStore&) = delete;
  SqliteEventStore& operator=(const SqliteEventStore&) = delete;
  ~SqliteEventStore() override;

  absl::Status CreateUser(const UserRecord& user) override;
  absl::StatusOr<UserRecord> GetUser(const std::string& user_id) override;
  absl::StatusOr<PageResult<UserRecord>> ListUsers(const Page& page) override;
  absl::Status DeleteUser(const std::string& user_id) override;
  absl::Status ResetUser(const std::string& user_id) override;
  absl::Status SetLearner(const std::string& user_id, Learner learner,
                          int64_t model_version) override;

  absl::StatusOr<int64_t> AppendPending(const EventRecord& event) override;
  absl::StatusOr<EventRecord> CompleteEvent(int64_t event_id, double loss,
                                            const std::vector<double>& posthoc,
                                            double weight,
                                            absl::Time updated_at) override;
  absl::StatusOr<EventRecord> GetEvent(int64_t event_id) override;
  absl::StatusOr<int64_t> AddPool(const PoolRecord& pool) override;
  // FAILED_PRECONDITION naming the path when the database file (or its
  // contexts file) was removed or replaced since it was opened: writes
  // would then be acknowledged and lost at the next start. Every write
  // checks this first.
  absl::Status CheckHealth() override;
  // With check_at_open false: SQLite's integrity check on a connection of
  // its own (other calls go on), then, under the store's lock, every
  // event's context location read and what no row points at erased.
  absl::Status RunDeferredChecks() override;
  // Rewrites the database header's schema version in its own transaction,
  // and probes the contexts file (ContextFile::Probe).
  absl::Status ProbeWrite() override;
  absl::StatusOr<PoolRecord> LatestPool(const BanditConfig& config) override;
  absl::StatusOr<int64_t> AppendAudit(const AuditEntry& entry) override;
  absl::StatusOr<PageResult<AuditEntry>> ListAudit(const Page& page) override;
  // PRAGMA integrity_check over the whole file (up to 100 findings), then
  // every user, event and model checkpoint read back and checked.
  absl::StatusOr<StoreCheckReport> CheckStore() override;
  absl::StatusOr<PageResult<EventRecord>> ListEvents(const std::string& user_id,
                                                     const std::string& meal_id,
                                                     const Page& page) override;
  absl::StatusOr<std::vector<EventRecord>> CompletedEvents(
      const std::string& user_id) override;
  absl::StatusOr<std::vector<EventRecord>> CompletedEventsFrom(
      const std::string& user_id, int64_t from_version) override;
  absl::Status PutCheckpoint(const std::string& user_id,
                             const ModelCheckpoint& checkpoint) override;
  absl::StatusOr<ModelCheckpoint> GetCheckpoint(
      const std::string& user_id) override;
  absl::Status DeleteCheckpoint(const std::string& user_id) override;

  // A checkpoint's bytes go in chunks of at most this many.
  static constexpr size_t kCheckpointChunkBytes = size_t{1} << 20;

  // Its commits are the group commits.
  StoreWriteStats write_stats() const override;
  void SetCommitObserver(CommitObserver observer) override {
    commit_observer_ = std::move(observer);
  }

 private:
  SqliteEventStore(sqlite3* db, int lock_fd, std::string path, uint64_t device,
                   uint64_t inode, std::unique_ptr<ContextFile> contexts,
                   int64_t context_file_min_bytes, bool synchronous_full,
                   bool checks_deferred);
  // The contexts of `user_id`'s events kept in the contexts file, as
  // (offset, length): what to erase once their deletion is committed.
  absl::StatusOr<std::vector<std::pair<int64_t, int64_t>>> ContextRangesLocked(
      const std::string& user_id) ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_);
  // Erases them after the commit that deleted their events; a failure is
  // logged (the bytes stay, unreferenced).
  void EraseContexts(const std::vector<std::pair<int64_t, int64_t>>& ranges)
      ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_);

  absl::StatusOr<UserRecord> GetUserLocked(const std::string& user_id)
      ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_);
  // NOT_FOUND unless the user exists.
  absl::Status CheckUserExistsLocked(const std::string& user_id)
      ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_);
  absl::Status DeleteCheckpointLocked(const std::string& user_id)
      ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_);
  // The user's checkpoint, checked (NOT_FOUND, DATA_LOSS as GetCheckpoint),
  // inside the caller's transaction.
  // The checkpoint protocol's rows (checkpoint_protocol.h).
  class CheckpointRowsImpl;
  friend class CheckpointRowsImpl;
  absl::StatusOr<ModelCheckpoint> ReadCheckpointLocked(
      const std::string& user_id) ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_);

  // Group commit: queues `apply` (run under mu_ inside the group's
  // transaction) and returns its status once the group is committed, or
  // the commit's error.
  struct QueuedWrite;
  absl::Status RunInGroup(absl::FunctionRef<absl::Status()> apply)
      ABSL_LOCKS_EXCLUDED(queue_mu_, mu_);
  void CommitGroup(const std::vector<QueuedWrite*>& group)
      ABSL_LOCKS_EXCLUDED(mu_);

  // Open skipped the checks that read the whole store (check_at_open).
  std::atomic<bool> checks_deferred_;

  absl::Mutex queue_mu_ ABSL_ACQUIRED_BEFORE(mu_);
  std::vector<QueuedWrite*> queue_ ABSL_GUARDED_BY(queue_mu_);
  bool committing_ ABSL_GUARDED_BY(queue_mu_) = false;

  absl::Mutex mu_;
  sqlite3* const db_ ABSL_PT_GUARDED_BY(mu_);
  // SqliteStoreOptions::busy_timeout, restored after the write probe's 0.
  int busy_timeout_ms_ = 5000;
  std::unique_ptr<sqlite::StatementCache> statements_ ABSL_PT_GUARDED_BY(mu_);
  CommitObserver commit_observer_;
  mutable absl::Mutex stats_mu_;
  StoreWriteStats write_stats_ ABSL_GUARDED_BY(stats_mu_);
  // Large contexts (null for ":memory:"): appended, synced before the
  // commit of the rows that point at them, and erased, all under mu_; read
  // from any thread (the file's identity by CheckHealth).
  const std::unique_ptr<ContextFile> contexts_;
  const int64_t context_file_min_bytes_;
  const bool synchronous_full_;
  // The store's lock file, held while the store is open; -1 for ":memory:".
  const int lock_fd_;
  // The database file as opened (device and inode; both 0 for ":memory:").
  const std::string path_;
  const uint64_t device_;
  const uint64_t inode_;
};

}  // namespace bitewise::bandit

#endif  // BITEWISE_SERVICES_BANDIT_STORE_SQLITE_EVENT_STORE_H_
