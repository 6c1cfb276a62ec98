#include "services/bandit/store/postgres_event_store.h"

#include <cmath>
#include <utility>

#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "services/bandit/store/event_checksum.h"
#include "services/bandit/store/pg_helpers.h"
#include "services/bandit/store/store_rows.h"
#include "services/common/status_macros.h"

namespace bitewise::bandit {
namespace {

using pg::Connection;
using pg::Params;
using pg::Rows;
using pg::Transaction;
using store_rows::ApproxBytes;
using store_rows::DecodePrior;
using store_rows::EncodeDoubles;
using store_rows::EncodePrior;
using store_rows::EventNotFound;
using store_rows::FromMicros;
using store_rows::ParsePageToken;
using store_rows::ToMicros;
using store_rows::UserNotFound;

constexpr char kApplication[] = "bitewise-bandit";

// Reads that must see one consistent state (a check and its rows).
constexpr char kSnapshot[] = "ISOLATION LEVEL REPEATABLE READ READ ONLY";

// The same tables and columns as the SQLite store's schema 5
// (sqlite_schema.cc), in PostgreSQL's types. bitewise_store marks the
// database as ours and holds the schema version.
constexpr char kSchemaSql[] = R"sql(
CREATE TABLE bitewise_store (
  singleton boolean PRIMARY KEY DEFAULT true CHECK (singleton),
  application text NOT NULL,
  schema_version bigint NOT NULL
);
-- User ids sort and compare by byte (COLLATE "C"), as in SQLite, whatever
-- the database's locale.
CREATE SEQUENCE user_incarnations;
CREATE TABLE users (
  user_id text COLLATE "C" PRIMARY KEY,
  learner bigint NOT NULL,
  strategy bigint NOT NULL,
  alpha float8 NOT NULL,
  lambda_c float8 NOT NULL,
  lambda_p float8 NOT NULL,
  epsilon float8 NOT NULL,
  importance_weighting boolean NOT NULL,
  context_dim bigint NOT NULL,
  posthoc_dim bigint NOT NULL,
  seed bigint NOT NULL,  -- the uint64 seed bit-cast to int64
  created_at_us bigint NOT NULL,
  model_version bigint NOT NULL DEFAULT 0,
  prior bytea,  -- the user's population prior (EncodePrior), NULL: none
  -- New at CreateUser and ResetUser: cached models of an older log are
  -- dropped by every process.
  incarnation bigint NOT NULL DEFAULT nextval('user_incarnations'),
  -- Selects since creation or reset (model_version + pending events; schema
  -- 2): the row changes with every event appended, so a write conditioned
  -- on where the log stands sees every other write of the user.
  selections bigint NOT NULL DEFAULT 0
);
CREATE TABLE user_actions (
  user_id text COLLATE "C" NOT NULL REFERENCES users (user_id) ON DELETE CASCADE,
  action bigint NOT NULL CHECK (action >= 0),
  name text NOT NULL,
  PRIMARY KEY (user_id, action)
);
-- A sequence never hands out a value twice, so ids are never reused.
CREATE TABLE events (
  event_id bigint GENERATED ALWAYS AS IDENTITY PRIMARY KEY,
  user_id text COLLATE "C" NOT NULL REFERENCES users (user_id) ON DELETE CASCADE,
  meal_id text NOT NULL,
  item_label text NOT NULL,
  action bigint NOT NULL,
  propensity float8 NOT NULL,
  selected_at_us bigint NOT NULL,
  completed boolean NOT NULL DEFAULT false,
  loss float8,
  posthoc bytea,  -- little-endian IEEE-754 float64 array
  weight float8,
  model_version bigint,
  updated_at_us bigint,
  selection_checksum bigint NOT NULL,
  outcome_checksum bigint,
  CHECK (completed = (model_version IS NOT NULL))
);
CREATE INDEX events_by_user ON events (user_id, event_id);
CREATE INDEX events_by_meal ON events (user_id, meal_id, event_id);
CREATE INDEX events_pending ON events (user_id) WHERE NOT completed;
CREATE UNIQUE INDEX events_by_completion
  ON events (user_id, model_version) WHERE completed;
-- Contexts apart from the events, so completing an event does not rewrite
-- its context; stored uncompressed (float64 arrays barely compress).
CREATE TABLE event_contexts (
  event_id bigint PRIMARY KEY REFERENCES events (event_id) ON DELETE CASCADE,
  context bytea NOT NULL
);
ALTER TABLE event_contexts ALTER COLUMN context SET STORAGE EXTERNAL;
CREATE TABLE population_pools (
  pool_version bigint GENERATED ALWAYS AS IDENTITY PRIMARY KEY,
  created_at_us bigint NOT NULL,
  users bigint NOT NULL,
  learner bigint NOT NULL,
  context_dim bigint NOT NULL,
  posthoc_dim bigint NOT NULL,
  prior bytea NOT NULL
);
CREATE TABLE pool_actions (
  pool_version bigint NOT NULL
    REFERENCES population_pools (pool_version) ON DELETE CASCADE,
  action bigint NOT NULL CHECK (action >= 0),
  name text NOT NULL,
  PRIMARY KEY (pool_version, action)
);
CREATE TABLE audit (
  audit_id bigint GENERATED ALWAYS AS IDENTITY PRIMARY KEY,
  at_us bigint NOT NULL,
  method text NOT NULL,
  target text NOT NULL,
  identity text NOT NULL,
  role text NOT NULL,
  peer text NOT NULL,
  result text NOT NULL
);
-- A checkpoint's chunks are written under a write id of their own, never
-- over another write's, and the header (written last) names its write.
CREATE SEQUENCE checkpoint_writes;
CREATE TABLE model_checkpoints (
  user_id text COLLATE "C" PRIMARY KEY REFERENCES users (user_id) ON DELETE CASCADE,
  model_version bigint NOT NULL CHECK (model_version > 0),
  last_event_id bigint NOT NULL,
  write_id bigint NOT NULL,
  state_bytes bigint NOT NULL,
  chunks bigint NOT NULL,
  checksum bigint NOT NULL,
  created_at_us bigint NOT NULL
);
CREATE TABLE model_checkpoint_chunks (
  user_id text COLLATE "C" NOT NULL REFERENCES users (user_id) ON DELETE CASCADE,
  write_id bigint NOT NULL,
  seq bigint NOT NULL,
  data bytea NOT NULL,
  PRIMARY KEY (user_id, write_id, seq)
);
ALTER TABLE model_checkpoint_chunks ALTER COLUMN data SET STORAGE EXTERNAL;
)sql";

// Schema 1 to 2: the users' selections, and no more lock function (replicas
// now write conditioned on where the log stands instead of locking users).
constexpr char kSchema2Sql[] = R"sql(
ALTER TABLE users ADD COLUMN selections bigint NOT NULL DEFAULT 0;
UPDATE users u SET selections = u.model_version +
  (SELECT count(*) FROM events e WHERE e.user_id = u.user_id AND NOT e.completed);
DROP FUNCTION IF EXISTS bitewise_enter_user(bigint, text);
UPDATE bitewise_store SET schema_version = 2;
)sql";

