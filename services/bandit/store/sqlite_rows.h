// The SQLite store's row helpers (internal to services/bandit/store): the
// user and event column lists its queries share, reading a user or an event
// from a row, the action-name tables, and a commit made durable with FULL
// whatever the connection's synchronous mode. Used by the store's role
// files (sqlite_event_store.cc, sqlite_event_log.cc, sqlite_checkpoints.cc,
// sqlite_pools_audit.cc).
#ifndef BITEWISE_SERVICES_BANDIT_STORE_SQLITE_ROWS_H_
#define BITEWISE_SERVICES_BANDIT_STORE_SQLITE_ROWS_H_

#include <sqlite3.h>

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"
#include "services/bandit/store/event_store.h"
#include "services/bandit/store/sqlite_helpers.h"
#include "services/bandit/store/store_rows.h"
#include "services/common/status_macros.h"

namespace bitewise::bandit::sqlite {

inline constexpr char kUserColumns[] = R"sql(
SELECT u.user_id, u.learner, u.strategy, u.alpha, u.lambda_c, u.lambda_p,
       u.epsilon, u.importance_weighting, u.context_dim, u.posthoc_dim,
       u.seed, u.created_at_us, u.model_version,
       (SELECT COUNT(*) FROM events e
        WHERE e.user_id = u.user_id AND e.completed = 0),
       u.prior, u.phi_radius
FROM users u
)sql";

// LEFT JOIN: an event whose context row is missing reads with none, and
// its selection checksum then fails (DATA_LOSS) rather than the event
// silently vanishing from the log.
// A context kept in the contexts file is read from there
// (bitewise_context, registered at Open).
inline constexpr char kEventColumns[] = R"sql(
SELECT event_id, user_id, meal_id, item_label,
       CASE WHEN context_offset IS NULL THEN context
            ELSE bitewise_context(context_offset, context_bytes) END,
       action, propensity, selected_at_us, completed, loss, posthoc, weight,
       model_version, updated_at_us, selection_checksum, outcome_checksum
FROM events LEFT JOIN event_contexts USING (event_id)
)sql";

// The action names of one user or pool, stored one row per action in
// `table` (user_actions, pool_actions) under `key_column`.
inline absl::Status WriteActionNames(sqlite3* db, const char* table,
                                     const char* key_column,
                                     absl::string_view key,
                                     const std::vector<std::string>& names,
                                     absl::string_view op) {
  for (size_t i = 0; i < names.size(); ++i) {
    ASSIGN_OR_RETURN(
        Statement row,
        Statement::Prepare(db,
                           absl::StrCat("INSERT INTO ", table, " (", key_column,
                                        ", action, name) VALUES (?1, ?2, ?3)"),
                           op));
    row.BindText(1, key);
    row.BindInt64(2, static_cast<int64_t>(i));
    row.BindText(3, names[i]);
    RETURN_IF_ERROR(row.Run());
  }
  return absl::OkStatus();
}

// Reads them back in action order; DATA_LOSS unless the actions are
// 0, 1, ... with at least one.
inline absl::StatusOr<std::vector<std::string>> ReadActionNames(
    sqlite3* db, const char* table, const char* key_column,
    absl::string_view key, absl::string_view what, absl::string_view op) {
  ASSIGN_OR_RETURN(Statement st,
                   Statement::Prepare(db,
                                      absl::StrCat("SELECT action, name FROM ",
                                                   table, " WHERE ", key_column,
                                                   " = ?1 ORDER BY action"),
                                      op));
  st.BindText(1, key);
  store_rows::ActionNamesReader names(what, table);
  while (true) {
    ASSIGN_OR_RETURN(const bool row, st.Step());
    if (!row) break;
    RETURN_IF_ERROR(names.Add(st.Int64(0), st.Text(1)));
  }
  return names.Take();
}

// Reads a row selected with kUserColumns (and its action names).
inline absl::StatusOr<UserRecord> ReadUser(sqlite3* db, Statement& st) {
  return store_rows::ReadUserRow(
      st, [db](const std::string& user_id, const std::string& what) {
        return ReadActionNames(db, "user_actions", "user_id", user_id, what,
                               "reading action names");
      });
}

// Reads a row selected with kEventColumns.
inline absl::StatusOr<EventRecord> ReadEvent(Statement& st) {
  return store_rows::ReadEventRow(st);
}

// Sets synchronous = FULL for its lifetime (from NORMAL), so the
// transaction it spans is fsynced at its commit. SQLite allows the change
// only outside a transaction: construct it before the transaction begins.
class DurableCommit {
 public:
  DurableCommit(sqlite3* db, bool needed) : db_(needed ? db : nullptr) {
    if (db_ != nullptr) {
      status_ = Exec(db_, "PRAGMA synchronous = FULL", "a durable commit");
    }
  }
  ~DurableCommit() {
    if (db_ != nullptr && status_.ok()) {
      const absl::Status restored =
          Exec(db_, "PRAGMA synchronous = NORMAL", "a durable commit");
      if (!restored.ok()) {
        std::fprintf(stderr, "bitewise-bandit: %s\n",
                     restored.ToString().c_str());
      }
    }
  }
  DurableCommit(const DurableCommit&) = delete;
  DurableCommit& operator=(const DurableCommit&) = delete;

  // Not OK if FULL could not be set: the caller must not go on.
  const absl::Status& status() const { return status_; }

 private:
  sqlite3* const db_;
  absl::Status status_;
};

}  // namespace bitewise::bandit::sqlite

namespace bitewise::bandit {

// The names the SQLite store's role files use unqualified.
using sqlite::DurableCommit;
using sqlite::Exec;
using sqlite::kEventColumns;
using sqlite::kUserColumns;
using sqlite::ReadActionNames;
using sqlite::ReadEvent;
using sqlite::ReadUser;
using sqlite::SqliteCloser;
using sqlite::SqliteError;
using sqlite::Statement;
using sqlite::Transaction;
using sqlite::WriteActionNames;

}  // namespace bitewise::bandit

#endif  // BITEWISE_SERVICES_BANDIT_STORE_SQLITE_ROWS_H_
