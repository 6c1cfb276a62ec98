// SqliteEventStore, population pools, the audit log and the full check.
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
absl::StatusOr<int64_t> SqliteEventStore::AddPool(const PoolRecord& pool) {
  RETURN_IF_ERROR(CheckHealth());
  absl::MutexLock lock(&mu_);
  ASSIGN_OR_RETURN(
      Transaction txn,
      Transaction::Begin(db_, Transaction::Kind::kWrite, "AddPool"));
  ASSIGN_OR_RETURN(
      Statement st,
      Statement::Prepare(
          db_,
          "INSERT INTO population_pools (created_at_us, users, learner, "
          "context_dim, posthoc_dim, prior) "
          "VALUES (?1, ?2, ?3, ?4, ?5, ?6) RETURNING pool_version",
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
  st.BindBlob(6, prior);
  ASSIGN_OR_RETURN(const bool row, st.Step());
  if (!row) return absl::InternalError("AddPool: no pool_version returned");
  const int64_t version = st.Int64(0);
  RETURN_IF_ERROR(st.Run());
  // Bound as text like any key; the column's INTEGER affinity converts it.
  RETURN_IF_ERROR(WriteActionNames(db_, "pool_actions", "pool_version",
                                   absl::StrCat(version), pool.action_names,
                                   "AddPool"));
  RETURN_IF_ERROR(txn.Commit());
  return version;
}

absl::StatusOr<PoolRecord> SqliteEventStore::LatestPool(
    const BanditConfig& config) {
  absl::MutexLock lock(&mu_);
  ASSIGN_OR_RETURN(
      Transaction txn,
      Transaction::Begin(db_, Transaction::Kind::kRead, "LatestPool"));
  // The newest pool of this learner and these dimensions whose actions are
  // the user's, name for name.
  ASSIGN_OR_RETURN(
      Statement st,
      Statement::Prepare(
          db_,
          "SELECT pool_version, created_at_us, users, prior "
          "FROM population_pools WHERE learner = ?1 AND context_dim = ?2 AND "
          "posthoc_dim = ?3 ORDER BY pool_version DESC",
          "LatestPool"));
  const int posthoc_dim = UsesPosthoc(config.learner) ? config.posthoc_dim : 0;
  st.BindInt64(1, static_cast<int64_t>(config.learner));
  st.BindInt64(2, config.context_dim);
  st.BindInt64(3, posthoc_dim);
  while (true) {
    ASSIGN_OR_RETURN(const bool row, st.Step());
    if (!row) break;
    PoolRecord pool;
    pool.pool_version = st.Int64(0);
    const std::string what = absl::StrCat("pool ", pool.pool_version);
    ASSIGN_OR_RETURN(
        pool.action_names,
        ReadActionNames(db_, "pool_actions", "pool_version",
                        absl::StrCat(pool.pool_version), what, "LatestPool"));
    if (pool.action_names != config.action_names) continue;
    pool.created_at = FromMicros(st.Int64(1));
    pool.users = st.Int64(2);
    pool.learner = config.learner;
    pool.context_dim = config.context_dim;
    pool.posthoc_dim = posthoc_dim;
    ASSIGN_OR_RETURN(pool.prior, DecodePrior(st.Blob(3), what));
    pool.prior.pool_version = pool.pool_version;
    return pool;
  }
  return store_rows::NoPoolFor(config, posthoc_dim);
}

absl::StatusOr<int64_t> SqliteEventStore::AppendAudit(const AuditEntry& entry) {
  RETURN_IF_ERROR(CheckHealth());
  absl::MutexLock lock(&mu_);
  ASSIGN_OR_RETURN(
      Statement st,
      Statement::Prepare(db_,
                         "INSERT INTO audit (at_us, method, target, identity, "
                         "role, peer, result) VALUES (?1, ?2, ?3, ?4, ?5, ?6, "
                         "?7) RETURNING audit_id",
                         "AppendAudit"));
  st.BindInt64(1, ToMicros(entry.time));
  st.BindText(2, entry.method);
  st.BindText(3, entry.target);
  st.BindText(4, entry.identity);
  st.BindText(5, entry.role);
  st.BindText(6, entry.peer);
  st.BindText(7, entry.result);
  ASSIGN_OR_RETURN(const bool row, st.Step());
  if (!row) return absl::InternalError("AppendAudit: no audit_id returned");
  const int64_t id = st.Int64(0);
  RETURN_IF_ERROR(st.Run());
  return id;
}

absl::StatusOr<PageResult<AuditEntry>> SqliteEventStore::ListAudit(
    const Page& page) {
  store_rows::PageBuilder<AuditEntry> out(
      page, 'a',
      [](const AuditEntry& entry) { return absl::StrCat(entry.audit_id); });
  int64_t after = 0;
  if (!page.page_token.empty()) {
    ASSIGN_OR_RETURN(after, store_rows::ParseIdPageToken(page.page_token, 'a'));
  }
  absl::MutexLock lock(&mu_);
  ASSIGN_OR_RETURN(
      Statement st,
      Statement::Prepare(db_,
                         "SELECT audit_id, at_us, method, target, identity, "
                         "role, peer, result FROM audit WHERE audit_id > ?1 "
                         "ORDER BY audit_id LIMIT ?2",
                         "ListAudit"));
  st.BindInt64(1, after);
  st.BindInt64(2, out.page_size() + 1);
  while (true) {
    ASSIGN_OR_RETURN(const bool row, st.Step());
    if (!row || !out.Room()) break;
    out.Add(store_rows::ReadAuditRow(st), /*bytes=*/0);
  }
  return out.Take();
}

absl::StatusOr<StoreCheckReport> SqliteEventStore::CheckStore() {
  constexpr int kMaxFindings = 100;
  absl::MutexLock lock(&mu_);
  ASSIGN_OR_RETURN(std::vector<std::string> findings,
                   sqlite::IntegrityFindings(db_, kMaxFindings));
  store_rows::CheckReportBuilder report(std::move(findings));
  ASSIGN_OR_RETURN(
      Transaction txn,
      Transaction::Begin(db_, Transaction::Kind::kRead, "CheckStore"));
  {
    ASSIGN_OR_RETURN(
        Statement users,
        Statement::Prepare(db_, absl::StrCat(kUserColumns, "ORDER BY user_id"),
                           "CheckStore"));
    while (true) {
      ASSIGN_OR_RETURN(const bool row, users.Step());
      if (!row) break;
      RETURN_IF_ERROR(report.User(ReadUser(db_, users)));
    }
  }
  {
    ASSIGN_OR_RETURN(Statement events,
                     Statement::Prepare(
                         db_, absl::StrCat(kEventColumns, "ORDER BY event_id"),
                         "CheckStore"));
    while (true) {
      ASSIGN_OR_RETURN(const bool row, events.Step());
      if (!row) break;
      RETURN_IF_ERROR(report.Event(ReadEvent(events).status()));
    }
  }
  {
    // Checkpoints are derived (a damaged one is ignored and the model
    // rebuilt from the log), but a damaged one is still worth knowing of.
    std::vector<std::string> with_checkpoint;
    ASSIGN_OR_RETURN(
        Statement st,
        Statement::Prepare(
            db_, "SELECT user_id FROM model_checkpoints ORDER BY user_id",
            "CheckStore"));
    while (true) {
      ASSIGN_OR_RETURN(const bool row, st.Step());
      if (!row) break;
      with_checkpoint.push_back(st.Text(0));
    }
    for (const std::string& user_id : with_checkpoint) {
      RETURN_IF_ERROR(
          report.Checkpoint(ReadCheckpointLocked(user_id).status()));
    }
  }
  RETURN_IF_ERROR(txn.Commit());
  return report.Take();
}

}  // namespace bitewise::bandit
