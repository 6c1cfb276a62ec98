#include "services/bandit/store/sqlite_event_store.h"

#include <fcntl.h>
#include <sqlite3.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <limits>
#include <utility>

#include "absl/strings/ascii.h"
#include "absl/strings/escaping.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "absl/strings/string_view.h"
#include "services/common/status_macros.h"

namespace bitewise::bandit {
namespace {

// Bumped whenever the schema changes incompatibly; a file with a larger
// version was written by a newer build and must not be touched.
// 2: users.prior and population_pools (the population prior); a version 1
// file is migrated when opened.
constexpr int kSchemaVersion = 2;
// 'BiTe': marks the file as ours, so a SQLite file of another application is
// refused instead of having tables added to it.
constexpr int kApplicationId = 0x42695465;

constexpr int kDefaultPageSize = 100;
constexpr int kMaxPageSize = 1000;

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
  action_names TEXT NOT NULL,  -- JSON array of strings
  seed INTEGER NOT NULL,       -- the uint64 seed bit-cast to int64
  created_at_us INTEGER NOT NULL,
  model_version INTEGER NOT NULL DEFAULT 0,
  prior BLOB  -- the user's population prior (EncodePrior), NULL: none
) STRICT;

-- AUTOINCREMENT: ids are never reused after ResetUser or DeleteUser, so an id
-- a client still holds cannot silently name someone else's new event.
CREATE TABLE events (
  event_id INTEGER PRIMARY KEY AUTOINCREMENT,
  user_id TEXT NOT NULL REFERENCES users (user_id) ON DELETE CASCADE,
  meal_id TEXT NOT NULL,
  item_label TEXT NOT NULL,
  context BLOB NOT NULL,  -- little-endian IEEE-754 float64 array
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
  CHECK ((completed = 1) = (model_version IS NOT NULL))
) STRICT;

CREATE INDEX events_by_user ON events (user_id, event_id);
CREATE INDEX events_by_meal ON events (user_id, meal_id, event_id);
-- Unique: two completed events of a user can never share a model_version
-- (pending rows have NULL there, and NULLs do not collide).
CREATE UNIQUE INDEX events_by_completion
  ON events (user_id, completed, model_version);
)sql";

// The population pools (schema 2), created with a new store and by the
// migration from version 1.
constexpr char kPoolsSql[] = R"sql(
CREATE TABLE population_pools (
  pool_version INTEGER PRIMARY KEY AUTOINCREMENT,
  created_at_us INTEGER NOT NULL,
  users INTEGER NOT NULL,
  learner INTEGER NOT NULL,
  context_dim INTEGER NOT NULL,
  posthoc_dim INTEGER NOT NULL,
  action_names TEXT NOT NULL,  -- JSON array of strings
  prior BLOB NOT NULL          -- EncodePrior with rounds 0
) STRICT;
)sql";

// Version 1 -> 2: the users' priors, then kPoolsSql.
constexpr char kMigrateTo2Sql[] = R"sql(
ALTER TABLE users ADD COLUMN prior BLOB;
)sql";

constexpr char kUserColumns[] = R"sql(
SELECT u.user_id, u.learner, u.strategy, u.alpha, u.lambda_c, u.lambda_p,
       u.epsilon, u.importance_weighting, u.context_dim, u.posthoc_dim,
       u.action_names, u.seed, u.created_at_us, u.model_version,
       (SELECT COUNT(*) FROM events e
        WHERE e.user_id = u.user_id AND e.completed = 0),
       u.prior
FROM users u
)sql";

constexpr char kEventColumns[] = R"sql(
SELECT event_id, user_id, meal_id, item_label, context, action, propensity,
       selected_at_us, completed, loss, posthoc, weight, model_version,
       updated_at_us
FROM events
)sql";

// ---------------------------------------------------------------------------
// Errors

absl::StatusCode CodeForSqlite(int rc) {
  switch (rc & 0xff) {
    case SQLITE_BUSY:
    case SQLITE_LOCKED:
      return absl::StatusCode::kUnavailable;  // retrying later can succeed
    case SQLITE_CONSTRAINT:
      return absl::StatusCode::kFailedPrecondition;
    case SQLITE_CORRUPT:
    case SQLITE_NOTADB:
      return absl::StatusCode::kDataLoss;
    case SQLITE_FULL:
    case SQLITE_NOMEM:
      return absl::StatusCode::kResourceExhausted;
    case SQLITE_CANTOPEN:
    case SQLITE_READONLY:
    case SQLITE_PERM:
    case SQLITE_AUTH:
      return absl::StatusCode::kFailedPrecondition;
    case SQLITE_TOOBIG:
    case SQLITE_RANGE:
    case SQLITE_MISMATCH:
      return absl::StatusCode::kInvalidArgument;
    default:
      return absl::StatusCode::kInternal;
  }
}

absl::Status SqliteError(sqlite3* db, int rc, absl::string_view op) {
  // The connection's message is more specific than the code's, but only if it
  // belongs to this failure; sqlite3_errcode tells.
  const char* message = (db != nullptr && sqlite3_extended_errcode(db) == rc)
                            ? sqlite3_errmsg(db)
                            : sqlite3_errstr(rc);
  return absl::Status(
      CodeForSqlite(rc),
      absl::StrCat(op, ": ", message, " (sqlite code ", rc, ")"));
}

// ---------------------------------------------------------------------------
// Encodings

int64_t ToMicros(absl::Time t) { return absl::ToUnixMicros(t); }
absl::Time FromMicros(int64_t us) { return absl::FromUnixMicros(us); }

