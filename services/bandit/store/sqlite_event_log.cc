// SqliteEventStore, the event log: users and their events.
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
#include "absl/time/clock.h"
#include "services/bandit/store/context_file.h"
#include "services/bandit/store/event_checksum.h"
#include "services/bandit/store/sqlite_event_store.h"
#include "services/bandit/store/sqlite_helpers.h"
#include "services/bandit/store/sqlite_rows.h"
#include "services/bandit/store/sqlite_schema.h"
#include "services/bandit/store/store_rows.h"
#include "services/common/status_macros.h"

namespace bitewise::bandit {
absl::Status SqliteEventStore::CreateUser(const UserRecord& user) {
  RETURN_IF_ERROR(CheckHealth());
  if (user.user_id.empty()) {
    return absl::InvalidArgumentError("user_id must not be empty");
  }
  RETURN_IF_ERROR(ValidateConfig(user.config));
  const BanditConfig& c = user.config;
  absl::MutexLock lock(&mu_);
  ASSIGN_OR_RETURN(
      Transaction txn,
      Transaction::Begin(db_, Transaction::Kind::kWrite, "CreateUser"));
  // model_version and pending_events describe stored events, of which a new
  // user has none; the caller's values are ignored.
  ASSIGN_OR_RETURN(
      Statement st,
      Statement::Prepare(
          db_,
          "INSERT INTO users (user_id, learner, strategy, alpha, lambda_c, "
          "lambda_p, epsilon, importance_weighting, context_dim, posthoc_dim, "
          "seed, created_at_us, model_version, prior, phi_radius) "
          "VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, 0, "
          "?13, ?14) ON CONFLICT (user_id) DO NOTHING RETURNING user_id",
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
  st.BindInt64(11, static_cast<int64_t>(c.seed));
  st.BindInt64(12, ToMicros(user.created_at));
  const std::string prior =
      c.prior.enabled() ? EncodePrior(c.prior) : std::string();
  if (c.prior.enabled()) st.BindBlob(13, prior);  // else NULL
  st.BindDouble(14, c.phi_radius);
  ASSIGN_OR_RETURN(const bool inserted, st.Step());
  RETURN_IF_ERROR(st.Run());
  if (!inserted) {
    return absl::AlreadyExistsError(
        absl::StrCat("user \"", user.user_id, "\" already exists"));
  }
  RETURN_IF_ERROR(WriteActionNames(db_, "user_actions", "user_id", user.user_id,
                                   c.action_names, "CreateUser"));
  return txn.Commit();
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
  return ReadUser(db_, st);
}

absl::StatusOr<UserRecord> SqliteEventStore::GetUser(
    const std::string& user_id) {
  absl::MutexLock lock(&mu_);
  return GetUserLocked(user_id);
}

absl::StatusOr<PageResult<UserRecord>> SqliteEventStore::ListUsers(
    const Page& page) {
  store_rows::PageBuilder<UserRecord> out(
      page, 'u', [](const UserRecord& user) { return user.user_id; });
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
  st.BindInt64(1, out.page_size() + 1);
  if (!page.page_token.empty()) st.BindText(2, after);
  while (true) {
    ASSIGN_OR_RETURN(const bool row, st.Step());
    if (!row || !out.Room()) break;
    ASSIGN_OR_RETURN(UserRecord user, ReadUser(db_, st));
    const int64_t bytes = ApproxBytes(user);
    if (!out.Add(std::move(user), bytes)) break;
  }
  return out.Take();
}

absl::Status SqliteEventStore::DeleteUser(const std::string& user_id) {
  RETURN_IF_ERROR(CheckHealth());
  absl::MutexLock lock(&mu_);
  // The deletion is on disk before the contexts are erased, whatever the
  // store's synchronous mode: otherwise a power loss could bring the
  // events back without them.
  const DurableCommit durable(db_, !synchronous_full_);
  RETURN_IF_ERROR(durable.status());
  ASSIGN_OR_RETURN(
      Transaction txn,
      Transaction::Begin(db_, Transaction::Kind::kWrite, "DeleteUser"));
  ASSIGN_OR_RETURN(const auto ranges, ContextRangesLocked(user_id));
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
  RETURN_IF_ERROR(txn.Commit());
  EraseContexts(ranges);
  return absl::OkStatus();
}

absl::StatusOr<std::vector<std::pair<int64_t, int64_t>>>
SqliteEventStore::ContextRangesLocked(const std::string& user_id) {
  std::vector<std::pair<int64_t, int64_t>> ranges;
  if (contexts_ == nullptr) return ranges;
  ASSIGN_OR_RETURN(Statement st,
                   Statement::Prepare(db_,
                                      "SELECT context_offset, context_bytes "
                                      "FROM events WHERE user_id = ?1 AND "
                                      "context_offset IS NOT NULL",
                                      "reading where contexts are"));
  st.BindText(1, user_id);
  while (true) {
    ASSIGN_OR_RETURN(const bool row, st.Step());
    if (!row) break;
    ranges.emplace_back(st.Int64(0), st.Int64(1));
  }
  return ranges;
}

void SqliteEventStore::EraseContexts(
    const std::vector<std::pair<int64_t, int64_t>>& ranges) {
  if (contexts_ == nullptr) return;
  if (const absl::Status erased = contexts_->Erase(ranges); !erased.ok()) {
    std::fprintf(stderr,
                 "bitewise-bandit: deleted events' contexts were not erased "
                 "from the contexts file (they stay, unreferenced): %s\n",
                 erased.ToString().c_str());
  }
}

absl::Status SqliteEventStore::ResetUser(const std::string& user_id) {
  RETURN_IF_ERROR(CheckHealth());
  absl::MutexLock lock(&mu_);
  // The deletion is on disk before the contexts are erased, whatever the
  // store's synchronous mode: otherwise a power loss could bring the
  // events back without them.
  const DurableCommit durable(db_, !synchronous_full_);
  RETURN_IF_ERROR(durable.status());
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
  ASSIGN_OR_RETURN(const auto ranges, ContextRangesLocked(user_id));
  {
    ASSIGN_OR_RETURN(
        Statement st,
        Statement::Prepare(db_, "DELETE FROM events WHERE user_id = ?1",
                           "ResetUser"));
    st.BindText(1, user_id);
    RETURN_IF_ERROR(st.Run());
  }
  RETURN_IF_ERROR(DeleteCheckpointLocked(user_id));
  RETURN_IF_ERROR(txn.Commit());
  EraseContexts(ranges);
  return absl::OkStatus();
}

absl::Status SqliteEventStore::SetLearner(const std::string& user_id,
                                          Learner learner,
                                          int64_t model_version) {
  RETURN_IF_ERROR(CheckHealth());
  absl::MutexLock lock(&mu_);
  ASSIGN_OR_RETURN(
      Transaction txn,
      Transaction::Begin(db_, Transaction::Kind::kWrite, "SetLearner"));
  {
    ASSIGN_OR_RETURN(
        Statement st,
        Statement::Prepare(db_,
                           "SELECT model_version FROM users WHERE user_id = ?1",
                           "SetLearner"));
    st.BindText(1, user_id);
    ASSIGN_OR_RETURN(const bool found, st.Step());
    if (!found) return UserNotFound(user_id);
    RETURN_IF_ERROR(store_rows::LogMovedSince(user_id, model_version,
                                              st.Int64(0), "SetLearner"));
    RETURN_IF_ERROR(st.Run());
  }
  {
    ASSIGN_OR_RETURN(Statement st,
                     Statement::Prepare(db_,
                                        "UPDATE users SET learner = ?2 "
                                        "WHERE user_id = ?1",
                                        "SetLearner"));
    st.BindText(1, user_id);
    st.BindInt64(2, static_cast<int64_t>(learner));
    RETURN_IF_ERROR(st.Run());
  }
  RETURN_IF_ERROR(DeleteCheckpointLocked(user_id));
  return txn.Commit();
}

absl::StatusOr<int64_t> SqliteEventStore::AppendPending(
    const EventRecord& event) {
  RETURN_IF_ERROR(CheckHealth());
  if (std::isnan(event.propensity)) {
    return absl::InvalidArgumentError("propensity must not be NaN");
  }
  const std::string context = EncodeDoubles(event.context);
  const int64_t checksum = SelectionChecksum(
      event.user_id, event.meal_id, event.item_label, context, event.action,
      event.propensity, ToMicros(event.selected_at));
  const absl::Time start = absl::Now();
  int64_t event_id = 0;
  const bool in_file =
      contexts_ != nullptr &&
      static_cast<int64_t>(context.size()) >= context_file_min_bytes_;
  RETURN_IF_ERROR(RunInGroup([&]() ABSL_NO_THREAD_SAFETY_ANALYSIS {
    // The row is inserted only if the user exists, and no row back means
    // it does not; then its context (both in this write's savepoint).
    {
      ASSIGN_OR_RETURN(
          Statement st,
          statements_->Get(
              "INSERT INTO events (user_id, meal_id, item_label, action, "
              "propensity, selected_at_us, completed, selection_checksum, "
              "context_offset, context_bytes) "
              "SELECT ?1, ?2, ?3, ?4, ?5, ?6, 0, ?7, ?8, ?9 "
              "WHERE EXISTS (SELECT 1 FROM users WHERE user_id = ?1) "
              "RETURNING event_id",
              "AppendPending"));
      st.BindText(1, event.user_id);
      st.BindText(2, event.meal_id);
      st.BindText(3, event.item_label);
      st.BindInt64(4, event.action);
      st.BindDouble(5, event.propensity);
      st.BindInt64(6, ToMicros(event.selected_at));
      st.BindInt64(7, checksum);
      if (in_file) {
        // Written now, synced before the group's commit; bytes of a write
        // that does not commit stay unreferenced.
        ASSIGN_OR_RETURN(const int64_t offset, contexts_->Append(context));
        st.BindInt64(8, offset);
        st.BindInt64(9, static_cast<int64_t>(context.size()));
      } else {
        st.BindNull(8);
        st.BindNull(9);
      }
      ASSIGN_OR_RETURN(const bool inserted, st.Step());
      event_id = inserted ? st.Int64(0) : 0;
      RETURN_IF_ERROR(st.Run());
    }
    const bool inserted = event_id != 0;
    if (inserted && !in_file) {
      ASSIGN_OR_RETURN(
          Statement st,
          statements_->Get("INSERT INTO event_contexts (event_id, context) "
                           "VALUES (?1, ?2)",
                           "AppendPending"));
      st.BindInt64(1, event_id);
      st.BindBlob(2, context);
      RETURN_IF_ERROR(st.Run());
    }
    if (!inserted) return UserNotFound(event.user_id);
    return absl::OkStatus();
  }));
  {
    absl::MutexLock stats(&stats_mu_);
    ++write_stats_.appends;
    write_stats_.append_seconds += absl::ToDoubleSeconds(absl::Now() - start);
  }
  return event_id;
}

absl::StatusOr<EventRecord> SqliteEventStore::CompleteEvent(
    int64_t event_id, double loss, const std::vector<double>& posthoc,
    double weight, absl::Time updated_at) {
  RETURN_IF_ERROR(CheckHealth());
  RETURN_IF_ERROR(store_rows::CheckOutcome(loss, weight));
  const std::string posthoc_bytes = EncodeDoubles(posthoc);
  const absl::Time start = absl::Now();
  EventRecord event;
  RETURN_IF_ERROR(RunInGroup([&]() ABSL_NO_THREAD_SAFETY_ANALYSIS {
    {
      // The one read of the event: what the model needs, and whether it
      // is still pending (in this transaction, so never applied twice).
      ASSIGN_OR_RETURN(
          Statement st,
          statements_->Get(absl::StrCat(kEventColumns, "WHERE event_id = ?1"),
                           "CompleteEvent"));
      st.BindInt64(1, event_id);
      ASSIGN_OR_RETURN(const bool found, st.Step());
      if (!found) return EventNotFound(event_id);
      ASSIGN_OR_RETURN(event, ReadEvent(st));
    }
    if (event.completed) return store_rows::AlreadyCompleted(event_id);
    {
      ASSIGN_OR_RETURN(
          Statement st,
          statements_->Get("UPDATE users SET model_version = model_version + 1 "
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
    ASSIGN_OR_RETURN(
        Statement st,
        statements_->Get(
            "UPDATE events SET completed = 1, loss = ?2, posthoc = ?3, "
            "weight = ?4, model_version = ?5, updated_at_us = ?6, "
            "outcome_checksum = ?7 WHERE event_id = ?1",
            "CompleteEvent"));
    st.BindInt64(1, event_id);
    st.BindDouble(2, loss);
    st.BindBlob(3, posthoc_bytes);
    st.BindDouble(4, weight);
    st.BindInt64(5, event.model_version);
    st.BindInt64(6, ToMicros(updated_at));
    st.BindInt64(7, OutcomeChecksum(loss, posthoc_bytes, weight,
                                    event.model_version, ToMicros(updated_at)));
    return st.Run();
  }));
  {
    absl::MutexLock stats(&stats_mu_);
    ++write_stats_.completions;
    write_stats_.completion_seconds +=
        absl::ToDoubleSeconds(absl::Now() - start);
  }
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
  store_rows::PageBuilder<EventRecord> out(
      page, 'e',
      [](const EventRecord& event) { return absl::StrCat(event.event_id); });
  int64_t after = 0;  // event ids start at 1
  if (!page.page_token.empty()) {
    ASSIGN_OR_RETURN(after, store_rows::ParseIdPageToken(page.page_token, 'e'));
  }
  absl::MutexLock lock(&mu_);
  // A read transaction: the existence check and the rows come from one
  // snapshot even if another process writes in between.
  ASSIGN_OR_RETURN(
      Transaction txn,
      Transaction::Begin(db_, Transaction::Kind::kRead, "ListEvents"));
  RETURN_IF_ERROR(CheckUserExistsLocked(user_id));
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
    st.BindInt64(3, out.page_size() + 1);
    if (!meal_id.empty()) st.BindText(4, meal_id);
    while (true) {
      ASSIGN_OR_RETURN(const bool row, st.Step());
      if (!row || !out.Room()) break;
      ASSIGN_OR_RETURN(EventRecord event, ReadEvent(st));
      const int64_t bytes = ApproxBytes(event);
      if (!out.Add(std::move(event), bytes)) break;
    }
  }
  RETURN_IF_ERROR(txn.Commit());
  return out.Take();
}

absl::StatusOr<std::vector<EventRecord>> SqliteEventStore::CompletedEvents(
    const std::string& user_id) {
  return CompletedEventsFrom(user_id, 1);
}

absl::StatusOr<std::vector<EventRecord>> SqliteEventStore::CompletedEventsFrom(
    const std::string& user_id, int64_t from_version) {
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
                                        "AND model_version >= ?2 "
                                        "ORDER BY model_version"),
                           "CompletedEvents"));
    st.BindText(1, user_id);
    st.BindInt64(2, from_version);
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
