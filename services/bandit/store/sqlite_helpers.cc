#include "services/bandit/store/sqlite_helpers.h"

#include <cerrno>
#include <cstring>

#include "absl/strings/str_cat.h"
#include "services/bandit/store/write_faults.h"

namespace bitewise::bandit::sqlite {

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

namespace {

// The errno of the last failed system call on the write-ahead log, else on
// the database file (sqlite3_system_errno reads errno later, after other
// calls may have changed it; each file keeps its own).
int LastWriteErrno(sqlite3* db) {
  int error = 0;
  sqlite3_file* log = nullptr;
  if (sqlite3_file_control(db, "main", SQLITE_FCNTL_JOURNAL_POINTER, &log) ==
          SQLITE_OK &&
      log != nullptr && log->pMethods != nullptr) {
    log->pMethods->xFileControl(log, SQLITE_FCNTL_LAST_ERRNO, &error);
  }
  if (error == 0) {
    sqlite3_file_control(db, "main", SQLITE_FCNTL_LAST_ERRNO, &error);
  }
  return error;
}

}  // namespace

absl::Status SqliteError(sqlite3* db, int rc, absl::string_view op) {
  // The connection's message is more specific than the code's, but only if it
  // belongs to this failure; sqlite3_errcode tells.
  const bool own = db != nullptr && sqlite3_extended_errcode(db) == rc;
  const char* message = own ? sqlite3_errmsg(db) : sqlite3_errstr(rc);
  const int primary = rc & 0xff;
  if (primary == SQLITE_IOERR || primary == SQLITE_FULL ||
      primary == SQLITE_READONLY) {
    // The storage refused a write: named by the errno beneath, with the
    // file (the database; its -wal log beside it takes the same writes).
    int error = own ? LastWriteErrno(db) : 0;
    if (error == 0 && primary == SQLITE_FULL) error = ENOSPC;
    if (error == 0 && primary == SQLITE_READONLY) error = EROFS;
    if (error == 0) error = EIO;
    const WriteErrno described = DescribeWriteErrno(error);
    const char* file = db != nullptr ? sqlite3_db_filename(db, "main") : "";
    return StorageFault(
        described.code,
        absl::StrCat(op, ": cannot write ",
                     file != nullptr && *file != '\0' ? file : "the database",
                     ": ", described.cause, " (",
                     error != 0 ? std::strerror(error) : message,
                     "; sqlite code ", rc, ")"));
  }
  if (primary == SQLITE_BUSY) {
    // The service alone writes its file (a lock of its own keeps other
    // services out); a lock held past the busy timeout is another program's
    // (a sqlite3 shell with a transaction open), and no write gets through
    // while it lasts: a storage fault, so health says so.
    const char* file = db != nullptr ? sqlite3_db_filename(db, "main") : "";
    return StorageFault(
        absl::StatusCode::kUnavailable,
        absl::StrCat(
            op, ": cannot write ",
            file != nullptr && *file != '\0' ? file : "the database",
            ": the database is locked by another connection past the "
            "busy timeout (a sqlite3 shell or another program with a "
            "transaction open? only bitewise-bandit should write it) (",
            message, "; sqlite code ", rc, ")"));
  }
  return absl::Status(
      CodeForSqlite(rc),
      absl::StrCat(op, ": ", message, " (sqlite code ", rc, ")"));
}

absl::Status Exec(sqlite3* db, const char* sql, absl::string_view op) {
  const int rc = sqlite3_exec(db, sql, nullptr, nullptr, nullptr);
  if (rc != SQLITE_OK) return SqliteError(db, rc, op);
  return absl::OkStatus();
}

absl::StatusOr<int64_t> ReadInt(sqlite3* db, const char* sql,
                                absl::string_view op) {
  ASSIGN_OR_RETURN(Statement st, Statement::Prepare(db, sql, op));
  ASSIGN_OR_RETURN(const bool row, st.Step());
  if (!row) return absl::InternalError(absl::StrCat(op, ": no result"));
  return st.Int64(0);
}

}  // namespace bitewise::bandit::sqlite