// Byte by byte so the file reads the same on any host.
std::string EncodeDoubles(const std::vector<double>& values) {
  std::string out(values.size() * 8, '\0');
  for (size_t i = 0; i < values.size(); ++i) {
    uint64_t bits;
    std::memcpy(&bits, &values[i], sizeof(bits));
    for (int b = 0; b < 8; ++b) {
      out[i * 8 + b] = static_cast<char>((bits >> (8 * b)) & 0xff);
    }
  }
  return out;
}

absl::StatusOr<std::vector<double>> DecodeDoubles(absl::string_view bytes,
                                                  absl::string_view what) {
  if (bytes.size() % 8 != 0) {
    return absl::DataLossError(absl::StrCat(what, ": stored vector has ",
                                            bytes.size(),
                                            " bytes, not a multiple of 8"));
  }
  std::vector<double> values(bytes.size() / 8);
  for (size_t i = 0; i < values.size(); ++i) {
    uint64_t bits = 0;
    for (int b = 0; b < 8; ++b) {
      bits |=
          static_cast<uint64_t>(static_cast<unsigned char>(bytes[i * 8 + b]))
          << (8 * b);
    }
    std::memcpy(&values[i], &bits, sizeof(bits));
  }
  return values;
}

// A population prior as one float64 array: pool_version, rounds,
// context_msn, posthoc_msn, K, d, q, then theta0 (K x d) and phi0 (K x q).
std::string EncodePrior(const PopulationPrior& prior) {
  const size_t k = prior.theta0.size();
  const size_t d = k > 0 ? prior.theta0[0].size() : 0;
  const size_t q = prior.phi0.empty() ? 0 : prior.phi0[0].size();
  std::vector<double> v = {static_cast<double>(prior.pool_version),
                           prior.rounds,
                           prior.context_msn,
                           prior.posthoc_msn,
                           static_cast<double>(k),
                           static_cast<double>(d),
                           static_cast<double>(q)};
  for (const auto& row : prior.theta0)
    v.insert(v.end(), row.begin(), row.end());
  for (const auto& row : prior.phi0) v.insert(v.end(), row.begin(), row.end());
  return EncodeDoubles(v);
}

absl::StatusOr<PopulationPrior> DecodePrior(absl::string_view bytes,
                                            absl::string_view what) {
  ASSIGN_OR_RETURN(const std::vector<double> v, DecodeDoubles(bytes, what));
  auto bad = [&] {
    return absl::DataLossError(
        absl::StrCat(what, ": stored population prior is malformed"));
  };
  if (v.size() < 7) return bad();
  for (int i = 4; i < 7; ++i) {
    if (!(v[i] >= 0 && v[i] <= (1 << 16) && v[i] == std::floor(v[i]))) {
      return bad();
    }
  }
  const size_t k = static_cast<size_t>(v[4]), d = static_cast<size_t>(v[5]),
               q = static_cast<size_t>(v[6]);
  if (v.size() != 7 + k * d + k * q) return bad();
  PopulationPrior prior;
  prior.pool_version = static_cast<int64_t>(v[0]);
  prior.rounds = v[1];
  prior.context_msn = v[2];
  prior.posthoc_msn = v[3];
  size_t at = 7;
  for (size_t a = 0; a < k; ++a, at += d) {
    prior.theta0.emplace_back(v.begin() + at, v.begin() + at + d);
  }
  for (size_t a = 0; a < k && q > 0; ++a, at += q) {
    prior.phi0.emplace_back(v.begin() + at, v.begin() + at + q);
  }
  return prior;
}

// Action names may hold any byte, so no separator is safe; a JSON array of
// strings is unambiguous and still readable in the sqlite3 shell.
std::string EncodeNames(const std::vector<std::string>& names) {
  static constexpr char kHex[] = "0123456789abcdef";
  std::string out = "[";
  for (size_t i = 0; i < names.size(); ++i) {
    if (i > 0) out += ',';
    out += '"';
    for (const char ch : names[i]) {
      const auto c = static_cast<unsigned char>(ch);
      if (c == '"' || c == '\\') {
        out += '\\';
        out += ch;
      } else if (c < 0x20) {
        out += "\\u00";
        out += kHex[c >> 4];
        out += kHex[c & 0xf];
      } else {
        out += ch;
      }
    }
    out += '"';
  }
  out += ']';
  return out;
}

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

