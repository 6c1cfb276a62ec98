#include "services/bandit/store/sqlite_schema.h"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "absl/strings/ascii.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "services/bandit/store/event_checksum.h"
#include "services/bandit/store/sqlite_helpers.h"
#include "services/common/status_macros.h"

namespace bitewise::bandit::sqlite {
namespace {

// 'BiTe': marks the file as ours, so a SQLite file of another application is
// refused instead of having tables added to it.
constexpr int kApplicationId = 0x42695465;

// Scalar doubles are declared ANY with a type check rather than REAL: SQLite
// stores an integral REAL as an integer on disk, which turns -0.0 into 0.0.
// ANY in a STRICT table keeps the bound value exactly, and STRICT makes every
// other column reject values of the wrong type.
constexpr char kSchemaSql[] = R"sql(
CREATE TABLE users (
  user_id TEXT PRIMARY KEY NOT NULL,
  learner INTEGER NOT NULL,
  strategy INTEGER NOT NULL,
  alpha ANY NOT NULL CHECK (typeof(alpha) = 'real'),
  lambda_c ANY NOT NULL CHECK (typeof(lambda_c) = 'real'),
  lambda_p ANY NOT NULL CHECK (typeof(lambda_p) = 'real'),
  epsilon ANY NOT NULL CHECK (typeof(epsilon) = 'real'),
  importance_weighting INTEGER NOT NULL CHECK (importance_weighting IN (0, 1)),
  context_dim INTEGER NOT NULL,
  posthoc_dim INTEGER NOT NULL,
  seed INTEGER NOT NULL,  -- the uint64 seed bit-cast to int64
  created_at_us INTEGER NOT NULL,
  model_version INTEGER NOT NULL DEFAULT 0,
  phi_radius ANY NOT NULL DEFAULT 0.1 CHECK (typeof(phi_radius) = 'real'),
  prior BLOB  -- the user's population prior (EncodePrior), NULL: none
) STRICT;

-- AUTOINCREMENT: ids are never reused after ResetUser or DeleteUser, so an id
-- a client still holds cannot silently name someone else's new event.
CREATE TABLE events (
  event_id INTEGER PRIMARY KEY AUTOINCREMENT,
  user_id TEXT NOT NULL REFERENCES users (user_id) ON DELETE CASCADE,
  meal_id TEXT NOT NULL,
  item_label TEXT NOT NULL,
  -- The context is in event_contexts (schema 5).
  action INTEGER NOT NULL,
  propensity ANY NOT NULL CHECK (typeof(propensity) = 'real'),
  selected_at_us INTEGER NOT NULL,
  completed INTEGER NOT NULL DEFAULT 0 CHECK (completed IN (0, 1)),
  -- The outcome: NULL while pending, all set once completed.
  loss ANY CHECK (typeof(loss) IN ('real', 'null')),
  posthoc BLOB,  -- little-endian IEEE-754 float64 array
  weight ANY CHECK (typeof(weight) IN ('real', 'null')),
  model_version INTEGER,
  updated_at_us INTEGER,
  -- event_checksum.h: of the selection's columns, and of the outcome's
  -- (NULL while pending).
  selection_checksum INTEGER NOT NULL,
  outcome_checksum INTEGER,
  CHECK ((completed = 1) = (model_version IS NOT NULL))
) STRICT;

CREATE INDEX events_by_user ON events (user_id, event_id);
CREATE INDEX events_by_meal ON events (user_id, meal_id, event_id);
-- Unique: two completed events of a user can never share a model_version
-- (pending rows have NULL there, and NULLs do not collide).
CREATE UNIQUE INDEX events_by_completion
  ON events (user_id, completed, model_version);
)sql";

// The events' contexts, apart from the events (schema 5): completing an event
// rewrites its row, and without its context that row is a few dozen bytes
// instead of 8 d (16 KB at d = 2048, written twice with the WAL).
constexpr char kEventContextsSql[] = R"sql(
CREATE TABLE event_contexts (
  event_id INTEGER PRIMARY KEY
    REFERENCES events (event_id) ON DELETE CASCADE,
  context BLOB NOT NULL  -- little-endian IEEE-754 float64 array
) STRICT;
)sql";