constexpr char kUserColumns[] = R"sql(
SELECT u.user_id, u.learner, u.strategy, u.alpha, u.lambda_c, u.lambda_p,
       u.epsilon, u.importance_weighting, u.context_dim, u.posthoc_dim,
       u.seed, u.created_at_us, u.model_version,
       (SELECT COUNT(*) FROM events e
        WHERE e.user_id = u.user_id AND NOT e.completed),
       u.prior, u.incarnation
FROM users u
)sql";

// An event's columns, as store_rows::ReadEventRow reads them, from `e` and
// its context `c`.
#define BITEWISE_EVENT_SELECT                                          \
  "SELECT e.event_id, e.user_id, e.meal_id, e.item_label, c.context, " \
  "e.action, e.propensity, e.selected_at_us, e.completed, e.loss, "    \
  "e.posthoc, e.weight, e.model_version, e.updated_at_us, "            \
  "e.selection_checksum, e.outcome_checksum "

// LEFT JOIN as in the SQLite store: a missing context fails the selection
// checksum (DATA_LOSS) instead of the event vanishing from the log.
constexpr char kEventColumns[] = BITEWISE_EVENT_SELECT
    "FROM events e LEFT JOIN event_contexts c ON c.event_id = e.event_id ";

// The event a completion's `e` (UPDATE ... RETURNING *) wrote, read the
// same way.
constexpr char kCompletedEvent[] = BITEWISE_EVENT_SELECT
    "FROM e LEFT JOIN event_contexts c ON c.event_id = e.event_id";
#undef BITEWISE_EVENT_SELECT

// $1..$7 of a completion: the event and its outcome, with the outcome's
// checksum.
Params OutcomeParams(int64_t event_id, double loss,
                     const std::string& posthoc_bytes, double weight,
                     int64_t model_version, int64_t updated_us) {
  return Params()
      .Int64(event_id)
      .Double(loss)
      .Bytes(posthoc_bytes)
      .Double(weight)
      .Int64(model_version)
      .Int64(updated_us)
      .Int64(OutcomeChecksum(loss, posthoc_bytes, weight, model_version,
                             updated_us));
}

// Why a completion wrote nothing: NOT_FOUND for an unknown event,
// FAILED_PRECONDITION for a completed one, else `if_pending`.
absl::Status NotCompleted(Connection& conn, int64_t event_id,
                          absl::Status if_pending) {
  ASSIGN_OR_RETURN(Rows found,
                   conn.Exec("SELECT completed FROM events WHERE event_id = $1",
                             Params().Int64(event_id), "CompleteEvent"));
  if (!found.Next()) return EventNotFound(event_id);
  if (found.Int64(0) != 0) return store_rows::AlreadyCompleted(event_id);
  return if_pending;
}

// A conditioned write refused because the user's log is no longer where
// the caller read it.
absl::Status LogMoved(const std::string& user_id) {
  return absl::AbortedError(
      absl::StrCat("user \"", user_id,
                   "\": another process wrote to the user's log since this "
                   "one read it (nothing written)"));
}

absl::Status WriteActionNames(Connection& conn, const char* table,
                              const char* key_column, Params key,
                              const std::vector<std::string>& names,
                              absl::string_view op) {
  const std::string sql = absl::StrCat("INSERT INTO ", table, " (", key_column,
                                       ", action, name) VALUES ($1, $2, $3)");
  for (size_t i = 0; i < names.size(); ++i) {
    Params row = key;
    row.Int64(static_cast<int64_t>(i)).Text(names[i]);
    RETURN_IF_ERROR(conn.Exec(sql, row, op).status());
  }
  return absl::OkStatus();
}

// In action order; DATA_LOSS unless the actions are 0, 1, ... with at least
// one.
absl::StatusOr<std::vector<std::string>> ReadActionNames(
    Connection& conn, const char* table, const char* key_column, Params key,
    absl::string_view what, absl::string_view op) {
  ASSIGN_OR_RETURN(
      Rows rows,
      conn.Exec(absl::StrCat("SELECT action, name FROM ", table, " WHERE ",
                             key_column, " = $1 ORDER BY action"),
                key, op));
  store_rows::ActionNamesReader names(what, table);
  while (rows.Next()) RETURN_IF_ERROR(names.Add(rows.Int64(0), rows.Text(1)));
  return names.Take();
}

absl::StatusOr<UserRecord> ReadUser(Connection& conn, Rows& rows) {
  ASSIGN_OR_RETURN(
      UserRecord user,
      store_rows::ReadUserRow(
          rows, [&conn](const std::string& user_id, const std::string& what) {
            return ReadActionNames(conn, "user_actions", "user_id",
                                   Params().Text(user_id), what,
                                   "reading action names");
          }));
  user.incarnation = rows.Int64(15);
  return user;
}

// Locks the user's row for the rest of the transaction: every write of a
// user's log takes this lock first, in every process.
absl::Status LockUser(Connection& conn, const std::string& user_id,
                      absl::string_view op) {
  ASSIGN_OR_RETURN(
      Rows rows, conn.Exec("SELECT 1 FROM users WHERE user_id = $1 FOR UPDATE",
                           Params().Text(user_id), op));
  if (rows.size() == 0) return UserNotFound(user_id);
  return absl::OkStatus();
}

absl::Status CheckUserExists(Connection& conn, const std::string& user_id,
                             absl::string_view op) {
  ASSIGN_OR_RETURN(Rows rows, conn.Exec("SELECT 1 FROM users WHERE "
                                        "user_id = $1",
                                        Params().Text(user_id), op));
  if (rows.size() == 0) return UserNotFound(user_id);
  return absl::OkStatus();
}