// Parses what EncodeNames writes plus the other JSON string escapes (the
// column may have been edited by hand); anything else is DATA_LOSS.
absl::StatusOr<std::vector<std::string>> DecodeNames(absl::string_view text) {
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
          // EncodeNames never writes surrogates; pairs are not worth parsing.
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

// Page tokens are opaque to clients: a kind tag keeps a user token from being
// replayed against an event listing, and base64 keeps arbitrary user ids
// printable.
std::string MakePageToken(char kind, absl::string_view key) {
  return absl::WebSafeBase64Escape(
      absl::StrCat(std::string(1, kind), ":", key));
}

// Returns the key of a token made by MakePageToken(kind, key).
absl::StatusOr<std::string> ParsePageToken(const std::string& token,
                                           char kind) {
  std::string raw;
  if (!absl::WebSafeBase64Unescape(token, &raw) || raw.size() < 2 ||
      raw[0] != kind || raw[1] != ':') {
    return absl::InvalidArgumentError("invalid page_token");
  }
  return raw.substr(2);
}

absl::StatusOr<int64_t> ParseEventPageToken(const std::string& token) {
  ASSIGN_OR_RETURN(const std::string key, ParsePageToken(token, 'e'));
  int64_t last_event_id = 0;
  if (!absl::SimpleAtoi(key, &last_event_id) || last_event_id <= 0) {
    return absl::InvalidArgumentError("invalid page_token");
  }
  return last_event_id;
}

int ClampPageSize(int page_size) {
  if (page_size <= 0) return kDefaultPageSize;
  return std::min(page_size, kMaxPageSize);
}

// ---------------------------------------------------------------------------
// RAII over the SQLite C API

// A prepared statement, finalized on destruction. Bind errors are remembered
// and reported by the next Step, which keeps call sites to one check.
class Statement {
 public:
  static absl::StatusOr<Statement> Prepare(sqlite3* db, absl::string_view sql,
                                           absl::string_view op) {
    sqlite3_stmt* stmt = nullptr;
    const int rc = sqlite3_prepare_v2(
        db, sql.data(), static_cast<int>(sql.size()), &stmt, nullptr);
    if (rc != SQLITE_OK) {
      sqlite3_finalize(stmt);
      return SqliteError(db, rc, op);
    }
    return Statement(db, stmt, op);
  }

  Statement(Statement&& other) noexcept
      : db_(other.db_),
        stmt_(std::exchange(other.stmt_, nullptr)),
        op_(other.op_),
        bind_rc_(other.bind_rc_) {}
  Statement& operator=(Statement&&) = delete;
  ~Statement() { sqlite3_finalize(stmt_); }

  // Parameters are 1-based, as in SQL.
  void BindInt64(int index, int64_t value) {
    Check(sqlite3_bind_int64(stmt_, index, value));
  }
  void BindDouble(int index, double value) {
    Check(sqlite3_bind_double(stmt_, index, value));
  }
  void BindText(int index, absl::string_view value) {
    Check(sqlite3_bind_text64(stmt_, index, value.data(), value.size(),
                              SQLITE_TRANSIENT, SQLITE_UTF8));
  }
  void BindBlob(int index, absl::string_view value) {
    // A non-null pointer even for an empty value: a zero-length blob, not
    // NULL.
    Check(sqlite3_bind_blob64(stmt_, index, value.empty() ? "" : value.data(),
                              value.size(), SQLITE_TRANSIENT));
  }

  // true: a row is ready; false: done.
  absl::StatusOr<bool> Step() {
    if (bind_rc_ != SQLITE_OK) return SqliteError(db_, bind_rc_, op_);
    const int rc = sqlite3_step(stmt_);
    if (rc == SQLITE_ROW) return true;
    if (rc == SQLITE_DONE) return false;
    return SqliteError(db_, rc, op_);
  }

  // Steps to completion; for statements whose rows (if any) are not needed,
  // or after the one row that was.
  absl::Status Run() {
    while (true) {
      ASSIGN_OR_RETURN(const bool row, Step());
      if (!row) return absl::OkStatus();
    }
  }

  // Columns are 0-based, as in the SQLite API.
  bool IsNull(int col) {
    return sqlite3_column_type(stmt_, col) == SQLITE_NULL;
  }
  int64_t Int64(int col) { return sqlite3_column_int64(stmt_, col); }
  double Double(int col) { return sqlite3_column_double(stmt_, col); }
  std::string Text(int col) {
    const auto* data =
        reinterpret_cast<const char*>(sqlite3_column_text(stmt_, col));
    const int size = sqlite3_column_bytes(stmt_, col);
    return data == nullptr ? std::string() : std::string(data, size);
  }
  absl::string_view Blob(int col) {
    const auto* data =
        static_cast<const char*>(sqlite3_column_blob(stmt_, col));
    const int size = sqlite3_column_bytes(stmt_, col);
    return data == nullptr ? absl::string_view()
                           : absl::string_view(data, size);
  }

 private:
  Statement(sqlite3* db, sqlite3_stmt* stmt, absl::string_view op)
      : db_(db), stmt_(stmt), op_(op) {}

  void Check(int rc) {
    if (rc != SQLITE_OK && bind_rc_ == SQLITE_OK) bind_rc_ = rc;
  }

  sqlite3* db_;
  sqlite3_stmt* stmt_;
  absl::string_view op_;  // a literal at every call site
  int bind_rc_ = SQLITE_OK;
};

// Runs SQL without parameters (constants only, never user data).
absl::Status Exec(sqlite3* db, const char* sql, absl::string_view op) {
  const int rc = sqlite3_exec(db, sql, nullptr, nullptr, nullptr);
  if (rc != SQLITE_OK) return SqliteError(db, rc, op);
  return absl::OkStatus();
}

// A transaction that rolls back unless committed, so every early return of a
// failed operation leaves the database as it was.
class Transaction {
 public:
  // Immediate transactions take the write lock up front; a deferred one that
  // later writes could fail to upgrade its lock halfway through.
  enum class Kind { kRead, kWrite };

  static absl::StatusOr<Transaction> Begin(sqlite3* db, Kind kind,
                                           absl::string_view op) {
    RETURN_IF_ERROR(Exec(
        db, kind == Kind::kWrite ? "BEGIN IMMEDIATE" : "BEGIN DEFERRED", op));
    return Transaction(db, op);
  }

  Transaction(Transaction&& other) noexcept
      : db_(std::exchange(other.db_, nullptr)), op_(other.op_) {}
  Transaction& operator=(Transaction&&) = delete;

  ~Transaction() {
    // SQLite rolls back by itself after some errors (e.g. SQLITE_FULL);
    // autocommit mode tells whether anything is left to undo.
    if (db_ != nullptr && sqlite3_get_autocommit(db_) == 0) {
      sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr);
    }
  }

  absl::Status Commit() {
    // On failure (e.g. SQLITE_BUSY) the transaction stays open and the
    // destructor rolls it back.
    RETURN_IF_ERROR(Exec(db_, "COMMIT", op_));
    db_ = nullptr;
    return absl::OkStatus();
  }

 private:
  Transaction(sqlite3* db, absl::string_view op) : db_(db), op_(op) {}

  sqlite3* db_;
  absl::string_view op_;
};

