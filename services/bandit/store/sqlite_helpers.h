// RAII over the SQLite C API for the bandit store (internal to
// services/bandit/store): prepared statements, transactions that roll back
// unless committed, and SQLite result codes as absl::Status.
#ifndef BITEWISE_SERVICES_BANDIT_STORE_SQLITE_HELPERS_H_
#define BITEWISE_SERVICES_BANDIT_STORE_SQLITE_HELPERS_H_

#include <sqlite3.h>

#include <cstdint>
#include <map>
#include <string>
#include <utility>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "services/common/status_macros.h"

namespace bitewise::bandit::sqlite {

// The absl code for a SQLite result code: BUSY/LOCKED UNAVAILABLE (retrying
// later can succeed), CORRUPT/NOTADB DATA_LOSS, FULL/NOMEM
// RESOURCE_EXHAUSTED, CONSTRAINT and permission problems
// FAILED_PRECONDITION, TOOBIG/RANGE/MISMATCH INVALID_ARGUMENT, else INTERNAL.
absl::StatusCode CodeForSqlite(int rc);

// `op`: SQLite's message for `rc` (the connection's when it is this
// failure's), with the code. The storage refusing a write (IOERR, FULL,
// READONLY) is a storage fault (write_faults.h) naming the file and the
// cause: RESOURCE_EXHAUSTED for a full disk or a file-size limit,
// UNAVAILABLE for a read-only file or an I/O error.
absl::Status SqliteError(sqlite3* db, int rc, absl::string_view op);

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
        bind_rc_(other.bind_rc_),
        in_use_(std::exchange(other.in_use_, nullptr)) {}
  Statement& operator=(Statement&&) = delete;
  ~Statement() {
    if (in_use_ == nullptr) {
      sqlite3_finalize(stmt_);
      return;
    }
    // A statement of a StatementCache: ready for its next use.
    sqlite3_reset(stmt_);
    sqlite3_clear_bindings(stmt_);
    *in_use_ = false;
  }

  // Parameters are 1-based, as in SQL.
  void BindInt64(int index, int64_t value) {
    Check(sqlite3_bind_int64(stmt_, index, value));
  }
  void BindNull(int index) { Check(sqlite3_bind_null(stmt_, index)); }
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
  friend class StatementCache;
  Statement(sqlite3* db, sqlite3_stmt* stmt, absl::string_view op,
            bool* in_use = nullptr)
      : db_(db), stmt_(stmt), op_(op), in_use_(in_use) {}

  void Check(int rc) {
    if (rc != SQLITE_OK && bind_rc_ == SQLITE_OK) bind_rc_ = rc;
  }

  sqlite3* db_;
  sqlite3_stmt* stmt_;
  absl::string_view op_;  // a literal at every call site
  int bind_rc_ = SQLITE_OK;
  bool* in_use_ = nullptr;  // set for a StatementCache's statement
};

// Statements of the hot path, prepared once per connection and reused
// (reset and unbound after each use). Used under the connection's lock; a
// statement still in use is not handed out twice (a fresh one is prepared).
class StatementCache {
 public:
  explicit StatementCache(sqlite3* db) : db_(db) {}
  StatementCache(const StatementCache&) = delete;
  StatementCache& operator=(const StatementCache&) = delete;
  ~StatementCache() {
    for (auto& entry : cache_) sqlite3_finalize(entry.second.stmt);
  }

  absl::StatusOr<Statement> Get(const std::string& sql, absl::string_view op) {
    auto it = cache_.find(sql);
    if (it == cache_.end()) {
      sqlite3_stmt* stmt = nullptr;
      const int rc =
          sqlite3_prepare_v3(db_, sql.data(), static_cast<int>(sql.size()),
                             SQLITE_PREPARE_PERSISTENT, &stmt, nullptr);
      if (rc != SQLITE_OK) {
        sqlite3_finalize(stmt);
        return SqliteError(db_, rc, op);
      }
      it = cache_.emplace(sql, Entry{stmt, false}).first;
    }
    if (it->second.in_use) return Statement::Prepare(db_, sql, op);
    it->second.in_use = true;
    return Statement(db_, it->second.stmt, op, &it->second.in_use);
  }

 private:
  struct Entry {
    sqlite3_stmt* stmt;
    bool in_use;
  };
  sqlite3* db_;
  // std::map: entries never move, so in_use pointers stay valid.
  std::map<std::string, Entry> cache_;
};

// Runs SQL without parameters (constants only, never user data).
absl::Status Exec(sqlite3* db, const char* sql, absl::string_view op);

// The single integer a query returns (a PRAGMA, a COUNT).
absl::StatusOr<int64_t> ReadInt(sqlite3* db, const char* sql,
                                absl::string_view op);

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

struct SqliteCloser {
  void operator()(sqlite3* db) const { sqlite3_close_v2(db); }
};

}  // namespace bitewise::bandit::sqlite

#endif  // BITEWISE_SERVICES_BANDIT_STORE_SQLITE_HELPERS_H_
