// EventLog: the store's first role, each user's configuration and event
// log (context, action, propensity, loss, post hoc context, meal, times),
// from which models are derived. Select writes a pending event; Update
// completes it in one transaction, exactly once.
#ifndef BITEWISE_SERVICES_BANDIT_STORE_EVENT_LOG_H_
#define BITEWISE_SERVICES_BANDIT_STORE_EVENT_LOG_H_

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/time/time.h"
#include "services/bandit/store/store_records.h"

namespace bitewise::bandit {

class EventLog {
 public:
  virtual ~EventLog() = default;

  // ALREADY_EXISTS if the id is taken.
  virtual absl::Status CreateUser(const UserRecord& user) = 0;
  // NOT_FOUND if unknown.
  virtual absl::StatusOr<UserRecord> GetUser(const std::string& user_id) = 0;
  // Ordered by user_id.
  virtual absl::StatusOr<PageResult<UserRecord>> ListUsers(
      const Page& page) = 0;
  // Deletes the user and all of its events. NOT_FOUND if unknown.
  virtual absl::Status DeleteUser(const std::string& user_id) = 0;
  // Deletes all of the user's events and sets model_version to 0; keeps the
  // configuration. NOT_FOUND if unknown.
  virtual absl::Status ResetUser(const std::string& user_id) = 0;
  // Changes the user's learner and keeps every event, so the model is
  // rebuilt from the log under the new learner; deletes the user's
  // checkpoint (the old learner's). Shared stores give the user a new
  // incarnation, so other processes drop their cached models. Only while
  // the user has `model_version` completed events (the log the caller
  // checked the new learner on): ABORTED, nothing written, otherwise.
  // NOT_FOUND if unknown.
  virtual absl::Status SetLearner(const std::string& user_id, Learner learner,
                                  int64_t model_version) = 0;

  // Durably appends a pending event (event_id, completed and the outcome
  // fields of `event` are ignored) and returns its new event_id.
  // NOT_FOUND if the user is unknown.
  virtual absl::StatusOr<int64_t> AppendPending(const EventRecord& event) = 0;

  // In one transaction: marks the pending event completed with this outcome,
  // increments the user's model_version and stores it on the event. Returns
  // the completed event. NOT_FOUND for an unknown event; FAILED_PRECONDITION
  // if it is already completed (nothing is written).
  virtual absl::StatusOr<EventRecord> CompleteEvent(
      int64_t event_id, double loss, const std::vector<double>& posthoc,
      double weight, absl::Time updated_at) = 0;

  // NOT_FOUND if unknown.
  virtual absl::StatusOr<EventRecord> GetEvent(int64_t event_id) = 0;

  // A user's events in event_id order, optionally only one meal's.
  virtual absl::StatusOr<PageResult<EventRecord>> ListEvents(
      const std::string& user_id, const std::string& meal_id,
      const Page& page) = 0;

  // Every completed event of the user in model_version order: the log the
  // model is rebuilt from.
  virtual absl::StatusOr<std::vector<EventRecord>> CompletedEvents(
      const std::string& user_id) = 0;

  // Completed events of the user with model_version >= `from_version`, in
  // model_version order.
  virtual absl::StatusOr<std::vector<EventRecord>> CompletedEventsFrom(
      const std::string& user_id, int64_t from_version) = 0;
};

}  // namespace bitewise::bandit

#endif  // BITEWISE_SERVICES_BANDIT_STORE_EVENT_LOG_H_