// ---------------------------------------------------------------------------
// Rows

absl::StatusOr<int> ToInt(int64_t value, absl::string_view what) {
  if (value < std::numeric_limits<int>::min() ||
      value > std::numeric_limits<int>::max()) {
    return absl::DataLossError(
        absl::StrCat(what, ": stored value ", value, " is out of range"));
  }
  return static_cast<int>(value);
}

// Reads a row selected with kUserColumns.
absl::StatusOr<UserRecord> ReadUser(Statement& st) {
  UserRecord user;
  user.user_id = st.Text(0);
  const std::string what = absl::StrCat("user \"", user.user_id, "\"");
  BanditConfig& config = user.config;
  const int64_t learner = st.Int64(1);
  const int64_t strategy = st.Int64(2);
  if (learner != static_cast<int>(Learner::kPostHoc) &&
      learner != static_cast<int>(Learner::kContextOnly)) {
    return absl::DataLossError(
        absl::StrCat(what, ": unknown learner ", learner));
  }
  if (strategy < static_cast<int>(Strategy::kLinUcb) ||
      strategy > static_cast<int>(Strategy::kUniform)) {
    return absl::DataLossError(
        absl::StrCat(what, ": unknown strategy ", strategy));
  }
  config.learner = static_cast<Learner>(learner);
  config.strategy = static_cast<Strategy>(strategy);
  config.alpha = st.Double(3);
  config.lambda_c = st.Double(4);
  config.lambda_p = st.Double(5);
  config.epsilon = st.Double(6);
  config.importance_weighting = st.Int64(7) != 0;
  ASSIGN_OR_RETURN(config.context_dim,
                   ToInt(st.Int64(8), absl::StrCat(what, " context_dim")));
  ASSIGN_OR_RETURN(config.posthoc_dim,
                   ToInt(st.Int64(9), absl::StrCat(what, " posthoc_dim")));
  ASSIGN_OR_RETURN(config.action_names, DecodeNames(st.Text(10)));
  config.seed = static_cast<uint64_t>(st.Int64(11));
  user.created_at = FromMicros(st.Int64(12));
  user.model_version = st.Int64(13);
  user.pending_events = st.Int64(14);
  if (!st.IsNull(15)) {
    ASSIGN_OR_RETURN(config.prior,
                     DecodePrior(st.Blob(15), absl::StrCat(what, " prior")));
    RETURN_IF_ERROR(ValidateConfig(config));
  }
  return user;
}

// Reads a row selected with kEventColumns.
absl::StatusOr<EventRecord> ReadEvent(Statement& st) {
  EventRecord event;
  event.event_id = st.Int64(0);
  const std::string what = absl::StrCat("event ", event.event_id);
  event.user_id = st.Text(1);
  event.meal_id = st.Text(2);
  event.item_label = st.Text(3);
  ASSIGN_OR_RETURN(event.context,
                   DecodeDoubles(st.Blob(4), absl::StrCat(what, " context")));
  ASSIGN_OR_RETURN(event.action,
                   ToInt(st.Int64(5), absl::StrCat(what, " action")));
  event.propensity = st.Double(6);
  event.selected_at = FromMicros(st.Int64(7));
  event.completed = st.Int64(8) != 0;
  if (event.completed) {
    event.loss = st.Double(9);
    if (!st.IsNull(10)) {
      ASSIGN_OR_RETURN(
          event.posthoc,
          DecodeDoubles(st.Blob(10), absl::StrCat(what, " posthoc")));
    }
    event.weight = st.Double(11);
    event.model_version = st.Int64(12);
    event.updated_at = FromMicros(st.Int64(13));
  }
  return event;
}

absl::Status UserNotFound(const std::string& user_id) {
  return absl::NotFoundError(absl::StrCat("user \"", user_id, "\" not found"));
}

absl::Status EventNotFound(int64_t event_id) {
  return absl::NotFoundError(absl::StrCat("event ", event_id, " not found"));
}

// ---------------------------------------------------------------------------
// Opening

struct SqliteCloser {
  void operator()(sqlite3* db) const { sqlite3_close_v2(db); }
};

absl::StatusOr<int64_t> ReadInt(sqlite3* db, const char* sql,
                                absl::string_view op) {
  ASSIGN_OR_RETURN(Statement st, Statement::Prepare(db, sql, op));
  ASSIGN_OR_RETURN(const bool row, st.Step());
  if (!row) return absl::InternalError(absl::StrCat(op, ": no result"));
  return st.Int64(0);
}

// Returns the file's schema version after checking that this build may use
// the file: 0 for a brand-new (empty) database, kSchemaVersion for a store.
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
  if (version != kSchemaVersion && version != 1) {
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

absl::Status InitializeDatabase(sqlite3* db,
                                const SqliteStoreOptions& options) {
  const std::string& path = options.path;
  const std::string op = absl::StrCat("opening ", path);
  // Check before changing anything: a foreign file must stay untouched, and
  // switching to WAL rewrites the header.
  RETURN_IF_ERROR(CheckExistingFile(db, path).status());

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
    RETURN_IF_ERROR(Exec(db, kPoolsSql, op));
    RETURN_IF_ERROR(Exec(
        db, absl::StrCat("PRAGMA application_id = ", kApplicationId).c_str(),
        op));
    RETURN_IF_ERROR(
        Exec(db, absl::StrCat("PRAGMA user_version = ", kSchemaVersion).c_str(),
             op));
  } else if (version == 1) {
    RETURN_IF_ERROR(Exec(db, kMigrateTo2Sql, op));
    RETURN_IF_ERROR(Exec(db, kPoolsSql, op));
    RETURN_IF_ERROR(Exec(db, "PRAGMA user_version = 2", op));
  }
  return txn.Commit();
}