absl::StatusOr<ModelCheckpoint> ReadCheckpoint(Connection& conn,
                                               const std::string& user_id) {
  constexpr char kOp[] = "GetCheckpoint";
  ModelCheckpoint out;
  int64_t bytes = 0, chunks = 0, checksum = 0, write_id = 0;
  {
    ASSIGN_OR_RETURN(
        Rows rows,
        conn.Exec("SELECT model_version, last_event_id, state_bytes, chunks, "
                  "checksum, created_at_us, write_id FROM model_checkpoints "
                  "WHERE user_id = $1",
                  Params().Text(user_id), kOp));
    if (!rows.Next()) {
      return absl::NotFoundError(
          absl::StrCat("user ", user_id, " has no model checkpoint"));
    }
    out.model_version = rows.Int64(0);
    out.last_event_id = rows.Int64(1);
    bytes = rows.Int64(2);
    chunks = rows.Int64(3);
    checksum = rows.Int64(4);
    out.created_at = FromMicros(rows.Int64(5));
    write_id = rows.Int64(6);
  }
  int64_t expected_seq = 0;
  // One chunk per statement: a whole checkpoint is hundreds of MB.
  for (; expected_seq < chunks; ++expected_seq) {
    ASSIGN_OR_RETURN(
        Rows rows,
        conn.Exec("SELECT data FROM model_checkpoint_chunks WHERE user_id = "
                  "$1 AND write_id = $2 AND seq = $3",
                  Params().Text(user_id).Int64(write_id).Int64(expected_seq),
                  kOp));
    if (!rows.Next()) break;
    const absl::string_view data = rows.Blob(0);
    if (out.state.empty() && bytes > 0) {
      out.state.reserve(static_cast<size_t>(bytes));
    }
    out.state.append(data.data(), data.size());
  }
  if (expected_seq != chunks ||
      static_cast<int64_t>(out.state.size()) != bytes ||
      BlobChecksum(out.state) != checksum) {
    return store_rows::CheckpointDamaged(user_id, out.model_version,
                                         out.state.size(), bytes, expected_seq,
                                         chunks);
  }
  return out;
}

absl::Status DeleteCheckpointRows(Connection& conn, const std::string& user_id,
                                  absl::string_view op) {
  for (const char* sql :
       {"DELETE FROM model_checkpoints WHERE user_id = $1",
        "DELETE FROM model_checkpoint_chunks WHERE user_id = $1"}) {
    RETURN_IF_ERROR(conn.Exec(sql, Params().Text(user_id), op).status());
  }
  return absl::OkStatus();
}

// Creates the schema in an empty database, or checks the one there.
absl::Status PrepareSchema(Connection& conn, bool create) {
  constexpr char kOp[] = "opening the store";
  ASSIGN_OR_RETURN(Rows fsync, conn.Exec("SHOW fsync", kOp));
  if (fsync.Next() && fsync.Text(0) == "off") {
    return absl::FailedPreconditionError(absl::StrCat(
        "PostgreSQL ", conn.description(),
        " runs with fsync off: acknowledged updates would not survive a "
        "power loss. Turn fsync on (postgresql.conf)"));
  }
  ASSIGN_OR_RETURN(Transaction txn, Transaction::Begin(conn, kOp));
  // Two processes opening a new database at once: one creates, the other
  // then finds the schema.
  RETURN_IF_ERROR(
      conn.Exec("SELECT pg_advisory_xact_lock(hashtext('bitewise schema'))",
                kOp)
          .status());
  ASSIGN_OR_RETURN(
      Rows found,
      conn.Exec("SELECT to_regclass('bitewise_store') IS NOT NULL, "
                "to_regclass('users') IS NOT NULL OR to_regclass('events') "
                "IS NOT NULL",
                kOp));
  found.Next();
  if (found.Int64(0) == 0) {
    if (found.Int64(1) != 0) {
      return absl::FailedPreconditionError(absl::StrCat(
          "PostgreSQL ", conn.description(),
          " has tables named users or events that are not a bitewise store; "
          "use a database of its own"));
    }
    if (!create) {
      return absl::FailedPreconditionError(
          absl::StrCat("PostgreSQL ", conn.description(),
                       " holds no bitewise store; pass --create to make one "
                       "there (or correct --db)"));
    }
    RETURN_IF_ERROR(conn.ExecScript(kSchemaSql, kOp));
    RETURN_IF_ERROR(conn.Exec("INSERT INTO bitewise_store (application, "
                              "schema_version) VALUES ($1, $2)",
                              Params()
                                  .Text(kApplication)
                                  .Int64(PostgresEventStore::kSchemaVersion),
                              kOp)
                        .status());
  } else {
    ASSIGN_OR_RETURN(
        Rows marker,
        conn.Exec("SELECT application, schema_version FROM bitewise_store",
                  kOp));
    if (!marker.Next() || marker.Text(0) != kApplication) {
      return absl::FailedPreconditionError(
          absl::StrCat("PostgreSQL ", conn.description(),
                       ": bitewise_store does not mark a bitewise store"));
    }
    if (marker.Int64(1) == 1) {
      // Every process on the database must be of this build: one of schema
      // 1 would lock users that the others no longer lock.
      RETURN_IF_ERROR(conn.ExecScript(kSchema2Sql, kOp));
    } else if (marker.Int64(1) != PostgresEventStore::kSchemaVersion) {
      return absl::FailedPreconditionError(absl::StrCat(
          "PostgreSQL ", conn.description(), " has store schema version ",
          marker.Int64(1), "; this build reads version ",
          PostgresEventStore::kSchemaVersion));
    }
  }
  return txn.Commit();
}

}  // namespace

absl::StatusOr<std::unique_ptr<PostgresEventStore>> PostgresEventStore::Open(
    const PostgresStoreOptions& options) {
  if (options.conninfo.empty()) {
    return absl::InvalidArgumentError("PostgresStoreOptions.conninfo is empty");
  }
  ASSIGN_OR_RETURN(std::unique_ptr<pg::Pool> pool,
                   pg::Pool::Open(options.conninfo, options.connections));
  {
    ASSIGN_OR_RETURN(pg::Pool::Lease conn, pool->Acquire("opening the store"));
    RETURN_IF_ERROR(PrepareSchema(*conn, options.create_if_missing));
  }
  return std::unique_ptr<PostgresEventStore>(
      new PostgresEventStore(std::move(pool), options.conninfo));
}

PostgresEventStore::PostgresEventStore(std::unique_ptr<pg::Pool> pool,
                                       std::string conninfo)
    : pool_(std::move(pool)), conninfo_(std::move(conninfo)) {}

absl::StatusOr<UserLogPosition> PostgresEventStore::LogPosition(
    const std::string& user_id) {
  constexpr char kOp[] = "reading where a user's log stands";
  ASSIGN_OR_RETURN(pg::Pool::Lease conn, pool_->Acquire(kOp));
  ASSIGN_OR_RETURN(Rows rows,
                   conn->Exec("SELECT model_version, selections - "
                              "model_version, incarnation FROM users WHERE "
                              "user_id = $1",
                              Params().Text(user_id), kOp));
  if (!rows.Next()) return UserNotFound(user_id);
  return UserLogPosition{rows.Int64(0), rows.Int64(1), rows.Int64(2)};
}

PostgresEventStore::~PostgresEventStore() = default;

const std::string& PostgresEventStore::description() const {
  return pool_->description();
}

absl::Status PostgresEventStore::CheckHealth() {
  absl::MutexLock lock(&health_mu_);
  if (health_ == nullptr) {
    absl::StatusOr<std::unique_ptr<Connection>> conn =
        Connection::Open(conninfo_);
    if (!conn.ok()) return conn.status();
    health_ = *std::move(conn);
  } else if (health_->broken()) {
    RETURN_IF_ERROR(health_->Reconnect());
  }
  // Writable, not only reachable: a standby in recovery accepts reads.
  ASSIGN_OR_RETURN(Rows rows,
                   health_->Exec("SELECT pg_is_in_recovery()", "health check"));
  if (rows.Next() && rows.Int64(0) != 0) {
    return absl::FailedPreconditionError(
        absl::StrCat("PostgreSQL ", health_->description(),
                     " is a standby in recovery: it cannot accept writes"));
  }
  return absl::OkStatus();
}

