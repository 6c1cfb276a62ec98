// The PostgreSQL store's row helpers (internal to services/bandit/store):
// the user and event column lists its queries share, reading a user or a
// checkpoint, the action-name tables, the user-row lock and the errors its
// roles share. Used by the store's role files (postgres_event_store.cc,
// postgres_event_log.cc, postgres_checkpoints.cc, postgres_pools_audit.cc).
#ifndef BITEWISE_SERVICES_BANDIT_STORE_PG_ROWS_H_
#define BITEWISE_SERVICES_BANDIT_STORE_PG_ROWS_H_

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"
#include "services/bandit/store/event_checksum.h"
#include "services/bandit/store/event_store.h"
#include "services/bandit/store/pg_helpers.h"
#include "services/bandit/store/store_rows.h"
#include "services/common/status_macros.h"

namespace bitewise::bandit::pg {

inline constexpr char kApplication[] = "bitewise-bandit";

// Reads that must see one consistent state (a check and its rows).
inline constexpr char kSnapshot[] = "ISOLATION LEVEL REPEATABLE READ READ ONLY";

inline constexpr char kUserColumns[] = R"sql(
SELECT u.user_id, u.learner, u.strategy, u.alpha, u.lambda_c, u.lambda_p,
       u.epsilon, u.importance_weighting, u.context_dim, u.posthoc_dim,
       u.seed, u.created_at_us, u.model_version,
       (SELECT COUNT(*) FROM events e
        WHERE e.user_id = u.user_id AND NOT e.completed),
       u.prior, u.phi_radius, u.incarnation
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
inline constexpr char kEventColumns[] = BITEWISE_EVENT_SELECT
    "FROM events e LEFT JOIN event_contexts c ON c.event_id = e.event_id ";

// The event a completion's `e` (UPDATE ... RETURNING *) wrote, read the
// same way.
inline constexpr char kCompletedEvent[] = BITEWISE_EVENT_SELECT
    "FROM e LEFT JOIN event_contexts c ON c.event_id = e.event_id";
#undef BITEWISE_EVENT_SELECT

// $1..$7 of a completion: the event and its outcome, with the outcome's
// checksum.
inline Params OutcomeParams(int64_t event_id, double loss,
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
inline absl::Status NotCompleted(Connection& conn, int64_t event_id,
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
inline absl::Status LogMoved(const std::string& user_id) {
  return absl::AbortedError(
      absl::StrCat("user \"", user_id,
                   "\": another process wrote to the user's log since this "
                   "one read it (nothing written)"));
}

inline absl::Status WriteActionNames(Connection& conn, const char* table,
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
inline absl::StatusOr<std::vector<std::string>> ReadActionNames(
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

inline absl::StatusOr<UserRecord> ReadUser(Connection& conn, Rows& rows) {
  ASSIGN_OR_RETURN(
      UserRecord user,
      store_rows::ReadUserRow(
          rows, [&conn](const std::string& user_id, const std::string& what) {
            return ReadActionNames(conn, "user_actions", "user_id",
                                   Params().Text(user_id), what,
                                   "reading action names");
          }));
  user.incarnation = rows.Int64(16);
  return user;
}

// Locks the user's row for the rest of the transaction: every write of a
// user's log takes this lock first, in every process.
inline absl::Status LockUser(Connection& conn, const std::string& user_id,
                             absl::string_view op) {
  ASSIGN_OR_RETURN(
      Rows rows, conn.Exec("SELECT 1 FROM users WHERE user_id = $1 FOR UPDATE",
                           Params().Text(user_id), op));
  if (rows.size() == 0) return UserNotFound(user_id);
  return absl::OkStatus();
}

inline absl::Status CheckUserExists(Connection& conn,
                                    const std::string& user_id,
                                    absl::string_view op) {
  ASSIGN_OR_RETURN(Rows rows, conn.Exec("SELECT 1 FROM users WHERE "
                                        "user_id = $1",
                                        Params().Text(user_id), op));
  if (rows.size() == 0) return UserNotFound(user_id);
  return absl::OkStatus();
}

inline absl::Status DeleteCheckpointRows(Connection& conn,
                                         const std::string& user_id,
                                         absl::string_view op) {
  for (const char* sql :
       {"DELETE FROM model_checkpoints WHERE user_id = $1",
        "DELETE FROM model_checkpoint_chunks WHERE user_id = $1"}) {
    RETURN_IF_ERROR(conn.Exec(sql, Params().Text(user_id), op).status());
  }
  return absl::OkStatus();
}

// The user's checkpoint read on `conn`, inside the caller's transaction
// (checkpoint_protocol.h's ReadCheckpoint; postgres_checkpoints.cc).
absl::StatusOr<ModelCheckpoint> ReadCheckpointOn(Connection& conn,
                                                 const std::string& user_id);

}  // namespace bitewise::bandit::pg

namespace bitewise::bandit {

// The names the PostgreSQL store's role files use unqualified.
using pg::CheckUserExists;
using pg::Connection;
using pg::DeleteCheckpointRows;
using pg::kApplication;
using pg::kCompletedEvent;
using pg::kEventColumns;
using pg::kSnapshot;
using pg::kUserColumns;
using pg::LockUser;
using pg::LogMoved;
using pg::NotCompleted;
using pg::OutcomeParams;
using pg::Params;
using pg::ReadActionNames;
using pg::ReadUser;
using pg::Rows;
using pg::Transaction;
using pg::WriteActionNames;

}  // namespace bitewise::bandit

#endif  // BITEWISE_SERVICES_BANDIT_STORE_PG_ROWS_H_
