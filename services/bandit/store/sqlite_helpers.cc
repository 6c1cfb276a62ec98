#include "services/bandit/store/sqlite_helpers.h"

#include "absl/strings/str_cat.h"

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