absl::Status PostgresEventStore::ProbeWrite() {
  absl::MutexLock lock(&health_mu_);
  if (health_ == nullptr || health_->broken()) {
    return absl::UnavailableError("PostgreSQL: no health connection yet");
  }
  // A row into a session's temporary table: a transaction with a commit
  // record, and a page of the (emptied at each commit) table written to the
  // server's disk, so a server out of space fails it. Nothing the service
  // keeps is touched.
  RETURN_IF_ERROR(health_->ExecScript(
      "CREATE TEMP TABLE IF NOT EXISTS bitewise_write_probe (b text) "
      "ON COMMIT DELETE ROWS",
      "write probe"));
  return health_->ExecScript(
      "INSERT INTO bitewise_write_probe VALUES (repeat('x', 100))",
      "write probe");
}

void PostgresEventStore::CountWrite(bool append, absl::Time start,
                                    absl::Time commit_start) {
  const absl::Time now = absl::Now();
  if (commit_observer_) {
    commit_observer_(absl::ToDoubleSeconds(now - commit_start), 1);
  }
  absl::MutexLock lock(&stats_mu_);
  if (append) {
    ++write_stats_.appends;
    write_stats_.append_seconds += absl::ToDoubleSeconds(now - start);
  } else {
    ++write_stats_.completions;
    write_stats_.completion_seconds += absl::ToDoubleSeconds(now - start);
  }
  ++write_stats_.commits;
  ++write_stats_.committed_writes;
  write_stats_.commit_seconds += absl::ToDoubleSeconds(now - commit_start);
}

StoreWriteStats PostgresEventStore::write_stats() const {
  absl::MutexLock lock(&stats_mu_);
  return write_stats_;
}

absl::Status PostgresEventStore::CreateUser(const UserRecord& user) {
  constexpr char kOp[] = "CreateUser";
  if (user.user_id.empty()) {
    return absl::InvalidArgumentError("user_id must not be empty");
  }
  RETURN_IF_ERROR(ValidateConfig(user.config));
  const BanditConfig& c = user.config;
  ASSIGN_OR_RETURN(pg::Pool::Lease conn, pool_->Acquire(kOp));
  ASSIGN_OR_RETURN(Transaction txn, Transaction::Begin(*conn, kOp));
  Params params;
  params.Text(user.user_id)
      .Int64(static_cast<int64_t>(c.learner))
      .Int64(static_cast<int64_t>(c.strategy))
      .Double(c.alpha)
      .Double(c.lambda_c)
      .Double(c.lambda_p)
      .Double(c.epsilon)
      .Bool(c.importance_weighting)
      .Int64(c.context_dim)
      .Int64(c.posthoc_dim)
      .Int64(static_cast<int64_t>(c.seed))
      .Int64(ToMicros(user.created_at));
  if (c.prior.enabled()) {
    params.Bytes(EncodePrior(c.prior));
  } else {
    params.NullBytes();
  }
  // model_version and pending_events describe stored events, of which a new
  // user has none; the caller's values are ignored.
  ASSIGN_OR_RETURN(
      Rows inserted,
      conn->Exec("INSERT INTO users (user_id, learner, strategy, alpha, "
                 "lambda_c, lambda_p, epsilon, importance_weighting, "
                 "context_dim, posthoc_dim, seed, created_at_us, "
                 "model_version, prior) VALUES ($1, $2, $3, $4, $5, $6, $7, "
                 "$8, $9, $10, $11, $12, 0, $13) ON CONFLICT (user_id) DO "
                 "NOTHING RETURNING user_id",
                 params, kOp));
  if (inserted.size() == 0) {
    return absl::AlreadyExistsError(
        absl::StrCat("user \"", user.user_id, "\" already exists"));
  }
  RETURN_IF_ERROR(WriteActionNames(*conn, "user_actions", "user_id",
                                   Params().Text(user.user_id), c.action_names,
                                   kOp));
  return txn.Commit();
}

absl::StatusOr<UserRecord> PostgresEventStore::GetUser(
    const std::string& user_id) {
  constexpr char kOp[] = "GetUser";
  ASSIGN_OR_RETURN(pg::Pool::Lease conn, pool_->Acquire(kOp));
  ASSIGN_OR_RETURN(Transaction txn, Transaction::Begin(*conn, kOp, kSnapshot));
  ASSIGN_OR_RETURN(
      Rows rows, conn->Exec(absl::StrCat(kUserColumns, "WHERE u.user_id = $1"),
                            Params().Text(user_id), kOp));
  if (!rows.Next()) return UserNotFound(user_id);
  ASSIGN_OR_RETURN(UserRecord user, ReadUser(*conn, rows));
  RETURN_IF_ERROR(txn.Commit());
  return user;
}

absl::StatusOr<PageResult<UserRecord>> PostgresEventStore::ListUsers(
    const Page& page) {
  constexpr char kOp[] = "ListUsers";
  store_rows::PageBuilder<UserRecord> out(
      page, 'u', [](const UserRecord& user) { return user.user_id; });
  std::string after;
  if (!page.page_token.empty()) {
    ASSIGN_OR_RETURN(after, ParsePageToken(page.page_token, 'u'));
  }
  ASSIGN_OR_RETURN(pg::Pool::Lease conn, pool_->Acquire(kOp));
  ASSIGN_OR_RETURN(Transaction txn, Transaction::Begin(*conn, kOp, kSnapshot));
  ASSIGN_OR_RETURN(
      Rows rows,
      conn->Exec(absl::StrCat(kUserColumns,
                              "WHERE u.user_id > $2 "
                              "ORDER BY u.user_id LIMIT $1"),
                 Params().Int64(out.page_size() + 1).Text(after), kOp));
  while (rows.Next() && out.Room()) {
    ASSIGN_OR_RETURN(UserRecord user, ReadUser(*conn, rows));
    const int64_t bytes = ApproxBytes(user);
    if (!out.Add(std::move(user), bytes)) break;
  }
  RETURN_IF_ERROR(txn.Commit());
  return out.Take();
}

absl::Status PostgresEventStore::DeleteUser(const std::string& user_id) {
  constexpr char kOp[] = "DeleteUser";
  ASSIGN_OR_RETURN(pg::Pool::Lease conn, pool_->Acquire(kOp));
  ASSIGN_OR_RETURN(Transaction txn, Transaction::Begin(*conn, kOp));
  RETURN_IF_ERROR(LockUser(*conn, user_id, kOp));
  // The user's events and checkpoint go with it (ON DELETE CASCADE).
  RETURN_IF_ERROR(conn->Exec("DELETE FROM users WHERE user_id = $1",
                             Params().Text(user_id), kOp)
                      .status());
  return txn.Commit();
}

