// PostgresEventStore, the event log: users and their events, and the
// conditioned writes of replicas.
#include <cmath>
#include <utility>

#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "services/bandit/store/event_checksum.h"
#include "services/bandit/store/pg_helpers.h"
#include "services/bandit/store/pg_rows.h"
#include "services/bandit/store/postgres_event_store.h"
#include "services/bandit/store/store_rows.h"
#include "services/common/status_macros.h"

namespace bitewise::bandit {
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
  params.Double(c.phi_radius);
  // model_version and pending_events describe stored events, of which a new
  // user has none; the caller's values are ignored.
  ASSIGN_OR_RETURN(
      Rows inserted,
      conn->Exec("INSERT INTO users (user_id, learner, strategy, alpha, "
                 "lambda_c, lambda_p, epsilon, importance_weighting, "
                 "context_dim, posthoc_dim, seed, created_at_us, "
                 "model_version, prior, phi_radius) VALUES ($1, $2, $3, $4, "
                 "$5, $6, $7, $8, $9, $10, $11, $12, 0, $13, $14) ON CONFLICT "
                 "(user_id) DO NOTHING RETURNING user_id",
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

absl::Status PostgresEventStore::SetLearner(const std::string& user_id,
                                            Learner learner,
                                            int64_t model_version) {
  constexpr char kOp[] = "SetLearner";
  ASSIGN_OR_RETURN(pg::Pool::Lease conn, pool_->Acquire(kOp));
  ASSIGN_OR_RETURN(Transaction txn, Transaction::Begin(*conn, kOp));
  RETURN_IF_ERROR(LockUser(*conn, user_id, kOp));
  {
    ASSIGN_OR_RETURN(
        Rows rows,
        conn->Exec("SELECT model_version FROM users WHERE user_id = $1",
                   Params().Text(user_id), kOp));
    rows.Next();
    RETURN_IF_ERROR(
        store_rows::LogMovedSince(user_id, model_version, rows.Int64(0), kOp));
  }
  RETURN_IF_ERROR(
      conn->Exec("UPDATE users SET learner = $2, incarnation = "
                 "nextval('user_incarnations') WHERE user_id = $1",
                 Params().Text(user_id).Int64(static_cast<int64_t>(learner)),
                 kOp)
          .status());
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
  RETURN_IF_ERROR(pg::OutcomeUnknownIfLost(
      *conn, rows.status(),
      "Retrying is safe: a Select that was applied stays a pending "
      "selection that no Update refers to"));
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
  absl::StatusOr<Rows> rows = conn->Exec(
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
      kOp);
  RETURN_IF_ERROR(pg::OutcomeUnknownIfLost(*conn, rows.status(),
                                           pg::kRetryAfterUnknownOutcome));
  if (!rows->Next()) return NotCompleted(*conn, event_id, LogMoved(user_id));
  ASSIGN_OR_RETURN(EventRecord event, store_rows::ReadEventRow(*rows));
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

}  // namespace bitewise::bandit