// Takes an exclusive advisory lock on "<path>.lock" (released by the
// kernel when the process ends, however it ends) and writes our pid into
// it. ":memory:" needs none (-1). FAILED_PRECONDITION naming the holder when
// another process has the store open; UNAVAILABLE if the lock file cannot
// be made.
absl::StatusOr<int> LockStoreFile(const std::string& path) {
  if (path == ":memory:") return -1;
  const std::string lock_path = path + ".lock";
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
absl::Status CheckIntegrity(sqlite3* db, const std::string& path) {
  const std::string op = absl::StrCat("checking ", path);
  ASSIGN_OR_RETURN(Statement st,
                   Statement::Prepare(db, "PRAGMA integrity_check(5)", op));
  std::vector<std::string> findings;
  while (true) {
    ASSIGN_OR_RETURN(const bool row, st.Step());
    if (!row) break;
    findings.push_back(st.Text(0));
  }
  if (findings.size() == 1 && findings[0] == "ok") return absl::OkStatus();
  return absl::DataLossError(absl::StrCat(
      path, " failed SQLite's integrity check: ", absl::StrJoin(findings, "; "),
      ". Restore the last backup (docs/operations.md)"));
}

}  // namespace

absl::StatusOr<std::unique_ptr<SqliteEventStore>> SqliteEventStore::Open(
    const SqliteStoreOptions& options) {
  if (options.path.empty()) {
    return absl::InvalidArgumentError("SqliteStoreOptions.path is empty");
  }
  // A missing or empty file is a new store only when asked for: a mistyped
  // --db must not silently start everyone from scratch.
  bool creating = false;
  if (options.path != ":memory:") {
    struct stat existing {};
    const bool exists = stat(options.path.c_str(), &existing) == 0;
    creating = !exists || existing.st_size == 0;
    if (creating && !options.create_if_missing) {
      return absl::FailedPreconditionError(absl::StrCat(
          "database \"", options.path, "\" ",
          exists ? "is an empty file" : "does not exist",
          "; pass --create to make a new store there (or correct --db)"));
    }
  }
  sqlite3* raw = nullptr;
  // NOMUTEX: the store's own mutex already serialises use of the connection.
  // A new file gets owner-only permissions: it holds health data.
  const mode_t previous_umask = creating ? umask(0077) : 0;
  const int rc = sqlite3_open_v2(
      options.path.c_str(), &raw,
      SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_NOMUTEX,
      nullptr);
  if (creating) umask(previous_umask);
  // SQLite allocates a handle even when opening fails; it must be closed.
  std::unique_ptr<sqlite3, SqliteCloser> db(raw);
  if (rc != SQLITE_OK) {
    return SqliteError(db.get(), rc, absl::StrCat("opening ", options.path));
  }
  sqlite3_extended_result_codes(db.get(), 1);
  const int64_t timeout_ms =
      std::clamp<int64_t>(absl::ToInt64Milliseconds(options.busy_timeout), 0,
                          std::numeric_limits<int>::max());
  sqlite3_busy_timeout(db.get(), static_cast<int>(timeout_ms));
  // One process per file: a second one would serve models that miss the
  // first one's updates.
  ASSIGN_OR_RETURN(const int lock_fd, LockStoreFile(options.path));
  absl::Status ready = InitializeDatabase(db.get(), options);
  if (ready.ok()) ready = CheckIntegrity(db.get(), options.path);
  if (!ready.ok()) {
    if (lock_fd >= 0) close(lock_fd);
    return ready;
  }
  struct stat file {};
  if (options.path != ":memory:" && stat(options.path.c_str(), &file) != 0) {
    if (lock_fd >= 0) close(lock_fd);
    return absl::UnavailableError(
        absl::StrCat("cannot stat ", options.path, ": ", std::strerror(errno)));
  }
  return std::unique_ptr<SqliteEventStore>(new SqliteEventStore(
      db.release(), lock_fd, options.path, static_cast<uint64_t>(file.st_dev),
      static_cast<uint64_t>(file.st_ino)));
}

SqliteEventStore::SqliteEventStore(sqlite3* db, int lock_fd, std::string path,
                                   uint64_t device, uint64_t inode)
    : db_(db),
      lock_fd_(lock_fd),
      path_(std::move(path)),
      device_(device),
      inode_(inode) {}

absl::Status SqliteEventStore::CheckHealth() {
  if (path_ == ":memory:") return absl::OkStatus();
  struct stat file {};
  if (stat(path_.c_str(), &file) != 0 ||
      static_cast<uint64_t>(file.st_dev) != device_ ||
      static_cast<uint64_t>(file.st_ino) != inode_) {
    return absl::FailedPreconditionError(absl::StrCat(
        "the database file ", path_,
        " was removed or replaced while the service had it open; writes "
        "would be lost at the next start. Restore it and restart the "
        "service"));
  }
  return absl::OkStatus();
}

SqliteEventStore::~SqliteEventStore() {
  sqlite3_close_v2(db_);
  if (lock_fd_ >= 0) close(lock_fd_);  // releases the lock
}