absl::Status PostgresEventStore::ResetUser(const std::string& user_id) {
  constexpr char kOp[] = "ResetUser";
  ASSIGN_OR_RETURN(pg::Pool::Lease conn, pool_->Acquire(kOp));
  ASSIGN_OR_RETURN(Transaction txn, Transaction::Begin(*conn, kOp));
  RETURN_IF_ERROR(LockUser(*conn, user_id, kOp));
  for (const char* sql :
       {"UPDATE users SET model_version = 0, selections = 0, incarnation = "
        "nextval('user_incarnations') WHERE user_id = $1",
        "DELETE FROM events WHERE user_id = $1"}) {
    RETURN_IF_ERROR(conn->Exec(sql, Params().Text(user_id), kOp).status());
  }
  RETURN_IF_ERROR(DeleteCheckpointRows(*conn, user_id, kOp));
  return txn.Commit();
}

absl::StatusOr<int64_t> PostgresEventStore::AppendPending(
    const EventRecord& event) {
  return Append(event, nullptr);
}

absl::StatusOr<int64_t> PostgresEventStore::AppendPendingAt(
    const EventRecord& event, const UserLogPosition& at) {
  return Append(event, &at);
}

absl::StatusOr<int64_t> PostgresEventStore::Append(const EventRecord& event,
                                                   const UserLogPosition* at) {
  constexpr char kOp[] = "AppendPending";
  if (std::isnan(event.propensity)) {
    return absl::InvalidArgumentError("propensity must not be NaN");
  }
  const absl::Time start = absl::Now();
  const std::string context = EncodeDoubles(event.context);
  const int64_t checksum = SelectionChecksum(
      event.user_id, event.meal_id, event.item_label, context, event.action,
      event.propensity, ToMicros(event.selected_at));
  Params params = Params()
                      .Text(event.user_id)
                      .Text(event.meal_id)
                      .Text(event.item_label)
                      .Int64(event.action)
                      .Double(event.propensity)
                      .Int64(ToMicros(event.selected_at))
                      .Int64(checksum)
                      .Bytes(context);
  if (at != nullptr) {
    params.Int64(at->model_version)
        .Int64(at->model_version + at->pending_events)
        .Int64(at->incarnation);
  }
  ASSIGN_OR_RETURN(pg::Pool::Lease conn, pool_->Acquire(kOp));
  // One statement, so one transaction: the user's count of selections, the
  // event and its context, only if the user exists (and, with `at`, its log
  // stands there); no row back means nothing was written.
  absl::StatusOr<Rows> rows = conn->Exec(
      absl::StrCat(
          "WITH u AS (UPDATE users SET selections = selections + 1 WHERE "
          "user_id = $1",
          at != nullptr ? " AND model_version = $9 AND selections = $10 AND "
                          "incarnation = $11"
                        : "",
          " RETURNING user_id), e AS (INSERT INTO events (user_id, meal_id, "
          "item_label, action, propensity, selected_at_us, "
          "selection_checksum) SELECT $1, $2, $3, $4, $5, $6, $7 FROM u "
          "RETURNING event_id) INSERT INTO event_contexts (event_id, context) "
          "SELECT event_id, $8 FROM e RETURNING event_id"),
      params, kOp);
  // A user deleted meanwhile fails the foreign key: also unknown.
  if (!rows.ok() && absl::IsFailedPrecondition(rows.status())) {
    return UserNotFound(event.user_id);
  }
  RETURN_IF_ERROR(rows.status());
  if (!rows->Next()) {
    if (at == nullptr) return UserNotFound(event.user_id);
    ASSIGN_OR_RETURN(Rows user, conn->Exec("SELECT 1 FROM users WHERE "
                                           "user_id = $1",
                                           Params().Text(event.user_id), kOp));
    if (!user.Next()) return UserNotFound(event.user_id);
    return LogMoved(event.user_id);
  }
  const int64_t event_id = rows->Int64(0);
  CountWrite(/*append=*/true, start, start);
  return event_id;
}

absl::StatusOr<EventRecord> PostgresEventStore::CompleteEvent(
    int64_t event_id, double loss, const std::vector<double>& posthoc,
    double weight, absl::Time updated_at) {
  constexpr char kOp[] = "CompleteEvent";
  RETURN_IF_ERROR(store_rows::CheckOutcome(loss, weight));
  const absl::Time start = absl::Now();
  const std::string posthoc_bytes = EncodeDoubles(posthoc);
  ASSIGN_OR_RETURN(pg::Pool::Lease conn, pool_->Acquire(kOp));
  ASSIGN_OR_RETURN(Transaction txn, Transaction::Begin(*conn, kOp));
  // The user's row first (the order every writer of a user's log takes),
  // then the event, now that no other completion of this user can run.
  int64_t model_version = 0;
  {
    ASSIGN_OR_RETURN(
        Rows rows,
        conn->Exec("UPDATE users SET model_version = model_version + 1 "
                   "WHERE user_id = (SELECT user_id FROM events WHERE "
                   "event_id = $1) RETURNING model_version",
                   Params().Int64(event_id), kOp));
    // No such event (or its user was deleted, with it).
    if (!rows.Next()) return EventNotFound(event_id);
    model_version = rows.Int64(0);
  }
  const int64_t updated_us = ToMicros(updated_at);
  // Completed only if still pending; the row comes back as stored, its
  // context with it, and is checked like any read.
  ASSIGN_OR_RETURN(
      Rows rows,
      conn->Exec(
          absl::StrCat(
              "WITH e AS (UPDATE events SET completed = true, loss = $2, "
              "posthoc = $3, weight = $4, model_version = $5, updated_at_us = "
              "$6, outcome_checksum = $7 WHERE event_id = $1 AND NOT completed "
              "RETURNING *) ",
              kCompletedEvent),
          OutcomeParams(event_id, loss, posthoc_bytes, weight, model_version,
                        updated_us),
          kOp));
  if (!rows.Next()) {
    // Rolled back: it was completed already, or removed by a reset that
    // committed just before this transaction locked the user.
    return NotCompleted(*conn, event_id,
                        store_rows::AlreadyCompleted(event_id));
  }
  ASSIGN_OR_RETURN(EventRecord event, store_rows::ReadEventRow(rows));
  const absl::Time commit_start = absl::Now();
  RETURN_IF_ERROR(txn.Commit());
  CountWrite(/*append=*/false, start, commit_start);
  return event;
}

