// PostgresEventStore: the EventStore of a facility, in a PostgreSQL
// database (server 15, reached through libpq), for several robots and
// BanditService processes on one set of users.
//
// The same contract and the same stored bytes as the SQLite store
// (store_rows.h): vectors as little-endian float64 arrays, scalars as
// float8 sent and read in binary (bit for bit, -0.0 included), the same
// checksums checked on every read, event ids from a sequence and so never
// reused. Every mutation is one PostgreSQL transaction, committed with
// synchronous_commit on (set on each connection), so an OK return means the
// change is flushed to the server's disk; concurrent commits share the
// server's WAL flushes. Open refuses a server that runs with fsync off.
//
// Each call takes one of a few pooled connections for its whole
// transaction. A user's writes are ordered by a lock on the user's row
// (every append, completion, reset, delete and checkpoint header takes it
// first), so two completions of a user never share a model_version and a
// reset never races a completion, even from two processes. Replicas write
// with AppendPendingAt and CompleteEventAt: each one statement that writes
// only if the user's row still says what the caller read (AppendPendingAt:
// version, selections, incarnation; CompleteEventAt: version, incarnation),
// else ABORTED with nothing written.
//
// Differences from the SQLite store:
//  - Strings (user ids, meals, labels, action names, audit fields) must be
//    valid UTF-8 without NUL bytes: INVALID_ARGUMENT with the server's
//    message (the invalid byte sequence) otherwise. The gRPC API already
//    requires valid UTF-8.
//  - A lost server is UNAVAILABLE naming the database; each connection is
//    re-established at its next use, so the service recovers when the
//    server returns, without a restart. A server that stops answering
//    fails the call after PostgresStoreOptions::response_timeout without
//    its next bytes (a storage fault), and its connection is closed. If
//    the connection is lost (or given up) at COMMIT or during a write of
//    one statement, the outcome is unknown: UNAVAILABLE says so, and a
//    retried Update is then either applied once or answers
//    already_applied.
//  - Users carry an incarnation (a sequence value set at CreateUser,
//    ResetUser and SetLearner; the DDL's comment predates the last) so a
//    process can tell a cached model is of an older log or learner.
//  - CheckStore reads back every user, event and checkpoint; the storage's
//    own consistency is the server's (see docs/operations.md, amcheck).
#ifndef BITEWISE_SERVICES_BANDIT_STORE_POSTGRES_EVENT_STORE_H_
#define BITEWISE_SERVICES_BANDIT_STORE_POSTGRES_EVENT_STORE_H_

#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "absl/base/thread_annotations.h"
#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/synchronization/mutex.h"
#include "absl/time/time.h"
#include "services/bandit/store/event_store.h"

namespace bitewise::bandit {

namespace pg {
class Pool;
class Connection;
}  // namespace pg

struct PostgresStoreOptions {
  // A libpq connection string: postgresql://USER@HOST:PORT/DB?... or
  // "host=... dbname=...". A password belongs in ~/.pgpass or PGPASSWORD,
  // not here (docs/security.md).
  std::string conninfo;
  // Connections kept open; one call uses one for its transaction.
  int connections = 4;
  // Whether a database without the bitewise tables gets them. Without it,
  // Open is FAILED_PRECONDITION naming the database.
  bool create_if_missing = true;
  // How long a statement waits for the server's next bytes before the call
  // fails UNAVAILABLE (a storage fault: health turns NOT_SERVING) and its
  // connection is closed; the health check waits at most 5 s of it.
  absl::Duration response_timeout = absl::Seconds(30);
};

class PostgresEventStore final : public EventStore {
 public:
  // Connects and checks (or creates) the schema. UNAVAILABLE naming the
  // database if it cannot be reached; FAILED_PRECONDITION if the database
  // holds other tables of the same names, a schema version this build does
  // not know, no store (and !create_if_missing), or the server runs with
  // fsync off.
  static absl::StatusOr<std::unique_ptr<PostgresEventStore>> Open(
      const PostgresStoreOptions& options);

  PostgresEventStore(const PostgresEventStore&) = delete;
  PostgresEventStore& operator=(const PostgresEventStore&) = delete;
  ~PostgresEventStore() override;

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
  // One statement each: a compare-and-set on the user's row (its version,
  // selections and incarnation; a completion: its version and incarnation).
  absl::StatusOr<int64_t> AppendPendingAt(const EventRecord& event,
                                          const UserLogPosition& at) override;
  absl::StatusOr<EventRecord> CompleteEventAt(
      const std::string& user_id, int64_t event_id, double loss,
      const std::vector<double>& posthoc, double weight, absl::Time updated_at,
      const UserLogPosition& at) override;
  absl::StatusOr<UserLogPosition> LogPosition(
      const std::string& user_id) override;
  absl::StatusOr<EventRecord> GetEvent(int64_t event_id) override;
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
  // A round trip to the server on a connection of its own: UNAVAILABLE
  // naming the database while it cannot be reached.
  absl::Status CheckHealth() override;
  // A row into a temporary table of the health connection's session.
  absl::Status ProbeWrite() override;
  absl::StatusOr<int64_t> AddPool(const PoolRecord& pool) override;
  absl::StatusOr<PoolRecord> LatestPool(const BanditConfig& config) override;
  absl::StatusOr<int64_t> AppendAudit(const AuditEntry& entry) override;
  absl::StatusOr<PageResult<AuditEntry>> ListAudit(const Page& page) override;
  absl::StatusOr<StoreCheckReport> CheckStore() override;
  // Each append and completion is its own commit.
  StoreWriteStats write_stats() const override;
  void SetCommitObserver(CommitObserver observer) override {
    commit_observer_ = std::move(observer);
  }
  // Several BanditService processes may share the database.
  bool shared() const override { return true; }
  // "database NAME at HOST:PORT" (no password), for logs.
  const std::string& description() const;

  // A checkpoint's bytes go in chunks of at most this many.
  static constexpr size_t kCheckpointChunkBytes = size_t{1} << 20;
  // The schema version this build writes and reads.
  static constexpr int kSchemaVersion = 3;

 private:
  PostgresEventStore(std::unique_ptr<pg::Pool> pool, std::string conninfo,
                     absl::Duration health_timeout);
  void CountWrite(bool append, absl::Time start, absl::Time commit_start);
  // AppendPending, with `at` only if the user's log stands there.
  absl::StatusOr<int64_t> Append(const EventRecord& event,
                                 const UserLogPosition* at);

  const std::unique_ptr<pg::Pool> pool_;
  const std::string conninfo_;
  const absl::Duration health_timeout_;
  absl::Mutex health_mu_;
  std::unique_ptr<pg::Connection> health_ ABSL_GUARDED_BY(health_mu_);
  CommitObserver commit_observer_;
  mutable absl::Mutex stats_mu_;
  StoreWriteStats write_stats_ ABSL_GUARDED_BY(stats_mu_);
};

}  // namespace bitewise::bandit

#endif  // BITEWISE_SERVICES_BANDIT_STORE_POSTGRES_EVENT_STORE_H_