// Schema 4 to 5, after kEventContextsSql: the contexts move out of events
// (DROP COLUMN rewrites the table once).
constexpr char kMoveContextsSql[] = R"sql(
INSERT INTO event_contexts (event_id, context)
  SELECT event_id, context FROM events;
ALTER TABLE events DROP COLUMN context;
)sql";

// Schema 6: a large context may live in the contexts file beside the
// database (context_file.h) instead of event_contexts: its offset and length
// there, both NULL for a context in event_contexts.
constexpr char kContextFileSql[] = R"sql(
ALTER TABLE events ADD COLUMN context_offset INTEGER;
ALTER TABLE events ADD COLUMN context_bytes INTEGER;
)sql";

// Action names, one row per action in the user's order (schema 3). Names
// may hold any byte; TEXT keeps them as bound, and readable in the shell.
constexpr char kUserActionsSql[] = R"sql(
CREATE TABLE user_actions (
  user_id TEXT NOT NULL REFERENCES users (user_id) ON DELETE CASCADE,
  action INTEGER NOT NULL CHECK (action >= 0),
  name TEXT NOT NULL,
  PRIMARY KEY (user_id, action)
) STRICT, WITHOUT ROWID;
)sql";

// The population pools and their action names (schema 3).
constexpr char kPoolsSql[] = R"sql(
CREATE TABLE population_pools (
  pool_version INTEGER PRIMARY KEY AUTOINCREMENT,
  created_at_us INTEGER NOT NULL,
  users INTEGER NOT NULL,
  learner INTEGER NOT NULL,
  context_dim INTEGER NOT NULL,
  posthoc_dim INTEGER NOT NULL,
  prior BLOB NOT NULL  -- EncodePrior with rounds 0
) STRICT;
)sql";

constexpr char kPoolActionsSql[] = R"sql(
CREATE TABLE pool_actions (
  pool_version INTEGER NOT NULL
    REFERENCES population_pools (pool_version) ON DELETE CASCADE,
  action INTEGER NOT NULL CHECK (action >= 0),
  name TEXT NOT NULL,
  PRIMARY KEY (pool_version, action)
) STRICT, WITHOUT ROWID;
)sql";

// The audit log of administrative calls (schema 3).
constexpr char kAuditSql[] = R"sql(
CREATE TABLE audit (
  audit_id INTEGER PRIMARY KEY AUTOINCREMENT,
  at_us INTEGER NOT NULL,
  method TEXT NOT NULL,
  target TEXT NOT NULL,
  identity TEXT NOT NULL,
  role TEXT NOT NULL,
  peer TEXT NOT NULL,
  result TEXT NOT NULL
) STRICT;
)sql";

// Model checkpoints (schema 4): each user's newest, its bytes in chunks
// written in their own transactions, the header row last. An optimisation
// only: the event log stays the truth.
constexpr char kCheckpointsSql[] = R"sql(
CREATE TABLE model_checkpoints (
  user_id TEXT PRIMARY KEY REFERENCES users (user_id) ON DELETE CASCADE,
  model_version INTEGER NOT NULL CHECK (model_version > 0),
  last_event_id INTEGER NOT NULL,
  state_bytes INTEGER NOT NULL,
  chunks INTEGER NOT NULL,
  checksum INTEGER NOT NULL,
  created_at_us INTEGER NOT NULL
) STRICT;
CREATE TABLE model_checkpoint_chunks (
  user_id TEXT NOT NULL REFERENCES users (user_id) ON DELETE CASCADE,
  model_version INTEGER NOT NULL,
  seq INTEGER NOT NULL,
  data BLOB NOT NULL,
  PRIMARY KEY (user_id, model_version, seq)
) STRICT;
)sql";

// Version 6 -> 7 stores poLinUCB's phi_radius with each user.
constexpr char kMigrateTo7Sql[] = R"sql(
ALTER TABLE users ADD COLUMN phi_radius ANY NOT NULL DEFAULT 0.1
  CHECK (typeof(phi_radius) = 'real');
)sql";

