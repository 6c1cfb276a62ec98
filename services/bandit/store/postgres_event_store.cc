// PostgresEventStore: opening the database (its schema), health and the
// write probe. The roles: postgres_event_log.cc, postgres_checkpoints.cc,
// postgres_pools_audit.cc.
#include "services/bandit/store/postgres_event_store.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "services/bandit/store/event_checksum.h"
#include "services/bandit/store/pg_helpers.h"
#include "services/bandit/store/pg_rows.h"
#include "services/bandit/store/store_rows.h"
#include "services/common/status_macros.h"

namespace bitewise::bandit {
namespace {

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
  phi_radius float8 NOT NULL DEFAULT 0.1,  -- poLinUCB's (schema 3)
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

// Schema 2 to 3: poLinUCB's phi_radius stored with each user (every user
// before had the default).
constexpr char kSchema3Sql[] = R"sql(
ALTER TABLE users ADD COLUMN phi_radius float8 NOT NULL DEFAULT 0.1;
UPDATE bitewise_store SET schema_version = 3;
)sql";

// FAILED_PRECONDITION when the server's fsync setting is off.
absl::Status RequireFsync(const Connection& conn, absl::string_view fsync) {
  if (fsync != "off") return absl::OkStatus();
  return absl::FailedPreconditionError(absl::StrCat(
      "PostgreSQL ", conn.description(),
      " runs with fsync off: acknowledged updates would not survive a "
      "power loss. Turn fsync on (postgresql.conf)"));
}

// Creates the schema in an empty database, or checks the one there.
absl::Status PrepareSchema(Connection& conn, bool create) {
  constexpr char kOp[] = "opening the store";
  ASSIGN_OR_RETURN(Rows fsync, conn.Exec("SHOW fsync", kOp));
  if (fsync.Next()) RETURN_IF_ERROR(RequireFsync(conn, fsync.Text(0)));
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
    const int64_t found = marker.Int64(1);
    if (found == 1) {
      // Every process on the database must be of this build: one of schema
      // 1 would lock users that the others no longer lock.
      RETURN_IF_ERROR(conn.ExecScript(kSchema2Sql, kOp));
    }
    if (found == 1 || found == 2) {
      RETURN_IF_ERROR(conn.ExecScript(kSchema3Sql, kOp));
    } else if (found != PostgresEventStore::kSchemaVersion) {
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
                   pg::Pool::Open(options.conninfo, options.connections,
                                  options.response_timeout));
  {
    ASSIGN_OR_RETURN(pg::Pool::Lease conn, pool->Acquire("opening the store"));
    RETURN_IF_ERROR(PrepareSchema(*conn, options.create_if_missing));
  }
  // The health check's statements are trivial: a server that takes longer
  // than 5 s to answer them is not one to report as serving.
  return std::unique_ptr<PostgresEventStore>(new PostgresEventStore(
      std::move(pool), options.conninfo,
      std::min(options.response_timeout, absl::Seconds(5))));
}

PostgresEventStore::PostgresEventStore(std::unique_ptr<pg::Pool> pool,
                                       std::string conninfo,
                                       absl::Duration health_timeout)
    : pool_(std::move(pool)),
      conninfo_(std::move(conninfo)),
      health_timeout_(health_timeout) {}

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
        Connection::Open(conninfo_, health_timeout_);
    if (!conn.ok()) return conn.status();
    health_ = *std::move(conn);
  } else if (health_->broken()) {
    RETURN_IF_ERROR(health_->Reconnect());
  }
  // Writable, not only reachable: a standby in recovery accepts reads. And
  // durable: fsync can be turned off by a reload or a restart under us.
  ASSIGN_OR_RETURN(
      Rows rows,
      health_->Exec("SELECT pg_is_in_recovery(), current_setting('fsync')",
                    "health check"));
  if (!rows.Next()) return absl::OkStatus();
  if (rows.Int64(0) != 0) {
    return absl::FailedPreconditionError(
        absl::StrCat("PostgreSQL ", health_->description(),
                     " is a standby in recovery: it cannot accept writes"));
  }
  return RequireFsync(*health_, rows.Text(1));
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

}  // namespace bitewise::bandit