absl::Status SqliteEventStore::CreateUser(const UserRecord& user) {
  RETURN_IF_ERROR(CheckHealth());
  if (user.user_id.empty()) {
    return absl::InvalidArgumentError("user_id must not be empty");
  }
  RETURN_IF_ERROR(ValidateConfig(user.config));
  const BanditConfig& c = user.config;
  absl::MutexLock lock(&mu_);
  // model_version and pending_events describe stored events, of which a new
  // user has none; the caller's values are ignored.
  ASSIGN_OR_RETURN(
      Statement st,
      Statement::Prepare(
          db_,
          "INSERT INTO users (user_id, learner, strategy, alpha, lambda_c, "
          "lambda_p, epsilon, importance_weighting, context_dim, posthoc_dim, "
          "action_names, seed, created_at_us, model_version, prior) "
          "VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, 0, "
          "?14) ON CONFLICT (user_id) DO NOTHING RETURNING user_id",
          "CreateUser"));
  st.BindText(1, user.user_id);
  st.BindInt64(2, static_cast<int64_t>(c.learner));
  st.BindInt64(3, static_cast<int64_t>(c.strategy));
  st.BindDouble(4, c.alpha);
  st.BindDouble(5, c.lambda_c);
  st.BindDouble(6, c.lambda_p);
  st.BindDouble(7, c.epsilon);
  st.BindInt64(8, c.importance_weighting ? 1 : 0);
  st.BindInt64(9, c.context_dim);
  st.BindInt64(10, c.posthoc_dim);
  st.BindText(11, EncodeNames(c.action_names));
  st.BindInt64(12, static_cast<int64_t>(c.seed));
  st.BindInt64(13, ToMicros(user.created_at));
  const std::string prior =
      c.prior.enabled() ? EncodePrior(c.prior) : std::string();
  if (c.prior.enabled()) st.BindBlob(14, prior);  // else NULL
  ASSIGN_OR_RETURN(const bool inserted, st.Step());
  RETURN_IF_ERROR(st.Run());
  if (!inserted) {
    return absl::AlreadyExistsError(
        absl::StrCat("user \"", user.user_id, "\" already exists"));
  }
  return absl::OkStatus();
}

absl::StatusOr<UserRecord> SqliteEventStore::GetUserLocked(
    const std::string& user_id) {
  ASSIGN_OR_RETURN(
      Statement st,
      Statement::Prepare(
          db_, absl::StrCat(kUserColumns, "WHERE u.user_id = ?1"), "GetUser"));
  st.BindText(1, user_id);
  ASSIGN_OR_RETURN(const bool row, st.Step());
  if (!row) return UserNotFound(user_id);
  return ReadUser(st);
}

absl::StatusOr<UserRecord> SqliteEventStore::GetUser(
    const std::string& user_id) {
  absl::MutexLock lock(&mu_);
  return GetUserLocked(user_id);
}

absl::StatusOr<PageResult<UserRecord>> SqliteEventStore::ListUsers(
    const Page& page) {
  const int page_size = ClampPageSize(page.page_size);
  std::string after;
  if (!page.page_token.empty()) {
    ASSIGN_OR_RETURN(after, ParsePageToken(page.page_token, 'u'));
  }
  absl::MutexLock lock(&mu_);
  ASSIGN_OR_RETURN(
      Statement st,
      Statement::Prepare(
          db_,
          absl::StrCat(kUserColumns,
                       page.page_token.empty() ? "" : "WHERE u.user_id > ?2 ",
                       "ORDER BY u.user_id LIMIT ?1"),
          "ListUsers"));
  // One extra row says whether another page exists.
  st.BindInt64(1, page_size + 1);
  if (!page.page_token.empty()) st.BindText(2, after);
  PageResult<UserRecord> result;
  while (true) {
    ASSIGN_OR_RETURN(const bool row, st.Step());
    if (!row) break;
    if (static_cast<int>(result.items.size()) == page_size) {
      result.next_page_token = MakePageToken('u', result.items.back().user_id);
      break;
    }
    ASSIGN_OR_RETURN(UserRecord user, ReadUser(st));
    result.items.push_back(std::move(user));
  }
  return result;
}

absl::Status SqliteEventStore::DeleteUser(const std::string& user_id) {
  RETURN_IF_ERROR(CheckHealth());
  absl::MutexLock lock(&mu_);
  ASSIGN_OR_RETURN(
      Transaction txn,
      Transaction::Begin(db_, Transaction::Kind::kWrite, "DeleteUser"));
  {
    // The user's events go with it through ON DELETE CASCADE.
    ASSIGN_OR_RETURN(Statement st,
                     Statement::Prepare(db_,
                                        "DELETE FROM users WHERE user_id = ?1 "
                                        "RETURNING user_id",
                                        "DeleteUser"));
    st.BindText(1, user_id);
    ASSIGN_OR_RETURN(const bool deleted, st.Step());
    RETURN_IF_ERROR(st.Run());
    if (!deleted) return UserNotFound(user_id);
  }
  return txn.Commit();
}

absl::Status SqliteEventStore::ResetUser(const std::string& user_id) {
  RETURN_IF_ERROR(CheckHealth());
  absl::MutexLock lock(&mu_);
  ASSIGN_OR_RETURN(
      Transaction txn,
      Transaction::Begin(db_, Transaction::Kind::kWrite, "ResetUser"));
  {
    ASSIGN_OR_RETURN(Statement st,
                     Statement::Prepare(db_,
                                        "UPDATE users SET model_version = 0 "
                                        "WHERE user_id = ?1 RETURNING user_id",
                                        "ResetUser"));
    st.BindText(1, user_id);
    ASSIGN_OR_RETURN(const bool found, st.Step());
    RETURN_IF_ERROR(st.Run());
    if (!found) return UserNotFound(user_id);
  }
  {
    ASSIGN_OR_RETURN(
        Statement st,
        Statement::Prepare(db_, "DELETE FROM events WHERE user_id = ?1",
                           "ResetUser"));
    st.BindText(1, user_id);
    RETURN_IF_ERROR(st.Run());
  }
  return txn.Commit();
}