// Version 1 -> 2 added the users' priors and the pools, whose action names
// were then a JSON column like the users'.
constexpr char kMigrateTo2Sql[] = R"sql(
ALTER TABLE users ADD COLUMN prior BLOB;
CREATE TABLE population_pools (
  pool_version INTEGER PRIMARY KEY AUTOINCREMENT,
  created_at_us INTEGER NOT NULL,
  users INTEGER NOT NULL,
  learner INTEGER NOT NULL,
  context_dim INTEGER NOT NULL,
  posthoc_dim INTEGER NOT NULL,
  action_names TEXT NOT NULL,
  prior BLOB NOT NULL
) STRICT;
)sql";

void AppendUtf8(uint32_t cp, std::string& out) {
  if (cp < 0x80) {
    out += static_cast<char>(cp);
  } else if (cp < 0x800) {
    out += static_cast<char>(0xc0 | (cp >> 6));
    out += static_cast<char>(0x80 | (cp & 0x3f));
  } else {
    out += static_cast<char>(0xe0 | (cp >> 12));
    out += static_cast<char>(0x80 | ((cp >> 6) & 0x3f));
    out += static_cast<char>(0x80 | (cp & 0x3f));
  }
}

// Version 2 stored action names as a JSON array of strings. This reads
// what version 2 wrote plus the other JSON string escapes (the column may
// have been edited by hand); anything else is DATA_LOSS. It runs only in the
// migration: SQLite's json_each would do the same but cuts a string at
// \u0000, and a name may hold any byte.
absl::StatusOr<std::vector<std::string>> DecodeVersion2Names(
    absl::string_view text) {
  const absl::Status bad = absl::DataLossError(
      absl::StrCat("malformed action_names column: ", text));
  std::vector<std::string> names;
  size_t pos = 0;
  auto at = [&](char c) { return pos < text.size() && text[pos] == c; };
  if (!at('[')) return bad;
  ++pos;
  if (at(']')) {
    ++pos;
    return pos == text.size() ? absl::StatusOr<std::vector<std::string>>(names)
                              : bad;
  }
  while (true) {
    if (!at('"')) return bad;
    ++pos;
    std::string name;
    while (true) {
      if (pos >= text.size()) return bad;
      const char c = text[pos++];
      if (c == '"') break;
      if (static_cast<unsigned char>(c) < 0x20) return bad;
      if (c != '\\') {
        name += c;
        continue;
      }
      if (pos >= text.size()) return bad;
      const char e = text[pos++];
      switch (e) {
        case '"':
        case '\\':
        case '/':
          name += e;
          break;
        case 'b':
          name += '\b';
          break;
        case 'f':
          name += '\f';
          break;
        case 'n':
          name += '\n';
          break;
        case 'r':
          name += '\r';
          break;
        case 't':
          name += '\t';
          break;
        case 'u': {
          if (pos + 4 > text.size()) return bad;
          uint32_t cp = 0;
          for (int k = 0; k < 4; ++k) {
            const char h = text[pos++];
            cp <<= 4;
            if (h >= '0' && h <= '9') {
              cp |= static_cast<uint32_t>(h - '0');
            } else if (h >= 'a' && h <= 'f') {
              cp |= static_cast<uint32_t>(h - 'a' + 10);
            } else if (h >= 'A' && h <= 'F') {
              cp |= static_cast<uint32_t>(h - 'A' + 10);
            } else {
              return bad;
            }
          }
          // Version 2 never wrote surrogates; pairs are not worth parsing.
          if (cp >= 0xd800 && cp <= 0xdfff) return bad;
          AppendUtf8(cp, name);
          break;
        }
        default:
          return bad;
      }
    }
    names.push_back(std::move(name));
    if (at(',')) {
      ++pos;
      continue;
    }
    if (!at(']')) return bad;
    ++pos;
    if (pos != text.size()) return bad;
    return names;
  }
}

// Version 2 -> 3: action names from the JSON columns into the child tables.
absl::Status CopyVersion2Names(sqlite3* db, const char* select,
                               const char* insert, const std::string& op) {
  ASSIGN_OR_RETURN(Statement rows, Statement::Prepare(db, select, op));
  while (true) {
    ASSIGN_OR_RETURN(const bool row, rows.Step());
    if (!row) return absl::OkStatus();
    const std::string key = rows.Text(0);
    absl::StatusOr<std::vector<std::string>> names =
        DecodeVersion2Names(rows.Text(1));
    if (!names.ok()) {
      return absl::DataLossError(
          absl::StrCat(op, ": ", key, ": ", names.status().message()));
    }
    for (size_t i = 0; i < names->size(); ++i) {
      ASSIGN_OR_RETURN(Statement st, Statement::Prepare(db, insert, op));
      st.BindText(1, key);
      st.BindInt64(2, static_cast<int64_t>(i));
      st.BindText(3, (*names)[i]);
      RETURN_IF_ERROR(st.Run());
    }
  }
}

