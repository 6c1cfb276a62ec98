// SqliteEventStore, model checkpoints: written in chunks, read back and
// checked.
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
#include "services/bandit/store/checkpoint_protocol.h"
#include "services/bandit/store/context_file.h"
#include "services/bandit/store/event_checksum.h"
#include "services/bandit/store/sqlite_event_store.h"
#include "services/bandit/store/sqlite_helpers.h"
#include "services/bandit/store/sqlite_rows.h"
#include "services/bandit/store/sqlite_schema.h"
#include "services/bandit/store/store_rows.h"
#include "services/common/status_macros.h"

namespace bitewise::bandit {
// The checkpoint protocol's rows (checkpoint_protocol.h). A write is keyed
// by its model version: one process writes the file.
class SqliteEventStore::CheckpointRowsImpl final : public CheckpointRows {
 public:
  explicit CheckpointRowsImpl(SqliteEventStore& store) : store_(store) {}

  absl::StatusOr<int64_t> NewWriteKey(
      const std::string& user_id, const ModelCheckpoint& checkpoint) override {
    return checkpoint.model_version;
  }

  absl::Status WriteChunk(const std::string& user_id, int64_t key, int64_t seq,
                          absl::string_view bytes) override
      ABSL_NO_THREAD_SAFETY_ANALYSIS {
    constexpr char kOp[] = "PutCheckpoint";
    absl::MutexLock lock(&store_.mu_);
    ASSIGN_OR_RETURN(
        Transaction txn,
        Transaction::Begin(store_.db_, Transaction::Kind::kWrite, kOp));
    RETURN_IF_ERROR(store_.CheckUserExistsLocked(user_id));
    ASSIGN_OR_RETURN(
        Statement st,
        Statement::Prepare(store_.db_,
                           "INSERT OR REPLACE INTO model_checkpoint_chunks "
                           "(user_id, model_version, seq, data) "
                           "VALUES (?1, ?2, ?3, ?4)",
                           kOp));
    st.BindText(1, user_id);
    st.BindInt64(2, key);
    st.BindInt64(3, seq);
    st.BindBlob(4, bytes);
    RETURN_IF_ERROR(st.Run());
    return txn.Commit();
  }

  absl::StatusOr<HeaderOutcome> CommitHeader(
      const std::string& user_id,
      const CheckpointHeader& header) override ABSL_NO_THREAD_SAFETY_ANALYSIS {
    constexpr char kOp[] = "PutCheckpoint";
    sqlite3* db = store_.db_;
    absl::MutexLock lock(&store_.mu_);
    ASSIGN_OR_RETURN(Transaction txn,
                     Transaction::Begin(db, Transaction::Kind::kWrite, kOp));
    RETURN_IF_ERROR(store_.CheckUserExistsLocked(user_id));
    HeaderOutcome outcome;
    {
      ASSIGN_OR_RETURN(
          Statement st,
          Statement::Prepare(db,
                             "SELECT 1 FROM events JOIN users USING (user_id) "
                             "WHERE user_id = ?1 AND completed = 1 AND "
                             "events.model_version = ?2 AND event_id = ?3 AND "
                             "users.learner = ?4",
                             kOp));
      st.BindText(1, user_id);
      st.BindInt64(2, header.model_version);
      st.BindInt64(3, header.last_event_id);
      st.BindInt64(4, static_cast<int64_t>(header.learner));
      ASSIGN_OR_RETURN(outcome.current, st.Step());
      RETURN_IF_ERROR(st.Run());
    }
    {
      ASSIGN_OR_RETURN(
          Statement st,
          Statement::Prepare(db,
                             "SELECT count(*), coalesce(sum(length(data)), 0) "
                             "FROM model_checkpoint_chunks WHERE user_id = ?1 "
                             "AND model_version = ?2",
                             kOp));
      st.BindText(1, user_id);
      st.BindInt64(2, header.write_key);
      ASSIGN_OR_RETURN(const bool row, st.Step());
      outcome.complete = row && st.Int64(0) == header.chunks &&
                         st.Int64(1) == header.state_bytes;
      RETURN_IF_ERROR(st.Run());
    }
    if (outcome.current && outcome.complete) {
      ASSIGN_OR_RETURN(
          Statement st,
          Statement::Prepare(
              db,
              "INSERT OR REPLACE INTO model_checkpoints (user_id, "
              "model_version, last_event_id, state_bytes, chunks, checksum, "
              "created_at_us) SELECT ?1, ?2, ?3, ?4, ?5, ?6, ?7 WHERE NOT "
              "EXISTS (SELECT 1 FROM model_checkpoints WHERE user_id = ?1 "
              "AND model_version > ?2)",
              kOp));
      st.BindText(1, user_id);
      st.BindInt64(2, header.model_version);
      st.BindInt64(3, header.last_event_id);
      st.BindInt64(4, header.state_bytes);
      st.BindInt64(5, header.chunks);
      st.BindInt64(6, header.checksum);
      st.BindInt64(7, ToMicros(header.created_at));
      RETURN_IF_ERROR(st.Run());
    }
    {
      ASSIGN_OR_RETURN(
          Statement st,
          Statement::Prepare(db,
                             // Kept: the current header's chunks.
                             "DELETE FROM model_checkpoint_chunks WHERE "
                             "user_id = ?1 AND model_version NOT IN (SELECT "
                             "model_version FROM model_checkpoints WHERE "
                             "user_id = ?1)",
                             kOp));
      st.BindText(1, user_id);
      RETURN_IF_ERROR(st.Run());
    }
    RETURN_IF_ERROR(txn.Commit());
    return outcome;
  }

