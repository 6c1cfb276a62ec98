// CheckpointStore: the store's role that keeps one saved model per user
// and the part of the log it covers, so a cold load reads it and the events
// after it instead of the whole log.
#ifndef BITEWISE_SERVICES_BANDIT_STORE_CHECKPOINT_STORE_H_
#define BITEWISE_SERVICES_BANDIT_STORE_CHECKPOINT_STORE_H_

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/time/time.h"
#include "services/bandit/store/store_records.h"

namespace bitewise::bandit {

class CheckpointStore {
 public:
  virtual ~CheckpointStore() = default;

  // Durably replaces the user's checkpoint. Large states are written in
  // chunks, each its own transaction, so other calls are not held up; the
  // checkpoint counts once its header is written. FAILED_PRECONDITION if the
  // log no longer has `last_event_id` at `model_version` (the user was reset
  // meanwhile) or the user's learner is no longer `checkpoint.learner`
  // (SetLearner meanwhile): nothing is kept. NOT_FOUND for an unknown user.
  virtual absl::Status PutCheckpoint(const std::string& user_id,
                                     const ModelCheckpoint& checkpoint) = 0;
  // The user's checkpoint. NOT_FOUND if there is none; DATA_LOSS naming the
  // user if its bytes are incomplete or do not match their checksum.
  virtual absl::StatusOr<ModelCheckpoint> GetCheckpoint(
      const std::string& user_id) = 0;
  // Removes the user's checkpoint, if any (ResetUser, SetLearner and
  // DeleteUser do too).
  virtual absl::Status DeleteCheckpoint(const std::string& user_id) = 0;
};

}  // namespace bitewise::bandit

#endif  // BITEWISE_SERVICES_BANDIT_STORE_CHECKPOINT_STORE_H_