// Version 2 -> 3 also gives every event its checksums.
absl::Status AddEventChecksums(sqlite3* db, const std::string& op) {
  RETURN_IF_ERROR(Exec(db,
                       "ALTER TABLE events ADD COLUMN selection_checksum "
                       "INTEGER NOT NULL DEFAULT 0",
                       op));
  RETURN_IF_ERROR(
      Exec(db, "ALTER TABLE events ADD COLUMN outcome_checksum INTEGER", op));
  ASSIGN_OR_RETURN(
      Statement rows,
      Statement::Prepare(db,
                         "SELECT event_id, user_id, meal_id, item_label, "
                         "context, action, propensity, selected_at_us, "
                         "completed, loss, posthoc, weight, model_version, "
                         "updated_at_us FROM events",
                         op));
  while (true) {
    ASSIGN_OR_RETURN(const bool row, rows.Step());
    if (!row) return absl::OkStatus();
    ASSIGN_OR_RETURN(Statement st,
                     Statement::Prepare(db,
                                        "UPDATE events SET selection_checksum "
                                        "= ?2, outcome_checksum = ?3 WHERE "
                                        "event_id = ?1",
                                        op));
    st.BindInt64(1, rows.Int64(0));
    st.BindInt64(2, SelectionChecksum(rows.Text(1), rows.Text(2), rows.Text(3),
                                      rows.Blob(4), rows.Int64(5),
                                      rows.Double(6), rows.Int64(7)));
    if (rows.Int64(8) != 0) {
      st.BindInt64(
          3, OutcomeChecksum(rows.Double(9), rows.Blob(10), rows.Double(11),
                             rows.Int64(12), rows.Int64(13)));
    }
    RETURN_IF_ERROR(st.Run());
  }
}

absl::Status MigrateTo3(sqlite3* db, const std::string& op) {
  RETURN_IF_ERROR(AddEventChecksums(db, op));
  RETURN_IF_ERROR(Exec(db, kAuditSql, op));
  RETURN_IF_ERROR(Exec(db, kUserActionsSql, op));
  RETURN_IF_ERROR(Exec(db, kPoolActionsSql, op));
  RETURN_IF_ERROR(CopyVersion2Names(
      db, "SELECT user_id, action_names FROM users",
      "INSERT INTO user_actions (user_id, action, name) VALUES (?1, ?2, ?3)",
      op));
  RETURN_IF_ERROR(CopyVersion2Names(
      db, "SELECT pool_version, action_names FROM population_pools",
      "INSERT INTO pool_actions (pool_version, action, name) "
      "VALUES (CAST(?1 AS INTEGER), ?2, ?3)",
      op));
  RETURN_IF_ERROR(Exec(db, "ALTER TABLE users DROP COLUMN action_names", op));
  return Exec(db, "ALTER TABLE population_pools DROP COLUMN action_names", op);
}