absl::StatusOr<EventRecord> PostgresEventStore::CompleteEventAt(
    const std::string& user_id, int64_t event_id, double loss,
    const std::vector<double>& posthoc, double weight, absl::Time updated_at,
    const UserLogPosition& at) {
  constexpr char kOp[] = "CompleteEvent";
  RETURN_IF_ERROR(store_rows::CheckOutcome(loss, weight));
  const absl::Time start = absl::Now();
  const std::string posthoc_bytes = EncodeDoubles(posthoc);
  const int64_t model_version = at.model_version + 1;
  const int64_t updated_us = ToMicros(updated_at);
  ASSIGN_OR_RETURN(pg::Pool::Lease conn, pool_->Acquire(kOp));
  // One statement, so one transaction and one round trip: the user's
  // version moves from `at`'s to the next (a compare-and-set on the version
  // and incarnation, under the user's row lock, which every writer of the
  // user's log takes and which makes a waiting writer re-check the row)
  // only if the event is the user's and pending, and the event is
  // completed only if the version moved. No row back: nothing written.
  ASSIGN_OR_RETURN(
      Rows rows,
      conn->Exec(
          absl::StrCat(
              "WITH u AS (UPDATE users SET model_version = $5 WHERE user_id = "
              "$8 AND model_version = $5 - 1 AND incarnation = $9 AND EXISTS "
              "(SELECT 1 FROM events WHERE event_id = $1 AND user_id = $8 "
              "AND NOT completed) RETURNING 1), e AS (UPDATE events SET "
              "completed = true, loss = $2, posthoc = $3, weight = $4, "
              "model_version = $5, updated_at_us = $6, outcome_checksum = $7 "
              "WHERE event_id = $1 AND user_id = $8 AND NOT completed AND "
              "EXISTS (SELECT 1 FROM u) RETURNING *) ",
              kCompletedEvent),
          OutcomeParams(event_id, loss, posthoc_bytes, weight, model_version,
                        updated_us)
              .Text(user_id)
              .Int64(at.incarnation),
          kOp));
  if (!rows.Next()) return NotCompleted(*conn, event_id, LogMoved(user_id));
  ASSIGN_OR_RETURN(EventRecord event, store_rows::ReadEventRow(rows));
  CountWrite(/*append=*/false, start, start);
  return event;
}

absl::StatusOr<EventRecord> PostgresEventStore::GetEvent(int64_t event_id) {
  constexpr char kOp[] = "GetEvent";
  ASSIGN_OR_RETURN(pg::Pool::Lease conn, pool_->Acquire(kOp));
  ASSIGN_OR_RETURN(Rows rows, conn->Exec(absl::StrCat(kEventColumns,
                                                      "WHERE e.event_id = $1"),
                                         Params().Int64(event_id), kOp));
  if (!rows.Next()) return EventNotFound(event_id);
  return store_rows::ReadEventRow(rows);
}

absl::StatusOr<PageResult<EventRecord>> PostgresEventStore::ListEvents(
    const std::string& user_id, const std::string& meal_id, const Page& page) {
  constexpr char kOp[] = "ListEvents";
  store_rows::PageBuilder<EventRecord> out(
      page, 'e',
      [](const EventRecord& event) { return absl::StrCat(event.event_id); });
  int64_t after = 0;  // event ids start at 1
  if (!page.page_token.empty()) {
    ASSIGN_OR_RETURN(after, store_rows::ParseIdPageToken(page.page_token, 'e'));
  }
  ASSIGN_OR_RETURN(pg::Pool::Lease conn, pool_->Acquire(kOp));
  // One snapshot for the existence check and the rows.
  ASSIGN_OR_RETURN(Transaction txn, Transaction::Begin(*conn, kOp, kSnapshot));
  RETURN_IF_ERROR(CheckUserExists(*conn, user_id, kOp));
  Params params;
  params.Text(user_id).Int64(after).Int64(out.page_size() + 1);
  if (!meal_id.empty()) params.Text(meal_id);
  ASSIGN_OR_RETURN(
      Rows rows,
      conn->Exec(absl::StrCat(kEventColumns, "WHERE e.user_id = $1 ",
                              meal_id.empty() ? "" : "AND e.meal_id = $4 ",
                              "AND e.event_id > $2 ORDER BY e.event_id "
                              "LIMIT $3"),
                 params, kOp));
  while (rows.Next() && out.Room()) {
    ASSIGN_OR_RETURN(EventRecord event, store_rows::ReadEventRow(rows));
    const int64_t bytes = ApproxBytes(event);
    if (!out.Add(std::move(event), bytes)) break;
  }
  RETURN_IF_ERROR(txn.Commit());
  return out.Take();
}

absl::StatusOr<std::vector<EventRecord>> PostgresEventStore::CompletedEvents(
    const std::string& user_id) {
  return CompletedEventsFrom(user_id, 1);
}

absl::StatusOr<std::vector<EventRecord>>
PostgresEventStore::CompletedEventsFrom(const std::string& user_id,
                                        int64_t from_version) {
  constexpr char kOp[] = "CompletedEvents";
  constexpr int64_t kBatch = 1000;
  ASSIGN_OR_RETURN(pg::Pool::Lease conn, pool_->Acquire(kOp));
  ASSIGN_OR_RETURN(Transaction txn, Transaction::Begin(*conn, kOp, kSnapshot));
  RETURN_IF_ERROR(CheckUserExists(*conn, user_id, kOp));
  // In batches of model versions: the server never holds a whole log of
  // 16 KB contexts in one result.
  std::vector<EventRecord> events;
  int64_t next = from_version;
  while (true) {
    ASSIGN_OR_RETURN(
        Rows rows,
        conn->Exec(absl::StrCat(kEventColumns,
                                "WHERE e.user_id = $1 AND e.completed AND "
                                "e.model_version >= $2 ORDER BY "
                                "e.model_version LIMIT $3"),
                   Params().Text(user_id).Int64(next).Int64(kBatch), kOp));
    while (rows.Next()) {
      ASSIGN_OR_RETURN(EventRecord event, store_rows::ReadEventRow(rows));
      next = event.model_version + 1;
      events.push_back(std::move(event));
    }
    if (rows.size() < kBatch) break;
  }
  RETURN_IF_ERROR(txn.Commit());
  return events;
}

