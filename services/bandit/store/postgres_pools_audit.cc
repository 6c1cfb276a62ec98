// PostgresEventStore, population pools, the audit log and the full check.
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
absl::StatusOr<int64_t> PostgresEventStore::AddPool(const PoolRecord& pool) {
  constexpr char kOp[] = "AddPool";
  PopulationPrior stored = pool.prior;
  stored.pool_version = 0;
  stored.rounds = 0.0;
  ASSIGN_OR_RETURN(pg::Pool::Lease conn, pool_->Acquire(kOp));
  ASSIGN_OR_RETURN(Transaction txn, Transaction::Begin(*conn, kOp));
  ASSIGN_OR_RETURN(
      Rows rows,
      conn->Exec("INSERT INTO population_pools (created_at_us, users, "
                 "learner, context_dim, posthoc_dim, prior) VALUES ($1, $2, "
                 "$3, $4, $5, $6) RETURNING pool_version",
                 Params()
                     .Int64(ToMicros(pool.created_at))
                     .Int64(pool.users)
                     .Int64(static_cast<int64_t>(pool.learner))
                     .Int64(pool.context_dim)
                     .Int64(pool.posthoc_dim)
                     .Bytes(EncodePrior(stored)),
                 kOp));
  if (!rows.Next()) return absl::InternalError("AddPool: no pool_version");
  const int64_t version = rows.Int64(0);
  RETURN_IF_ERROR(WriteActionNames(*conn, "pool_actions", "pool_version",
                                   Params().Int64(version), pool.action_names,
                                   kOp));
  RETURN_IF_ERROR(txn.Commit());
  return version;
}

absl::StatusOr<PoolRecord> PostgresEventStore::LatestPool(
    const BanditConfig& config) {
  constexpr char kOp[] = "LatestPool";
  const int posthoc_dim = UsesPosthoc(config.learner) ? config.posthoc_dim : 0;
  ASSIGN_OR_RETURN(pg::Pool::Lease conn, pool_->Acquire(kOp));
  ASSIGN_OR_RETURN(Transaction txn, Transaction::Begin(*conn, kOp, kSnapshot));
  // The newest pool of this learner and these dimensions whose actions are
  // the user's, name for name.
  ASSIGN_OR_RETURN(
      Rows rows,
      conn->Exec("SELECT pool_version, created_at_us, users, prior FROM "
                 "population_pools WHERE learner = $1 AND context_dim = $2 "
                 "AND posthoc_dim = $3 ORDER BY pool_version DESC",
                 Params()
                     .Int64(static_cast<int64_t>(config.learner))
                     .Int64(config.context_dim)
                     .Int64(posthoc_dim),
                 kOp));
  while (rows.Next()) {
    PoolRecord pool;
    pool.pool_version = rows.Int64(0);
    const std::string what = absl::StrCat("pool ", pool.pool_version);
    ASSIGN_OR_RETURN(
        pool.action_names,
        ReadActionNames(*conn, "pool_actions", "pool_version",
                        Params().Int64(pool.pool_version), what, kOp));
    if (pool.action_names != config.action_names) continue;
    pool.created_at = FromMicros(rows.Int64(1));
    pool.users = rows.Int64(2);
    pool.learner = config.learner;
    pool.context_dim = config.context_dim;
    pool.posthoc_dim = posthoc_dim;
    ASSIGN_OR_RETURN(pool.prior, DecodePrior(rows.Blob(3), what));
    pool.prior.pool_version = pool.pool_version;
    RETURN_IF_ERROR(txn.Commit());
    return pool;
  }
  return store_rows::NoPoolFor(config, posthoc_dim);
}

absl::StatusOr<int64_t> PostgresEventStore::AppendAudit(
    const AuditEntry& entry) {
  constexpr char kOp[] = "AppendAudit";
  ASSIGN_OR_RETURN(pg::Pool::Lease conn, pool_->Acquire(kOp));
  ASSIGN_OR_RETURN(Rows rows,
                   conn->Exec("INSERT INTO audit (at_us, method, target, "
                              "identity, role, peer, result) VALUES ($1, $2, "
                              "$3, $4, $5, $6, $7) RETURNING audit_id",
                              Params()
                                  .Int64(ToMicros(entry.time))
                                  .Text(entry.method)
                                  .Text(entry.target)
                                  .Text(entry.identity)
                                  .Text(entry.role)
                                  .Text(entry.peer)
                                  .Text(entry.result),
                              kOp));
  if (!rows.Next()) return absl::InternalError("AppendAudit: no audit_id");
  return rows.Int64(0);
}