// Returns the file's schema version after checking that this build may use
// the file: 0 for a brand-new (empty) database, 1..kSchemaVersion for a store
// (older versions are migrated).
absl::StatusOr<int64_t> CheckExistingFile(sqlite3* db,
                                          const std::string& path) {
  // The first read of the file is where SQLite notices it is not a database.
  const int rc = sqlite3_exec(db, "SELECT COUNT(*) FROM sqlite_schema", nullptr,
                              nullptr, nullptr);
  if ((rc & 0xff) == SQLITE_NOTADB) {
    return absl::FailedPreconditionError(
        absl::StrCat(path, " is not a SQLite database"));
  }
  if (rc != SQLITE_OK) {
    return SqliteError(db, rc, absl::StrCat("opening ", path));
  }
  const std::string op = absl::StrCat("opening ", path);
  ASSIGN_OR_RETURN(const int64_t version,
                   ReadInt(db, "PRAGMA user_version", op));
  ASSIGN_OR_RETURN(const int64_t app_id,
                   ReadInt(db, "PRAGMA application_id", op));
  ASSIGN_OR_RETURN(const int64_t objects,
                   ReadInt(db, "SELECT COUNT(*) FROM sqlite_schema", op));
  if (app_id != 0 && app_id != kApplicationId) {
    return absl::FailedPreconditionError(
        absl::StrCat(path,
                     " is a SQLite database of another application "
                     "(application_id ",
                     app_id, ")"));
  }
  if (version == 0) {
    if (objects != 0) {
      return absl::FailedPreconditionError(
          absl::StrCat(path,
                       " is a SQLite database but not a bitewise bandit store "
                       "(it has tables and no schema version)"));
    }
    return 0;
  }
  if (version < 1 || version > kSchemaVersion) {
    return absl::FailedPreconditionError(absl::StrCat(
        path, " has bandit store schema version ", version,
        "; this build knows version ", kSchemaVersion,
        version > kSchemaVersion ? " (written by a newer build?)" : ""));
  }
  if (app_id != kApplicationId) {
    return absl::FailedPreconditionError(
        absl::StrCat(path, " has schema version ", version,
                     " but is not marked as a bitewise bandit store"));
  }
  return version;
}

}  // namespace

absl::Status InitializeDatabase(sqlite3* db,
                                const SqliteStoreOptions& options) {
  const std::string& path = options.path;
  const std::string op = absl::StrCat("opening ", path);
  // Check before changing anything: a foreign file must stay untouched, and
  // switching to WAL rewrites the header.
  ASSIGN_OR_RETURN(const int64_t found_version, CheckExistingFile(db, path));
  if (found_version == 0) {
    // A new file's pages are 1 KB (SQLite's default is 4): each commit
    // writes whole pages of every table and index it touches, twice with
    // the write-ahead log, and the hot path's rows are small (benchmarks.md,
    // bytes written per pair). Only possible before the first table.
    RETURN_IF_ERROR(Exec(db, "PRAGMA page_size = 1024", op));
  }

  {
    ASSIGN_OR_RETURN(Statement st,
                     Statement::Prepare(db, "PRAGMA journal_mode = WAL", op));
    ASSIGN_OR_RETURN(const bool row, st.Step());
    const std::string mode = row ? st.Text(0) : "";
    RETURN_IF_ERROR(st.Run());
    // An in-memory database reports "memory" and has no journal to speak of.
    if (mode != "wal" && mode != "memory") {
      return absl::FailedPreconditionError(absl::StrCat(
          path, ": cannot switch to WAL journal mode (got \"", mode, "\")"));
    }
  }
  RETURN_IF_ERROR(Exec(db, "PRAGMA foreign_keys = ON", op));
  ASSIGN_OR_RETURN(const int64_t foreign_keys,
                   ReadInt(db, "PRAGMA foreign_keys", op));
  if (foreign_keys != 1) {
    // DeleteUser relies on ON DELETE CASCADE.
    return absl::FailedPreconditionError(
        absl::StrCat(op, ": this SQLite build cannot enforce foreign keys"));
  }
  RETURN_IF_ERROR(Exec(db,
                       options.synchronous_full ? "PRAGMA synchronous = FULL"
                                                : "PRAGMA synchronous = NORMAL",
                       op));

  // Check again under the write lock: another process may have created the
  // schema since the first look.
  ASSIGN_OR_RETURN(Transaction txn,
                   Transaction::Begin(db, Transaction::Kind::kWrite, op));
  ASSIGN_OR_RETURN(const int64_t version, CheckExistingFile(db, path));
  if (version == 0) {
    RETURN_IF_ERROR(Exec(db, kSchemaSql, op));
    RETURN_IF_ERROR(Exec(db, kUserActionsSql, op));
    RETURN_IF_ERROR(Exec(db, kPoolsSql, op));
    RETURN_IF_ERROR(Exec(db, kPoolActionsSql, op));
    RETURN_IF_ERROR(Exec(db, kAuditSql, op));
    RETURN_IF_ERROR(Exec(db, kCheckpointsSql, op));
    RETURN_IF_ERROR(Exec(db, kEventContextsSql, op));
    RETURN_IF_ERROR(Exec(db, kContextFileSql, op));
    RETURN_IF_ERROR(Exec(
        db, absl::StrCat("PRAGMA application_id = ", kApplicationId).c_str(),
        op));
    RETURN_IF_ERROR(
        Exec(db, absl::StrCat("PRAGMA user_version = ", kSchemaVersion).c_str(),
             op));
  } else {
    if (version == 1) {
      RETURN_IF_ERROR(Exec(db, kMigrateTo2Sql, op));
    }
    if (version <= 2) {
      RETURN_IF_ERROR(MigrateTo3(db, op));
    }
    if (version <= 3) {
      RETURN_IF_ERROR(Exec(db, kCheckpointsSql, op));
    }
    if (version <= 4) {
      RETURN_IF_ERROR(Exec(db, kEventContextsSql, op));
      RETURN_IF_ERROR(Exec(db, kMoveContextsSql, op));
    }
    if (version <= 5) {
      RETURN_IF_ERROR(Exec(db, kContextFileSql, op));
    }
    if (version <= 6) {
      // Every user before version 7 had poLinUCB's default radius.
      RETURN_IF_ERROR(Exec(db, kMigrateTo7Sql, op));
    }
    RETURN_IF_ERROR(
        Exec(db, absl::StrCat("PRAGMA user_version = ", kSchemaVersion).c_str(),
             op));
  }
  return txn.Commit();
}