absl::StatusOr<int64_t> SqliteEventStore::AppendPending(
    const EventRecord& event) {
  RETURN_IF_ERROR(CheckHealth());
  if (std::isnan(event.propensity)) {
    return absl::InvalidArgumentError("propensity must not be NaN");
  }
  const std::string context = EncodeDoubles(event.context);
  absl::MutexLock lock(&mu_);
  // One statement, hence atomic on its own: the row is inserted only if the
  // user exists, and no row back means it does not.
  ASSIGN_OR_RETURN(
      Statement st,
      Statement::Prepare(
          db_,
          "INSERT INTO events (user_id, meal_id, item_label, context, action, "
          "propensity, selected_at_us, completed) "
          "SELECT ?1, ?2, ?3, ?4, ?5, ?6, ?7, 0 "
          "WHERE EXISTS (SELECT 1 FROM users WHERE user_id = ?1) "
          "RETURNING event_id",
          "AppendPending"));
  st.BindText(1, event.user_id);
  st.BindText(2, event.meal_id);
  st.BindText(3, event.item_label);
  st.BindBlob(4, context);
  st.BindInt64(5, event.action);
  st.BindDouble(6, event.propensity);
  st.BindInt64(7, ToMicros(event.selected_at));
  ASSIGN_OR_RETURN(const bool inserted, st.Step());
  const int64_t event_id = inserted ? st.Int64(0) : 0;
  RETURN_IF_ERROR(st.Run());
  if (!inserted) return UserNotFound(event.user_id);
  return event_id;
}

absl::StatusOr<EventRecord> SqliteEventStore::CompleteEvent(
    int64_t event_id, double loss, const std::vector<double>& posthoc,
    double weight, absl::Time updated_at) {
  RETURN_IF_ERROR(CheckHealth());
  if (std::isnan(loss)) {
    return absl::InvalidArgumentError("loss must not be NaN");
  }
  if (std::isnan(weight)) {
    return absl::InvalidArgumentError("weight must not be NaN");
  }
  const std::string posthoc_bytes = EncodeDoubles(posthoc);
  absl::MutexLock lock(&mu_);
  ASSIGN_OR_RETURN(
      Transaction txn,
      Transaction::Begin(db_, Transaction::Kind::kWrite, "CompleteEvent"));
  EventRecord event;
  {
    ASSIGN_OR_RETURN(
        Statement st,
        Statement::Prepare(db_,
                           absl::StrCat(kEventColumns, "WHERE event_id = ?1"),
                           "CompleteEvent"));
    st.BindInt64(1, event_id);
    ASSIGN_OR_RETURN(const bool found, st.Step());
    if (!found) return EventNotFound(event_id);
    ASSIGN_OR_RETURN(event, ReadEvent(st));
  }
  if (event.completed) {
    return absl::FailedPreconditionError(
        absl::StrCat("event ", event_id, " is already completed"));
  }
  {
    ASSIGN_OR_RETURN(
        Statement st,
        Statement::Prepare(db_,
                           "UPDATE users SET model_version = model_version + 1 "
                           "WHERE user_id = ?1 RETURNING model_version",
                           "CompleteEvent"));
    st.BindText(1, event.user_id);
    ASSIGN_OR_RETURN(const bool found, st.Step());
    // The foreign key makes this unreachable short of a damaged file.
    if (!found) {
      return absl::DataLossError(absl::StrCat("event ", event_id,
                                              " belongs to missing user \"",
                                              event.user_id, "\""));
    }
    event.model_version = st.Int64(0);
    RETURN_IF_ERROR(st.Run());
  }
  {
    ASSIGN_OR_RETURN(
        Statement st,
        Statement::Prepare(
            db_,
            "UPDATE events SET completed = 1, loss = ?2, posthoc = ?3, "
            "weight = ?4, model_version = ?5, updated_at_us = ?6 "
            "WHERE event_id = ?1",
            "CompleteEvent"));
    st.BindInt64(1, event_id);
    st.BindDouble(2, loss);
    st.BindBlob(3, posthoc_bytes);
    st.BindDouble(4, weight);
    st.BindInt64(5, event.model_version);
    st.BindInt64(6, ToMicros(updated_at));
    RETURN_IF_ERROR(st.Run());
  }
  RETURN_IF_ERROR(txn.Commit());
  event.completed = true;
  event.loss = loss;
  event.posthoc = posthoc;
  event.weight = weight;
  // Reported as stored, i.e. truncated to microseconds.
  event.updated_at = FromMicros(ToMicros(updated_at));
  return event;
}

absl::StatusOr<EventRecord> SqliteEventStore::GetEvent(int64_t event_id) {
  absl::MutexLock lock(&mu_);
  ASSIGN_OR_RETURN(
      Statement st,
      Statement::Prepare(
          db_, absl::StrCat(kEventColumns, "WHERE event_id = ?1"), "GetEvent"));
  st.BindInt64(1, event_id);
  ASSIGN_OR_RETURN(const bool found, st.Step());
  if (!found) return EventNotFound(event_id);
  return ReadEvent(st);
}

absl::StatusOr<int64_t> SqliteEventStore::AddPool(const PoolRecord& pool) {
  RETURN_IF_ERROR(CheckHealth());
  absl::MutexLock lock(&mu_);
  ASSIGN_OR_RETURN(
      Statement st,
      Statement::Prepare(
          db_,
          "INSERT INTO population_pools (created_at_us, users, learner, "
          "context_dim, posthoc_dim, action_names, prior) "
          "VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7) RETURNING pool_version",
          "AddPool"));
  PopulationPrior stored = pool.prior;
  stored.pool_version = 0;
  stored.rounds = 0.0;
  const std::string prior = EncodePrior(stored);
  st.BindInt64(1, ToMicros(pool.created_at));
  st.BindInt64(2, pool.users);
  st.BindInt64(3, static_cast<int64_t>(pool.learner));
  st.BindInt64(4, pool.context_dim);
  st.BindInt64(5, pool.posthoc_dim);
  st.BindText(6, EncodeNames(pool.action_names));
  st.BindBlob(7, prior);
  ASSIGN_OR_RETURN(const bool row, st.Step());
  if (!row) return absl::InternalError("AddPool: no pool_version returned");
  const int64_t version = st.Int64(0);
  RETURN_IF_ERROR(st.Run());
  return version;
}

