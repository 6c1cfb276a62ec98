#include "services/bandit/store/checkpoint_protocol.h"

#include "absl/strings/str_cat.h"
#include "services/bandit/store/event_checksum.h"
#include "services/bandit/store/store_rows.h"
#include "services/common/status_macros.h"

namespace bitewise::bandit {

absl::Status WriteCheckpoint(CheckpointRows& rows, const std::string& user_id,
                             const ModelCheckpoint& checkpoint,
                             size_t chunk_bytes) {
  if (checkpoint.model_version <= 0 || checkpoint.state.empty()) {
    return absl::InvalidArgumentError(
        "checkpoint: needs model_version > 0 and a state");
  }
  const absl::string_view state = checkpoint.state;
  CheckpointHeader header;
  header.model_version = checkpoint.model_version;
  header.last_event_id = checkpoint.last_event_id;
  header.learner = checkpoint.learner;
  header.state_bytes = static_cast<int64_t>(state.size());
  header.chunks =
      static_cast<int64_t>((state.size() + chunk_bytes - 1) / chunk_bytes);
  header.checksum = BlobChecksum(state);
  header.created_at = checkpoint.created_at;
  ASSIGN_OR_RETURN(header.write_key, rows.NewWriteKey(user_id, checkpoint));
  // The chunks first, one transaction each: other calls run in between.
  for (int64_t seq = 0; seq < header.chunks; ++seq) {
    RETURN_IF_ERROR(rows.WriteChunk(
        user_id, header.write_key, seq,
        state.substr(static_cast<size_t>(seq) * chunk_bytes, chunk_bytes)));
  }
  ASSIGN_OR_RETURN(const HeaderOutcome outcome,
                   rows.CommitHeader(user_id, header));
  if (!outcome.current) {
    return store_rows::CheckpointNotKept(user_id, checkpoint);
  }
  if (!outcome.complete) {
    return absl::AbortedError(absl::StrCat(
        "checkpoint of user ", user_id, " at model version ",
        checkpoint.model_version,
        ": a concurrent checkpoint or delete removed its chunks; not kept"));
  }
  return absl::OkStatus();
}

absl::StatusOr<ModelCheckpoint> ReadCheckpoint(CheckpointRows& rows,
                                               const std::string& user_id) {
  ASSIGN_OR_RETURN(const CheckpointHeader header, rows.ReadHeader(user_id));
  ModelCheckpoint out;
  out.model_version = header.model_version;
  out.last_event_id = header.last_event_id;
  out.created_at = header.created_at;
  if (header.state_bytes > 0) {
    out.state.reserve(static_cast<size_t>(header.state_bytes));
  }
  int64_t expected_seq = 0;
  bool in_order = true;
  RETURN_IF_ERROR(rows.ReadChunks(
      user_id, header.write_key, [&](int64_t seq, absl::string_view bytes) {
        if (seq != expected_seq || expected_seq >= header.chunks) {
          in_order = false;
          return false;
        }
        ++expected_seq;
        out.state.append(bytes.data(), bytes.size());
        return true;
      }));
  if (!in_order || expected_seq != header.chunks ||
      static_cast<int64_t>(out.state.size()) != header.state_bytes ||
      BlobChecksum(out.state) != header.checksum) {
    return store_rows::CheckpointDamaged(user_id, out.model_version,
                                         out.state.size(), header.state_bytes,
                                         expected_seq, header.chunks);
  }
  return out;
}

}  // namespace bitewise::bandit