absl::Status PostgresEventStore::PutCheckpoint(
    const std::string& user_id, const ModelCheckpoint& checkpoint) {
  constexpr char kOp[] = "PutCheckpoint";
  if (checkpoint.model_version <= 0 || checkpoint.state.empty()) {
    return absl::InvalidArgumentError(
        "checkpoint: needs model_version > 0 and a state");
  }
  const absl::string_view state = checkpoint.state;
  const int64_t chunks = static_cast<int64_t>(
      (state.size() + kCheckpointChunkBytes - 1) / kCheckpointChunkBytes);
  ASSIGN_OR_RETURN(pg::Pool::Lease conn, pool_->Acquire(kOp));
  int64_t write_id = 0;
  {
    ASSIGN_OR_RETURN(Rows rows,
                     conn->Exec("SELECT nextval('checkpoint_writes')", kOp));
    if (!rows.Next()) return absl::InternalError("PutCheckpoint: no write id");
    write_id = rows.Int64(0);
  }
  // The chunks first, each its own transaction (one statement), under this
  // write's own id: nothing another write reads is overwritten.
  for (int64_t seq = 0; seq < chunks; ++seq) {
    absl::Status written =
        conn->Exec(
                "INSERT INTO model_checkpoint_chunks (user_id, write_id, "
                "seq, data) VALUES ($1, $2, $3, $4)",
                Params().Text(user_id).Int64(write_id).Int64(seq).Bytes(
                    state.substr(seq * kCheckpointChunkBytes,
                                 kCheckpointChunkBytes)),
                kOp)
            .status();
    // The foreign key: the user is unknown (or was deleted meanwhile).
    if (absl::IsFailedPrecondition(written)) return UserNotFound(user_id);
    RETURN_IF_ERROR(written);
  }
  // Then the header, under the user's lock, if the log still has this
  // event at this version and every chunk of this write is still there
  // (a concurrent checkpoint or delete removes chunks it does not keep);
  // the chunks of every other write go.
  ASSIGN_OR_RETURN(Transaction txn, Transaction::Begin(*conn, kOp));
  RETURN_IF_ERROR(LockUser(*conn, user_id, kOp));
  ASSIGN_OR_RETURN(
      Rows current,
      conn->Exec("SELECT 1 FROM events WHERE user_id = $1 AND completed AND "
                 "model_version = $2 AND event_id = $3",
                 Params()
                     .Text(user_id)
                     .Int64(checkpoint.model_version)
                     .Int64(checkpoint.last_event_id),
                 kOp));
  const bool is_current = current.size() > 0;
  ASSIGN_OR_RETURN(
      Rows stored,
      conn->Exec("SELECT count(*), coalesce(sum(length(data)), 0) FROM "
                 "model_checkpoint_chunks WHERE user_id = $1 AND write_id = $2",
                 Params().Text(user_id).Int64(write_id), kOp));
  stored.Next();
  const bool complete = stored.Int64(0) == chunks &&
                        stored.Int64(1) == static_cast<int64_t>(state.size());
  if (is_current && complete) {
    RETURN_IF_ERROR(
        conn->Exec("INSERT INTO model_checkpoints (user_id, model_version, "
                   "last_event_id, write_id, state_bytes, chunks, checksum, "
                   "created_at_us) VALUES ($1, $2, $3, $4, $5, $6, $7, $8) "
                   "ON CONFLICT (user_id) DO UPDATE SET model_version = "
                   "EXCLUDED.model_version, last_event_id = "
                   "EXCLUDED.last_event_id, write_id = EXCLUDED.write_id, "
                   "state_bytes = EXCLUDED.state_bytes, chunks = "
                   "EXCLUDED.chunks, checksum = EXCLUDED.checksum, "
                   "created_at_us = EXCLUDED.created_at_us "
                   // A replica whose model is behind never replaces a
                   // newer checkpoint with its older one.
                   "WHERE model_checkpoints.model_version <= "
                   "EXCLUDED.model_version",
                   Params()
                       .Text(user_id)
                       .Int64(checkpoint.model_version)
                       .Int64(checkpoint.last_event_id)
                       .Int64(write_id)
                       .Int64(static_cast<int64_t>(state.size()))
                       .Int64(chunks)
                       .Int64(BlobChecksum(state))
                       .Int64(ToMicros(checkpoint.created_at)),
                   kOp)
            .status());
  }
  // Kept: the current header's chunks (and none if there is no header).
  RETURN_IF_ERROR(
      conn->Exec("DELETE FROM model_checkpoint_chunks c WHERE c.user_id = $1 "
                 "AND NOT EXISTS (SELECT 1 FROM model_checkpoints h WHERE "
                 "h.user_id = $1 AND h.write_id = c.write_id)",
                 Params().Text(user_id), kOp)
          .status());
  RETURN_IF_ERROR(txn.Commit());
  if (is_current && !complete) {
    return absl::AbortedError(absl::StrCat(
        "checkpoint of user ", user_id, " at model version ",
        checkpoint.model_version,
        ": a concurrent checkpoint or delete removed its chunks; not kept"));
  }
  if (!is_current) {
    return store_rows::CheckpointNotKept(user_id, checkpoint);
  }
  return absl::OkStatus();
}

absl::StatusOr<ModelCheckpoint> PostgresEventStore::GetCheckpoint(
    const std::string& user_id) {
  constexpr char kOp[] = "GetCheckpoint";
  ASSIGN_OR_RETURN(pg::Pool::Lease conn, pool_->Acquire(kOp));
  ASSIGN_OR_RETURN(Transaction txn, Transaction::Begin(*conn, kOp, kSnapshot));
  RETURN_IF_ERROR(CheckUserExists(*conn, user_id, kOp));
  ASSIGN_OR_RETURN(ModelCheckpoint out, ReadCheckpoint(*conn, user_id));
  RETURN_IF_ERROR(txn.Commit());
  return out;
}

absl::Status PostgresEventStore::DeleteCheckpoint(const std::string& user_id) {
  constexpr char kOp[] = "DeleteCheckpoint";
  ASSIGN_OR_RETURN(pg::Pool::Lease conn, pool_->Acquire(kOp));
  ASSIGN_OR_RETURN(Transaction txn, Transaction::Begin(*conn, kOp));
  RETURN_IF_ERROR(LockUser(*conn, user_id, kOp));
  RETURN_IF_ERROR(DeleteCheckpointRows(*conn, user_id, kOp));
  return txn.Commit();
}

absl::StatusOr<int64_t> PostgresEventStore::AddPool(const PoolRecord& pool) {
  constexpr char kOp[] = "AddPool";
  PopulationPrior stored = pool.prior;
  stored.pool_version = 0;
  stored.rounds = 0.0;
  ASSIGN_OR_RETURN(pg::Pool::Lease conn, pool_->Acquire(kOp));
  ASSIGN_OR_RETURN(Transaction txn, Transaction::Begin(*conn, kOp));
  ASSIGN_OR_RETURN(
      Rows rows,
      conn->Exec("INSERT INTO population_pools (created_at_us, users, "
                 "learner, context_dim, posthoc_dim, prior) VALUES ($1, $2, "
                 "$3, $4, $5, $6) RETURNING pool_version",
                 Params()
                     .Int64(ToMicros(pool.created_at))
                     .Int64(pool.users)
                     .Int64(static_cast<int64_t>(pool.learner))
                     .Int64(pool.context_dim)
                     .Int64(pool.posthoc_dim)
                     .Bytes(EncodePrior(stored)),
                 kOp));
  if (!rows.Next()) return absl::InternalError("AddPool: no pool_version");
  const int64_t version = rows.Int64(0);
  RETURN_IF_ERROR(WriteActionNames(*conn, "pool_actions", "pool_version",
                                   Params().Int64(version), pool.action_names,
                                   kOp));
  RETURN_IF_ERROR(txn.Commit());
  return version;
}

