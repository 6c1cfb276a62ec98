// PostgresEventStore, model checkpoints: written in chunks, read back and
// checked.
#include <cmath>
#include <utility>

#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "services/bandit/store/checkpoint_protocol.h"
#include "services/bandit/store/event_checksum.h"
#include "services/bandit/store/pg_helpers.h"
#include "services/bandit/store/pg_rows.h"
#include "services/bandit/store/postgres_event_store.h"
#include "services/bandit/store/store_rows.h"
#include "services/common/status_macros.h"

namespace bitewise::bandit {
namespace {

// The checkpoint protocol's rows (checkpoint_protocol.h) on one
// connection. A write is keyed by a sequence: replicas may write the same
// user's checkpoint at once.
class PostgresCheckpointRows final : public CheckpointRows {
 public:
  explicit PostgresCheckpointRows(Connection& conn) : conn_(conn) {}

  absl::StatusOr<int64_t> NewWriteKey(
      const std::string& user_id, const ModelCheckpoint& checkpoint) override {
    ASSIGN_OR_RETURN(
        Rows rows,
        conn_.Exec("SELECT nextval('checkpoint_writes')", "PutCheckpoint"));
    if (!rows.Next()) return absl::InternalError("PutCheckpoint: no write id");
    return rows.Int64(0);
  }

  absl::Status WriteChunk(const std::string& user_id, int64_t key, int64_t seq,
                          absl::string_view bytes) override {
    absl::Status written =
        conn_
            .Exec(
                "INSERT INTO model_checkpoint_chunks (user_id, write_id, "
                "seq, data) VALUES ($1, $2, $3, $4)",
                Params().Text(user_id).Int64(key).Int64(seq).Bytes(bytes),
                "PutCheckpoint")
            .status();
    // The foreign key: the user is unknown (or was deleted meanwhile).
    if (absl::IsFailedPrecondition(written)) return UserNotFound(user_id);
    return written;
  }

  absl::StatusOr<HeaderOutcome> CommitHeader(
      const std::string& user_id, const CheckpointHeader& header) override {
    constexpr char kOp[] = "PutCheckpoint";
    ASSIGN_OR_RETURN(Transaction txn, Transaction::Begin(conn_, kOp));
    RETURN_IF_ERROR(LockUser(conn_, user_id, kOp));
    HeaderOutcome outcome;
    ASSIGN_OR_RETURN(
        Rows current,
        conn_.Exec("SELECT 1 FROM events JOIN users USING (user_id) WHERE "
                   "user_id = $1 AND completed AND events.model_version = $2 "
                   "AND event_id = $3 AND users.learner = $4",
                   Params()
                       .Text(user_id)
                       .Int64(header.model_version)
                       .Int64(header.last_event_id)
                       .Int64(static_cast<int64_t>(header.learner)),
                   kOp));
    outcome.current = current.size() > 0;
    ASSIGN_OR_RETURN(
        Rows stored,
        conn_.Exec(
            "SELECT count(*), coalesce(sum(length(data)), 0) FROM "
            "model_checkpoint_chunks WHERE user_id = $1 AND write_id = $2",
            Params().Text(user_id).Int64(header.write_key), kOp));
    stored.Next();
    outcome.complete = stored.Int64(0) == header.chunks &&
                       stored.Int64(1) == header.state_bytes;
    if (outcome.current && outcome.complete) {
      RETURN_IF_ERROR(
          conn_
              .Exec("INSERT INTO model_checkpoints (user_id, model_version, "
                    "last_event_id, write_id, state_bytes, chunks, checksum, "
                    "created_at_us) VALUES ($1, $2, $3, $4, $5, $6, $7, $8) "
                    "ON CONFLICT (user_id) DO UPDATE SET model_version = "
                    "EXCLUDED.model_version, last_event_id = "
                    "EXCLUDED.last_event_id, write_id = EXCLUDED.write_id, "
                    "state_bytes = EXCLUDED.state_bytes, chunks = "
                    "EXCLUDED.chunks, checksum = EXCLUDED.checksum, "
                    "created_at_us = EXCLUDED.created_at_us "
                    // A replica whose model is behind never replaces a
                    // newer checkpoint with its older one.
                    "WHERE model_checkpoints.model_version <= "
                    "EXCLUDED.model_version",
                    Params()
                        .Text(user_id)
                        .Int64(header.model_version)
                        .Int64(header.last_event_id)
                        .Int64(header.write_key)
                        .Int64(header.state_bytes)
                        .Int64(header.chunks)
                        .Int64(header.checksum)
                        .Int64(ToMicros(header.created_at)),
                    kOp)
              .status());
    }
    // Kept: the current header's chunks (and none if there is no header).
    RETURN_IF_ERROR(
        conn_
            .Exec("DELETE FROM model_checkpoint_chunks c WHERE c.user_id = $1 "
                  "AND NOT EXISTS (SELECT 1 FROM model_checkpoints h WHERE "
                  "h.user_id = $1 AND h.write_id = c.write_id)",
                  Params().Text(user_id), kOp)
            .status());
    RETURN_IF_ERROR(txn.Commit());
    return outcome;
  }