  absl::StatusOr<CheckpointHeader> ReadHeader(
      const std::string& user_id) override ABSL_NO_THREAD_SAFETY_ANALYSIS {
    ASSIGN_OR_RETURN(
        Statement st,
        Statement::Prepare(store_.db_,
                           "SELECT model_version, last_event_id, state_bytes, "
                           "chunks, checksum, created_at_us FROM "
                           "model_checkpoints WHERE user_id = ?1",
                           "GetCheckpoint"));
    st.BindText(1, user_id);
    ASSIGN_OR_RETURN(const bool row, st.Step());
    if (!row) {
      return absl::NotFoundError(
          absl::StrCat("user ", user_id, " has no model checkpoint"));
    }
    CheckpointHeader header;
    header.model_version = st.Int64(0);
    header.write_key = header.model_version;
    header.last_event_id = st.Int64(1);
    header.state_bytes = st.Int64(2);
    header.chunks = st.Int64(3);
    header.checksum = st.Int64(4);
    header.created_at = FromMicros(st.Int64(5));
    RETURN_IF_ERROR(st.Run());
    return header;
  }

  absl::Status ReadChunks(const std::string& user_id, int64_t key,
                          absl::FunctionRef<bool(int64_t, absl::string_view)>
                              chunk) override ABSL_NO_THREAD_SAFETY_ANALYSIS {
    ASSIGN_OR_RETURN(
        Statement st,
        Statement::Prepare(store_.db_,
                           "SELECT seq, data FROM model_checkpoint_chunks "
                           "WHERE user_id = ?1 AND model_version = ?2 "
                           "ORDER BY seq",
                           "GetCheckpoint"));
    st.BindText(1, user_id);
    st.BindInt64(2, key);
    while (true) {
      ASSIGN_OR_RETURN(const bool row, st.Step());
      if (!row || !chunk(st.Int64(0), st.Blob(1))) break;
    }
    return absl::OkStatus();
  }

 private:
  SqliteEventStore& store_;
};

absl::Status SqliteEventStore::PutCheckpoint(
    const std::string& user_id, const ModelCheckpoint& checkpoint) {
  RETURN_IF_ERROR(CheckHealth());
  CheckpointRowsImpl rows(*this);
  return WriteCheckpoint(rows, user_id, checkpoint, kCheckpointChunkBytes);
}

absl::StatusOr<ModelCheckpoint> SqliteEventStore::GetCheckpoint(
    const std::string& user_id) {
  absl::MutexLock lock(&mu_);
  ASSIGN_OR_RETURN(
      Transaction txn,
      Transaction::Begin(db_, Transaction::Kind::kRead, "GetCheckpoint"));
  RETURN_IF_ERROR(CheckUserExistsLocked(user_id));
  ASSIGN_OR_RETURN(ModelCheckpoint out, ReadCheckpointLocked(user_id));
  RETURN_IF_ERROR(txn.Commit());
  return out;
}

absl::StatusOr<ModelCheckpoint> SqliteEventStore::ReadCheckpointLocked(
    const std::string& user_id) {
  CheckpointRowsImpl rows(*this);
  return ReadCheckpoint(rows, user_id);
}

absl::Status SqliteEventStore::DeleteCheckpoint(const std::string& user_id) {
  RETURN_IF_ERROR(CheckHealth());
  absl::MutexLock lock(&mu_);
  ASSIGN_OR_RETURN(
      Transaction txn,
      Transaction::Begin(db_, Transaction::Kind::kWrite, "DeleteCheckpoint"));
  RETURN_IF_ERROR(CheckUserExistsLocked(user_id));
  RETURN_IF_ERROR(DeleteCheckpointLocked(user_id));
  return txn.Commit();
}

absl::Status SqliteEventStore::DeleteCheckpointLocked(
    const std::string& user_id) {
  for (const char* sql :
       {"DELETE FROM model_checkpoints WHERE user_id = ?1",
        "DELETE FROM model_checkpoint_chunks WHERE user_id = ?1"}) {
    ASSIGN_OR_RETURN(Statement st,
                     Statement::Prepare(db_, sql, "DeleteCheckpoint"));
    st.BindText(1, user_id);
    RETURN_IF_ERROR(st.Run());
  }
  return absl::OkStatus();
}

}  // namespace bitewise::bandit