absl::StatusOr<PageResult<AuditEntry>> PostgresEventStore::ListAudit(
    const Page& page) {
  constexpr char kOp[] = "ListAudit";
  store_rows::PageBuilder<AuditEntry> out(
      page, 'a',
      [](const AuditEntry& entry) { return absl::StrCat(entry.audit_id); });
  int64_t after = 0;
  if (!page.page_token.empty()) {
    ASSIGN_OR_RETURN(after, store_rows::ParseIdPageToken(page.page_token, 'a'));
  }
  ASSIGN_OR_RETURN(pg::Pool::Lease conn, pool_->Acquire(kOp));
  ASSIGN_OR_RETURN(
      Rows rows,
      conn->Exec("SELECT audit_id, at_us, method, target, identity, role, "
                 "peer, result FROM audit WHERE audit_id > $1 ORDER BY "
                 "audit_id LIMIT $2",
                 Params().Int64(after).Int64(out.page_size() + 1), kOp));
  while (rows.Next() && out.Room()) {
    out.Add(store_rows::ReadAuditRow(rows), /*bytes=*/0);
  }
  return out.Take();
}

absl::StatusOr<StoreCheckReport> PostgresEventStore::CheckStore() {
  constexpr char kOp[] = "CheckStore";
  constexpr int64_t kBatch = 500;
  ASSIGN_OR_RETURN(pg::Pool::Lease conn, pool_->Acquire(kOp));
  ASSIGN_OR_RETURN(Transaction txn, Transaction::Begin(*conn, kOp, kSnapshot));
  store_rows::CheckReportBuilder report;
  {
    ASSIGN_OR_RETURN(
        Rows users,
        conn->Exec(absl::StrCat(kUserColumns, "ORDER BY u.user_id"), kOp));
    while (users.Next()) RETURN_IF_ERROR(report.User(ReadUser(*conn, users)));
  }
  {
    // Each user's count of selections, which replicas index the random
    // stream with, against the log.
    ASSIGN_OR_RETURN(
        Rows counts,
        conn->Exec("SELECT user_id, selections, n FROM (SELECT u.user_id, "
                   "u.selections, u.model_version + (SELECT count(*) FROM "
                   "events e WHERE e.user_id = u.user_id AND NOT e.completed) "
                   "AS n FROM users u) c WHERE selections <> n ORDER BY "
                   "user_id",
                   kOp));
    while (counts.Next()) {
      RETURN_IF_ERROR(report.User(absl::DataLossError(
          absl::StrCat("user \"", counts.Text(0), "\" counts ", counts.Int64(1),
                       " selections, but its log holds ", counts.Int64(2),
                       " (completed and pending)"))));
    }
  }
  // In batches: the server never holds every context in one result.
  for (int64_t after = 0;;) {
    ASSIGN_OR_RETURN(Rows events,
                     conn->Exec(absl::StrCat(kEventColumns,
                                             "WHERE e.event_id > $1 ORDER BY "
                                             "e.event_id LIMIT $2"),
                                Params().Int64(after).Int64(kBatch), kOp));
    while (events.Next()) {
      after = events.Int64(0);
      RETURN_IF_ERROR(report.Event(store_rows::ReadEventRow(events).status()));
    }
    if (events.size() < kBatch) break;
  }
  {
    std::vector<std::string> with_checkpoint;
    ASSIGN_OR_RETURN(Rows rows,
                     conn->Exec("SELECT user_id FROM model_checkpoints ORDER "
                                "BY user_id",
                                kOp));
    while (rows.Next()) with_checkpoint.push_back(rows.Text(0));
    for (const std::string& user_id : with_checkpoint) {
      RETURN_IF_ERROR(
          report.Checkpoint(pg::ReadCheckpointOn(*conn, user_id).status()));
    }
  }
  RETURN_IF_ERROR(txn.Commit());
  return report.Take();
}

}  // namespace bitewise::bandit