absl::StatusOr<PoolRecord> PostgresEventStore::LatestPool(
    const BanditConfig& config) {
  constexpr char kOp[] = "LatestPool";
  const int posthoc_dim =
      config.learner == Learner::kPostHoc ? config.posthoc_dim : 0;
  ASSIGN_OR_RETURN(pg::Pool::Lease conn, pool_->Acquire(kOp));
  ASSIGN_OR_RETURN(Transaction txn, Transaction::Begin(*conn, kOp, kSnapshot));
  // The newest pool of this learner and these dimensions whose actions are
  // the user's, name for name.
  ASSIGN_OR_RETURN(
      Rows rows,
      conn->Exec("SELECT pool_version, created_at_us, users, prior FROM "
                 "population_pools WHERE learner = $1 AND context_dim = $2 "
                 "AND posthoc_dim = $3 ORDER BY pool_version DESC",
                 Params()
                     .Int64(static_cast<int64_t>(config.learner))
                     .Int64(config.context_dim)
                     .Int64(posthoc_dim),
                 kOp));
  while (rows.Next()) {
    PoolRecord pool;
    pool.pool_version = rows.Int64(0);
    const std::string what = absl::StrCat("pool ", pool.pool_version);
    ASSIGN_OR_RETURN(
        pool.action_names,
        ReadActionNames(*conn, "pool_actions", "pool_version",
                        Params().Int64(pool.pool_version), what, kOp));
    if (pool.action_names != config.action_names) continue;
    pool.created_at = FromMicros(rows.Int64(1));
    pool.users = rows.Int64(2);
    pool.learner = config.learner;
    pool.context_dim = config.context_dim;
    pool.posthoc_dim = posthoc_dim;
    ASSIGN_OR_RETURN(pool.prior, DecodePrior(rows.Blob(3), what));
    pool.prior.pool_version = pool.pool_version;
    RETURN_IF_ERROR(txn.Commit());
    return pool;
  }
  return store_rows::NoPoolFor(config, posthoc_dim);
}

absl::StatusOr<int64_t> PostgresEventStore::AppendAudit(
    const AuditEntry& entry) {
  constexpr char kOp[] = "AppendAudit";
  ASSIGN_OR_RETURN(pg::Pool::Lease conn, pool_->Acquire(kOp));
  ASSIGN_OR_RETURN(Rows rows,
                   conn->Exec("INSERT INTO audit (at_us, method, target, "
                              "identity, role, peer, result) VALUES ($1, $2, "
                              "$3, $4, $5, $6, $7) RETURNING audit_id",
                              Params()
                                  .Int64(ToMicros(entry.time))
                                  .Text(entry.method)
                                  .Text(entry.target)
                                  .Text(entry.identity)
                                  .Text(entry.role)
                                  .Text(entry.peer)
                                  .Text(entry.result),
                              kOp));
  if (!rows.Next()) return absl::InternalError("AppendAudit: no audit_id");
  return rows.Int64(0);
}

absl::StatusOr<PageResult<AuditEntry>> PostgresEventStore::ListAudit(
    const Page& page) {
  constexpr char kOp[] = "ListAudit";
  store_rows::PageBuilder<AuditEntry> out(
      page, 'a',
      [](const AuditEntry& entry) { return absl::StrCat(entry.audit_id); });
  int64_t after = 0;
  if (!page.page_token.empty()) {
    ASSIGN_OR_RETURN(after, store_rows::ParseIdPageToken(page.page_token, 'a'));
  }
  ASSIGN_OR_RETURN(pg::Pool::Lease conn, pool_->Acquire(kOp));
  ASSIGN_OR_RETURN(
      Rows rows,
      conn->Exec("SELECT audit_id, at_us, method, target, identity, role, "
                 "peer, result FROM audit WHERE audit_id > $1 ORDER BY "
                 "audit_id LIMIT $2",
                 Params().Int64(after).Int64(out.page_size() + 1), kOp));
  while (rows.Next() && out.Room()) {
    out.Add(store_rows::ReadAuditRow(rows), /*bytes=*/0);
  }
  return out.Take();
}

absl::StatusOr<StoreCheckReport> PostgresEventStore::CheckStore() {
  constexpr char kOp[] = "CheckStore";
  constexpr int64_t kBatch = 500;
  ASSIGN_OR_RETURN(pg::Pool::Lease conn, pool_->Acquire(kOp));
  ASSIGN_OR_RETURN(Transaction txn, Transaction::Begin(*conn, kOp, kSnapshot));
  store_rows::CheckReportBuilder report;
  {
    ASSIGN_OR_RETURN(
        Rows users,
        conn->Exec(absl::StrCat(kUserColumns, "ORDER BY u.user_id"), kOp));
    while (users.Next()) RETURN_IF_ERROR(report.User(ReadUser(*conn, users)));
  }
  {
    // Each user's count of selections, which replicas index the random
    // stream with, against the log.
    ASSIGN_OR_RETURN(
        Rows counts,
        conn->Exec("SELECT user_id, selections, n FROM (SELECT u.user_id, "
                   "u.selections, u.model_version + (SELECT count(*) FROM "
                   "events e WHERE e.user_id = u.user_id AND NOT e.completed) "
                   "AS n FROM users u) c WHERE selections <> n ORDER BY "
                   "user_id",
                   kOp));
    while (counts.Next()) {
      RETURN_IF_ERROR(report.User(absl::DataLossError(
          absl::StrCat("user \"", counts.Text(0), "\" counts ", counts.Int64(1),
                       " selections, but its log holds ", counts.Int64(2),
                       " (completed and pending)"))));
    }
  }
  // In batches: the server never holds every context in one result.
  for (int64_t after = 0;;) {
    ASSIGN_OR_RETURN(Rows events,
                     conn->Exec(absl::StrCat(kEventColumns,
                                             "WHERE e.event_id > $1 ORDER BY "
                                             "e.event_id LIMIT $2"),
                                Params().Int64(after).Int64(kBatch), kOp));
    while (events.Next()) {
      after = events.Int64(0);
      RETURN_IF_ERROR(report.Event(store_rows::ReadEventRow(events).status()));
    }
    if (events.size() < kBatch) break;
  }
  {
    std::vector<std::string> with_checkpoint;
    ASSIGN_OR_RETURN(Rows rows,
                     conn->Exec("SELECT user_id FROM model_checkpoints ORDER "
                                "BY user_id",
                                kOp));
    while (rows.Next()) with_checkpoint.push_back(rows.Text(0));
    for (const std::string& user_id : with_checkpoint) {
      RETURN_IF_ERROR(
          report.Checkpoint(ReadCheckpoint(*conn, user_id).status()));
    }
  }
  RETURN_IF_ERROR(txn.Commit());
  return report.Take();
}

}  // namespace bitewise::bandit
