// The checkpoint protocol (internal to services/bandit/store), written once
// for both stores: how a saved model is written without holding up other
// calls, when it counts, and how it is read back and checked.
//
// Writing: the state is cut into chunks, each written in a transaction of
// its own under a write key no other write of the user's checkpoint uses;
// then, in one transaction under the user's lock, the header is written if
// the log still has the checkpoint's last event at its model version, the
// user's learner is still the checkpoint's, and every chunk of this write
// is there (a concurrent checkpoint or delete
// removes chunks it does not keep), never replacing a newer header; and
// the chunks of every other write go. The checkpoint counts once its header
// is committed. Reading: the header, then its write's chunks in order,
// checked against the header's size, chunk count and checksum.
//
// A store provides the rows (CheckpointRows); SQLite keys a write by its
// model version (one process writes), PostgreSQL by a sequence (replicas
// may write the same version at once).
#ifndef BITEWISE_SERVICES_BANDIT_STORE_CHECKPOINT_PROTOCOL_H_
#define BITEWISE_SERVICES_BANDIT_STORE_CHECKPOINT_PROTOCOL_H_

#include <cstddef>
#include <cstdint>
#include <string>

#include "absl/functional/function_ref.h"
#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "absl/time/time.h"
#include "services/bandit/store/store_records.h"

namespace bitewise::bandit {

struct CheckpointHeader {
  int64_t model_version = 0;
  int64_t last_event_id = 0;
  Learner learner = Learner::kPostHoc;  // must be the user's to be current
  int64_t write_key = 0;
  int64_t state_bytes = 0;
  int64_t chunks = 0;
  int64_t checksum = 0;
  absl::Time created_at;
};

// What CommitHeader found.
struct HeaderOutcome {
  // The log has the last event at the version, and the user the learner.
  bool current = false;
  bool complete = false;  // every chunk of the write is there
};

class CheckpointRows {
 public:
  virtual ~CheckpointRows() = default;
  // A key for a new write of `checkpoint`.
  virtual absl::StatusOr<int64_t> NewWriteKey(
      const std::string& user_id, const ModelCheckpoint& checkpoint) = 0;
  // One chunk, in its own transaction. NOT_FOUND for an unknown user.
  virtual absl::Status WriteChunk(const std::string& user_id, int64_t key,
                                  int64_t seq, absl::string_view bytes) = 0;
  // In one transaction under the user's lock: see the file comment.
  // NOT_FOUND for an unknown user.
  virtual absl::StatusOr<HeaderOutcome> CommitHeader(
      const std::string& user_id, const CheckpointHeader& header) = 0;
  // Inside the caller's read transaction: the header (NOT_FOUND "user U
  // has no model checkpoint"), and the chunks of `key` from seq 0 in
  // order, each handed to `chunk` until it returns false.
  virtual absl::StatusOr<CheckpointHeader> ReadHeader(
      const std::string& user_id) = 0;
  virtual absl::Status ReadChunks(
      const std::string& user_id, int64_t key,
      absl::FunctionRef<bool(int64_t seq, absl::string_view bytes)> chunk) = 0;
};

// PutCheckpoint's contract (checkpoint_store.h), in chunks of `chunk_bytes`.
absl::Status WriteCheckpoint(CheckpointRows& rows, const std::string& user_id,
                             const ModelCheckpoint& checkpoint,
                             size_t chunk_bytes);

// GetCheckpoint's contract, inside the caller's read transaction: DATA_LOSS
// naming the user when the bytes are incomplete or do not match the
// checksum.
absl::StatusOr<ModelCheckpoint> ReadCheckpoint(CheckpointRows& rows,
                                               const std::string& user_id);

}  // namespace bitewise::bandit

#endif  // BITEWISE_SERVICES_BANDIT_STORE_CHECKPOINT_PROTOCOL_H_