absl::StatusOr<PoolRecord> SqliteEventStore::LatestPool(
    const BanditConfig& config) {
  absl::MutexLock lock(&mu_);
  ASSIGN_OR_RETURN(
      Statement st,
      Statement::Prepare(
          db_,
          "SELECT pool_version, created_at_us, users, prior "
          "FROM population_pools WHERE learner = ?1 AND context_dim = ?2 AND "
          "posthoc_dim = ?3 AND action_names = ?4 "
          "ORDER BY pool_version DESC LIMIT 1",
          "LatestPool"));
  const int posthoc_dim =
      config.learner == Learner::kPostHoc ? config.posthoc_dim : 0;
  st.BindInt64(1, static_cast<int64_t>(config.learner));
  st.BindInt64(2, config.context_dim);
  st.BindInt64(3, posthoc_dim);
  st.BindText(4, EncodeNames(config.action_names));
  ASSIGN_OR_RETURN(const bool row, st.Step());
  if (!row) {
    return absl::NotFoundError(absl::StrCat(
        "no population pool for ", LearnerName(config.learner),
        " users with context_dim ", config.context_dim, ", posthoc_dim ",
        posthoc_dim, " and these ", config.num_actions(),
        " actions; build one with BuildPopulationPrior"));
  }
  PoolRecord pool;
  pool.pool_version = st.Int64(0);
  pool.created_at = FromMicros(st.Int64(1));
  pool.users = st.Int64(2);
  pool.learner = config.learner;
  pool.context_dim = config.context_dim;
  pool.posthoc_dim = posthoc_dim;
  pool.action_names = config.action_names;
  ASSIGN_OR_RETURN(
      pool.prior,
      DecodePrior(st.Blob(3), absl::StrCat("pool ", pool.pool_version)));
  pool.prior.pool_version = pool.pool_version;
  RETURN_IF_ERROR(st.Run());
  return pool;
}

absl::Status SqliteEventStore::CheckUserExistsLocked(
    const std::string& user_id) {
  ASSIGN_OR_RETURN(
      Statement st,
      Statement::Prepare(db_, "SELECT 1 FROM users WHERE user_id = ?1",
                         "CheckUserExists"));
  st.BindText(1, user_id);
  ASSIGN_OR_RETURN(const bool found, st.Step());
  if (!found) return UserNotFound(user_id);
  return absl::OkStatus();
}

absl::StatusOr<PageResult<EventRecord>> SqliteEventStore::ListEvents(
    const std::string& user_id, const std::string& meal_id, const Page& page) {
  const int page_size = ClampPageSize(page.page_size);
  int64_t after = 0;  // event ids start at 1
  if (!page.page_token.empty()) {
    ASSIGN_OR_RETURN(after, ParseEventPageToken(page.page_token));
  }
  absl::MutexLock lock(&mu_);
  // A read transaction: the existence check and the rows come from one
  // snapshot even if another process writes in between.
  ASSIGN_OR_RETURN(
      Transaction txn,
      Transaction::Begin(db_, Transaction::Kind::kRead, "ListEvents"));
  RETURN_IF_ERROR(CheckUserExistsLocked(user_id));
  PageResult<EventRecord> result;
  {
    // Separate statements so each filter gets its index.
    ASSIGN_OR_RETURN(
        Statement st,
        Statement::Prepare(
            db_,
            absl::StrCat(kEventColumns, "WHERE user_id = ?1 ",
                         meal_id.empty() ? "" : "AND meal_id = ?4 ",
                         "AND event_id > ?2 ORDER BY event_id LIMIT ?3"),
            "ListEvents"));
    st.BindText(1, user_id);
    st.BindInt64(2, after);
    st.BindInt64(3, page_size + 1);
    if (!meal_id.empty()) st.BindText(4, meal_id);
    while (true) {
      ASSIGN_OR_RETURN(const bool row, st.Step());
      if (!row) break;
      if (static_cast<int>(result.items.size()) == page_size) {
        result.next_page_token =
            MakePageToken('e', absl::StrCat(result.items.back().event_id));
        break;
      }
      ASSIGN_OR_RETURN(EventRecord event, ReadEvent(st));
      result.items.push_back(std::move(event));
    }
  }
  RETURN_IF_ERROR(txn.Commit());
  return result;
}

absl::StatusOr<std::vector<EventRecord>> SqliteEventStore::CompletedEvents(
    const std::string& user_id) {
  absl::MutexLock lock(&mu_);
  ASSIGN_OR_RETURN(
      Transaction txn,
      Transaction::Begin(db_, Transaction::Kind::kRead, "CompletedEvents"));
  RETURN_IF_ERROR(CheckUserExistsLocked(user_id));
  std::vector<EventRecord> events;
  {
    ASSIGN_OR_RETURN(
        Statement st,
        Statement::Prepare(db_,
                           absl::StrCat(kEventColumns,
                                        "WHERE user_id = ?1 AND completed = 1 "
                                        "ORDER BY model_version"),
                           "CompletedEvents"));
    st.BindText(1, user_id);
    while (true) {
      ASSIGN_OR_RETURN(const bool row, st.Step());
      if (!row) break;
      ASSIGN_OR_RETURN(EventRecord event, ReadEvent(st));
      events.push_back(std::move(event));
    }
  }
  RETURN_IF_ERROR(txn.Commit());
  return events;
}

}  // namespace bitewise::bandit
