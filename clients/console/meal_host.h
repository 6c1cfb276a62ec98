// MealHost: the one meal bitewise-console runs on its robot, apart from any
// browser. Meals run on the host's own worker thread through the meal
// library, so a browser that disconnects mid-bite neither stops nor repeats
// the bite; every browser sees the same meal through a Subscription (the
// current state at once, then every change); a second meal while one runs
// is refused naming it; every update not yet delivered (an operator's
// answer, an Update the BanditService could not take) is in the journal
// file, delivered when the next meal starts, so a console killed mid-meal
// loses none.
//
// Thread-safe. Errors: INVALID_ARGUMENT for a bad id or an item not on the
// plate, FAILED_PRECONDITION when the meal is not in a state for the
// request (the message says why, naming the running meal), and the meal
// library's errors.
#ifndef BITEWISE_CLIENTS_CONSOLE_MEAL_HOST_H_
#define BITEWISE_CLIENTS_CONSOLE_MEAL_HOST_H_

#include <deque>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "absl/base/thread_annotations.h"
#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/synchronization/mutex.h"
#include "absl/time/time.h"
#include "clients/meal/meal.h"
#include "clients/meal/service_clients.h"
#include "clients/meal/update_journal.h"

namespace bitewise::console {

namespace mealpb = ::bitewise::meal::v1;

// One browser's view of the meal: Server-Sent Events frames, in order.
class Subscription {
 public:
  // The next frame, waiting at most `timeout`; nullopt on timeout or once
  // closed (see closed()).
  std::optional<std::string> Next(absl::Duration timeout);
  void Push(std::string frame);
  void Close();
  bool closed() const;

 private:
  // A browser that falls this far behind is dropped; it reconnects and is
  // sent the current state.
  static constexpr size_t kMaxQueued = 512;
  mutable absl::Mutex mu_;
  std::deque<std::string> frames_ ABSL_GUARDED_BY(mu_);
  bool closed_ ABSL_GUARDED_BY(mu_) = false;
};

// Protobuf's JSON mapping with the proto field names and every field.
std::string ToJson(const google::protobuf::Message& message);

struct MealHostOptions {
  // Every meal's settings but its user and id.
  meals::MealOptions defaults;
  std::string journal_path = "bitewise-console.journal";
};

class MealHost : public meals::MealListener {
 public:
  MealHost(meals::ServiceClients* clients, MealHostOptions options);
  ~MealHost() override;

  // Delivers what an earlier run left in the journal.
  absl::StatusOr<int> DeliverJournal();
  // Starts a meal for `user_id` and looks at the plate. `meal_id` empty:
  // "meal-YYYYMMDD-HHMMSS". Returns the meal's state at once.
  absl::StatusOr<mealpb::MealState> StartMeal(const std::string& user_id,
                                              std::string meal_id);
  // Looks at the plate again (after a failure).
  absl::Status Look();
  // Starts a bite on `item_index` (the robot's choice when absent); it
  // runs on the worker, then the plate is looked at again.
  // FAILED_PRECONDITION when `plate_version` is given and is not the
  // plate's now, or when the plate has no look a bite may use
  // (MealState.plate_fresh).
  absl::Status Bite(std::optional<int> item_index,
                    std::optional<int> plate_version = std::nullopt);
  absl::Status Answer(const std::string& event_id, bool success);
  absl::Status EndMeal();
  // RobotService.Stop, with or without a meal.
  absl::StatusOr<v1::StopResponse> Stop();

  mealpb::MealState State() const;
  // The plate as JPEG bytes and its plate_version; NOT_FOUND before the
  // first look.
  absl::StatusOr<std::pair<int, std::string>> PlateJpeg();
  // Receives the current state now and every change after.
  std::shared_ptr<Subscription> Subscribe();
  // Ends every subscription (shutting down).
  void CloseSubscriptions();

  void OnEvent(const mealpb::BiteEvent& event,
               const mealpb::MealState& state) override;
  void OnNote(const std::string& note) override;

 private:
  // Runs `task` on the worker; FAILED_PRECONDITION if one is running.
  absl::Status Enqueue(std::function<void()> task)
      ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_);
  void WorkerLoop();
  void Broadcast(const std::string& frame);
  // Encodes the meal's plate as JPEG unless the cached one is of its
  // current plate_version.
  void UpdatePlateJpeg(const meals::Meal& meal);
  std::string RunningMealText() const ABSL_SHARED_LOCKS_REQUIRED(mu_);

  meals::ServiceClients* const clients_;
  const MealHostOptions options_;
  meals::UpdateJournal journal_;

  mutable absl::Mutex mu_;
  std::shared_ptr<meals::Meal> meal_ ABSL_GUARDED_BY(mu_);
  std::optional<std::function<void()>> task_ ABSL_GUARDED_BY(mu_);
  bool working_ ABSL_GUARDED_BY(mu_) = false;
  // Whether the running task has published a state yet (one that has not
  // is just starting, not ending).
  bool task_published_ ABSL_GUARDED_BY(mu_) = false;
  bool stopping_ ABSL_GUARDED_BY(mu_) = false;
  std::vector<std::shared_ptr<Subscription>> subscriptions_
      ABSL_GUARDED_BY(mu_);
  int jpeg_version_ ABSL_GUARDED_BY(mu_) = 0;
  const meals::Meal* jpeg_meal_ ABSL_GUARDED_BY(mu_) = nullptr;
  std::string jpeg_ ABSL_GUARDED_BY(mu_);
  std::thread worker_;
};

}  // namespace bitewise::console

#endif  // BITEWISE_CLIENTS_CONSOLE_MEAL_HOST_H_