// Takes an exclusive advisory lock on "<path>.lock" (released by the
// kernel when the process ends, however it ends) and writes our pid into
// it. ":memory:" needs none (-1). FAILED_PRECONDITION naming the holder when
// another process has the store open; UNAVAILABLE if the lock file cannot
// be made.
std::string StoreFilesBase(const std::string& path) {
  if (path == ":memory:") return path;
  std::error_code error;
  const std::filesystem::path real =
      std::filesystem::weakly_canonical(path, error);
  return error ? path : real.string();
}

absl::StatusOr<int> LockStoreFile(const std::string& path,
                                  const std::string& real_path) {
  if (path == ":memory:") return -1;
  const std::string lock_path = real_path + ".lock";
  const int fd = open(lock_path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd < 0) {
    return absl::UnavailableError(absl::StrCat(
        "cannot create the lock file ", lock_path, ": ", std::strerror(errno)));
  }
  if (flock(fd, LOCK_EX | LOCK_NB) != 0) {
    char holder[32] = {0};
    const ssize_t n = pread(fd, holder, sizeof(holder) - 1, 0);
    close(fd);
    return absl::FailedPreconditionError(absl::StrCat(
        path, " is already open in another process (pid ",
        n > 0 ? absl::StripAsciiWhitespace(holder) : "unknown", ", holding ",
        lock_path,
        "); one BanditService per database file: two would serve models that "
        "miss each other's updates"));
  }
  const std::string pid = absl::StrCat(getpid(), "\n");
  if (ftruncate(fd, 0) != 0 || pwrite(fd, pid.data(), pid.size(), 0) !=
                                   static_cast<ssize_t>(pid.size())) {
    // The lock is what matters; the pid is for the message.
  }
  return fd;
}

// PRAGMA integrity_check: a file whose structure is damaged (flipped bytes,
// a torn copy) must not be served as if it were whole. DATA_LOSS naming the
// path and SQLite's first findings.
absl::StatusOr<std::vector<std::string>> IntegrityFindings(sqlite3* db,
                                                           int max_findings) {
  ASSIGN_OR_RETURN(
      Statement st,
      Statement::Prepare(
          db, absl::StrCat("PRAGMA integrity_check(", max_findings, ")"),
          "integrity check"));
  std::vector<std::string> findings;
  while (true) {
    ASSIGN_OR_RETURN(const bool row, st.Step());
    if (!row) break;
    findings.push_back(st.Text(0));
  }
  if (findings.size() == 1 && findings[0] == "ok") findings.clear();
  return findings;
}

absl::Status CheckIntegrity(sqlite3* db, const std::string& path) {
  ASSIGN_OR_RETURN(const std::vector<std::string> findings,
                   IntegrityFindings(db, 5));
  if (findings.empty()) return absl::OkStatus();
  return absl::DataLossError(absl::StrCat(
      path, " failed SQLite's integrity check: ", absl::StrJoin(findings, "; "),
      ". Restore the last backup (docs/operations.md)"));
}

}  // namespace bitewise::bandit::sqlite