  absl::StatusOr<CheckpointHeader> ReadHeader(
      const std::string& user_id) override {
    ASSIGN_OR_RETURN(
        Rows rows,
        conn_.Exec("SELECT model_version, last_event_id, state_bytes, chunks, "
                   "checksum, created_at_us, write_id FROM model_checkpoints "
                   "WHERE user_id = $1",
                   Params().Text(user_id), "GetCheckpoint"));
    if (!rows.Next()) {
      return absl::NotFoundError(
          absl::StrCat("user ", user_id, " has no model checkpoint"));
    }
    CheckpointHeader header;
    header.model_version = rows.Int64(0);
    header.last_event_id = rows.Int64(1);
    header.state_bytes = rows.Int64(2);
    header.chunks = rows.Int64(3);
    header.checksum = rows.Int64(4);
    header.created_at = FromMicros(rows.Int64(5));
    header.write_key = rows.Int64(6);
    return header;
  }

  absl::Status ReadChunks(
      const std::string& user_id, int64_t key,
      absl::FunctionRef<bool(int64_t, absl::string_view)> chunk) override {
    // One chunk per statement: a whole checkpoint is a hundred MB.
    for (int64_t seq = 0;; ++seq) {
      ASSIGN_OR_RETURN(
          Rows rows,
          conn_.Exec("SELECT data FROM model_checkpoint_chunks WHERE user_id = "
                     "$1 AND write_id = $2 AND seq = $3",
                     Params().Text(user_id).Int64(key).Int64(seq),
                     "GetCheckpoint"));
      if (!rows.Next() || !chunk(seq, rows.Blob(0))) return absl::OkStatus();
    }
  }

 private:
  Connection& conn_;
};

}  // namespace

absl::StatusOr<ModelCheckpoint> pg::ReadCheckpointOn(
    Connection& conn, const std::string& user_id) {
  PostgresCheckpointRows rows(conn);
  return ReadCheckpoint(rows, user_id);
}

absl::Status PostgresEventStore::PutCheckpoint(
    const std::string& user_id, const ModelCheckpoint& checkpoint) {
  ASSIGN_OR_RETURN(pg::Pool::Lease conn, pool_->Acquire("PutCheckpoint"));
  PostgresCheckpointRows rows(*conn);
  return WriteCheckpoint(rows, user_id, checkpoint, kCheckpointChunkBytes);
}

absl::StatusOr<ModelCheckpoint> PostgresEventStore::GetCheckpoint(
    const std::string& user_id) {
  constexpr char kOp[] = "GetCheckpoint";
  ASSIGN_OR_RETURN(pg::Pool::Lease conn, pool_->Acquire(kOp));
  ASSIGN_OR_RETURN(Transaction txn, Transaction::Begin(*conn, kOp, kSnapshot));
  RETURN_IF_ERROR(CheckUserExists(*conn, user_id, kOp));
  ASSIGN_OR_RETURN(ModelCheckpoint out, pg::ReadCheckpointOn(*conn, user_id));
  RETURN_IF_ERROR(txn.Commit());
  return out;
}

absl::Status PostgresEventStore::DeleteCheckpoint(const std::string& user_id) {
  constexpr char kOp[] = "DeleteCheckpoint";
  ASSIGN_OR_RETURN(pg::Pool::Lease conn, pool_->Acquire(kOp));
  ASSIGN_OR_RETURN(Transaction txn, Transaction::Begin(*conn, kOp));
  RETURN_IF_ERROR(LockUser(*conn, user_id, kOp));
  RETURN_IF_ERROR(DeleteCheckpointRows(*conn, user_id, kOp));
  return txn.Commit();
}

}  // namespace bitewise::bandit
