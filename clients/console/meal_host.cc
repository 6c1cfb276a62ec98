#include "clients/console/meal_host.h"

#include <google/protobuf/util/json_util.h>

#include <utility>

#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "opencv2/imgcodecs.hpp"
#include "opencv2/imgproc.hpp"
#include "services/domain/user_id.h"

namespace bitewise::console {
namespace {

// The frame's colour image as JPEG.
absl::StatusOr<std::string> EncodeJpeg(const v1::Frame& frame) {
  cv::Mat bgr;
  const auto* bytes =
      reinterpret_cast<const unsigned char*>(frame.rgb().data());
  if (frame.rgb_encoding() == v1::IMAGE_ENCODING_RGB8) {
    const size_t expected = size_t{frame.width()} * frame.height() * 3;
    if (frame.rgb().size() != expected || expected == 0) {
      return absl::DataLossError(
          absl::StrCat("the plate's frame has ", frame.rgb().size(),
                       " RGB bytes for ", frame.width(), "x", frame.height()));
    }
    const cv::Mat rgb(static_cast<int>(frame.height()),
                      static_cast<int>(frame.width()), CV_8UC3,
                      const_cast<unsigned char*>(bytes));
    cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
  } else {
    const std::vector<unsigned char> encoded(bytes, bytes + frame.rgb().size());
    bgr = cv::imdecode(encoded, cv::IMREAD_COLOR);
    if (bgr.empty()) {
      return absl::DataLossError("the plate's frame does not decode");
    }
  }
  std::vector<unsigned char> jpeg;
  if (!cv::imencode(".jpg", bgr, jpeg, {cv::IMWRITE_JPEG_QUALITY, 85})) {
    return absl::InternalError("JPEG encoding of the plate failed");
  }
  return std::string(jpeg.begin(), jpeg.end());
}

std::string SseFrame(const char* event, const std::string& data) {
  return absl::StrCat("event: ", event, "\ndata: ", data, "\n\n");
}

}  // namespace

std::string ToJson(const google::protobuf::Message& message) {
  google::protobuf::util::JsonPrintOptions options;
  options.preserve_proto_field_names = true;
  options.always_print_primitive_fields = true;
  std::string out;
  // Only fails for Any types with unknown type URLs, which we do not use.
  (void)google::protobuf::util::MessageToJsonString(message, &out, options);
  return out;
}

std::optional<std::string> Subscription::Next(absl::Duration timeout) {
  absl::MutexLock lock(&mu_);
  auto ready = [this]() ABSL_SHARED_LOCKS_REQUIRED(mu_) {
    return closed_ || !frames_.empty();
  };
  mu_.AwaitWithTimeout(absl::Condition(&ready), timeout);
  if (closed_ || frames_.empty()) return std::nullopt;
  std::string frame = std::move(frames_.front());
  frames_.pop_front();
  return frame;
}

void Subscription::Push(std::string frame) {
  absl::MutexLock lock(&mu_);
  if (closed_) return;
  if (frames_.size() >= kMaxQueued) {
    closed_ = true;
    frames_.clear();
    return;
  }
  frames_.push_back(std::move(frame));
}

void Subscription::Close() {
  absl::MutexLock lock(&mu_);
  closed_ = true;
}

bool Subscription::closed() const {
  absl::MutexLock lock(&mu_);
  return closed_;
}

MealHost::MealHost(meals::ServiceClients* clients, MealHostOptions options)
    : clients_(clients),
      options_(std::move(options)),
      journal_(options_.journal_path),
      worker_([this] { WorkerLoop(); }) {}

MealHost::~MealHost() {
  CloseSubscriptions();
  {
    absl::MutexLock lock(&mu_);
    stopping_ = true;
  }
  worker_.join();
}

void MealHost::WorkerLoop() {
  while (true) {
    std::function<void()> task;
    {
      absl::MutexLock lock(&mu_);
      auto ready = [this]() ABSL_SHARED_LOCKS_REQUIRED(mu_) {
        return stopping_ || task_.has_value();
      };
      mu_.Await(absl::Condition(&ready));
      if (!task_.has_value()) return;  // stopping with nothing to do
      task = std::move(*task_);
      task_.reset();
      working_ = true;
      task_published_ = false;
    }
    task();
    absl::MutexLock lock(&mu_);
    working_ = false;
  }
}

absl::Status MealHost::Enqueue(std::function<void()> task) {
  // A task ends a moment after the state it leaves is published (a browser
  // may tap as soon as it sees the plate), so that moment is waited out.
  // While a bite or a look is under way, or a task is queued or has just
  // started (it has published nothing yet, so the phase shown is the one
  // before it), the answer is "busy" at once.
  const std::string phase = meal_ != nullptr ? meal_->state().phase() : "";
  const bool just_started = working_ && !task_published_;
  if (!task_.has_value() && !just_started && phase != "biting" &&
      phase != "looking") {
    auto idle = [this]() ABSL_SHARED_LOCKS_REQUIRED(mu_) {
      return !working_ && !task_.has_value();
    };
    mu_.AwaitWithTimeout(absl::Condition(&idle), absl::Seconds(2));
  }
  if (working_ || task_.has_value()) {
    return absl::FailedPreconditionError(
        "the robot is busy with this meal: wait for the bite to end, or "
        "press STOP");
  }
  task_ = std::move(task);
  return absl::OkStatus();
}

std::string MealHost::RunningMealText() const {
  const mealpb::MealState state = meal_->state();
  return absl::StrCat("meal ", state.meal_id(), " for ", state.user_id());
}

absl::StatusOr<int> MealHost::DeliverJournal() {
  // The journal is only ever delivered by a meal; a meal object with no
  // bite does just that.
  meals::Meal delivery(clients_, &journal_, options_.defaults, nullptr);
  return delivery.DeliverJournal();
}

absl::StatusOr<mealpb::MealState> MealHost::StartMeal(
    const std::string& user_id, std::string meal_id) {
  if (absl::Status valid = domain::ValidateUserId(user_id); !valid.ok()) {
    return valid;
  }
  if (meal_id.empty()) {
    meal_id = absl::StrCat(
        "meal-",
        absl::FormatTime("%Y%m%d-%H%M%S", absl::Now(), absl::LocalTimeZone()));
  }
  if (absl::Status valid = domain::ValidateId("meal_id", meal_id);
      !valid.ok()) {
    return valid;
  }
  std::shared_ptr<meals::Meal> meal;
  {
    absl::MutexLock lock(&mu_);
    if (meal_ != nullptr && meal_->state().running()) {
      return absl::FailedPreconditionError(absl::StrCat(
          RunningMealText(), " is running on this robot; end it first"));
    }
    meals::MealOptions options = options_.defaults;
    options.user_id = user_id;
    options.meal_id = meal_id;
    meal = std::make_shared<meals::Meal>(clients_, &journal_, options, this);
    absl::Status queued = Enqueue([this, meal] {
      const absl::StatusOr<int> delivered = meal->DeliverJournal();
      if (delivered.ok() && *delivered > 0) {
        OnNote(absl::StrCat("journal: delivered ", *delivered,
                            " update(s) left from before"));
      }
      // A failure is in the meal's state. A STOP from the meal's start on
      // (its count starts at 0) cancels this first look.
      (void)meal->LookAtPlate(uint64_t{0});
    });
    if (!queued.ok()) return queued;
    meal_ = meal;
  }
  const mealpb::MealState state = meal->state();
  Broadcast(SseFrame("state", ToJson(state)));
  return state;
}

absl::Status MealHost::Look() {
  absl::MutexLock lock(&mu_);
  if (meal_ == nullptr || !meal_->state().running()) {
    return absl::FailedPreconditionError("no meal is running");
  }
  std::shared_ptr<meals::Meal> meal = meal_;
  // A STOP from now on, while the look waits in the queue, cancels it: the
  // look may move the arm.
  const uint64_t stops = meal->stops();
  return Enqueue([meal, stops] { (void)meal->LookAtPlate(stops); });
}

absl::Status MealHost::Bite(std::optional<int> item_index,
                            std::optional<int> plate_version) {
  absl::MutexLock lock(&mu_);
  if (meal_ == nullptr || !meal_->state().running()) {
    return absl::FailedPreconditionError(
        "no meal is running: choose a person and start one");
  }
  const mealpb::MealState state = meal_->state();
  if (plate_version.has_value() && *plate_version != state.plate_version()) {
    return absl::FailedPreconditionError(
        absl::StrCat("the plate was looked at again since this choice (look ",
                     *plate_version, ", now ", state.plate_version(),
                     "): its items may be numbered differently; choose again"));
  }
  if (!state.plate_fresh()) {
    return absl::FailedPreconditionError(
        state.items_size() == 0
            ? "the last look at the plate failed: look at the plate again"
            : "the plate has not been looked at since the last bite: look "
              "at the plate again");
  }
  if (item_index.has_value() &&
      (*item_index < 0 || *item_index >= state.items_size())) {
    return absl::InvalidArgumentError(
        absl::StrCat("item_index ", *item_index, " is not on the plate (",
                     meals::Count(state.items_size(), "item", "items"), ")"));
  }
  std::shared_ptr<meals::Meal> meal = meal_;
  // A STOP from now on, while the bite waits in the queue, ends it before
  // the arm moves.
  const uint64_t stops = meal->stops();
  return Enqueue([meal, item_index, stops] {
    // A failure is in the meal's state. Only a bite that went well is
    // followed by a look: the look may move the arm back to its viewing
    // pose, which must not follow a STOP, a collision or a sensor fault by
    // itself ("Look at the plate again" asks for it).
    const absl::Status bitten = meal->Bite(item_index, stops);
    if (bitten.ok() && meal->state().running()) {
      (void)meal->LookAtPlate(stops);
    }
  });
}

absl::Status MealHost::Answer(const std::string& event_id, bool success) {
  std::shared_ptr<meals::Meal> meal;
  {
    absl::MutexLock lock(&mu_);
    meal = meal_;
  }
  if (meal == nullptr) {
    return absl::FailedPreconditionError("no meal is running");
  }
  return meal->Answer(event_id, success);
}

absl::Status MealHost::EndMeal() {
  absl::MutexLock lock(&mu_);
  if (meal_ == nullptr || !meal_->state().running()) {
    return absl::FailedPreconditionError("no meal is running");
  }
  std::shared_ptr<meals::Meal> meal = meal_;
  return Enqueue([meal] { (void)meal->Finish(); });
}

absl::StatusOr<v1::StopResponse> MealHost::Stop() {
  std::shared_ptr<meals::Meal> meal;
  {
    absl::MutexLock lock(&mu_);
    meal = meal_;
  }
  if (meal != nullptr) return meal->Stop();
  return clients_->robot.Stop();
}

mealpb::MealState MealHost::State() const {
  std::shared_ptr<meals::Meal> meal;
  {
    absl::MutexLock lock(&mu_);
    meal = meal_;
  }
  if (meal != nullptr) return meal->state();
  mealpb::MealState idle;
  idle.set_phase("idle");
  idle.set_message("No meal is running.");
  return idle;
}

absl::StatusOr<std::pair<int, std::string>> MealHost::PlateJpeg() {
  std::shared_ptr<meals::Meal> meal;
  {
    absl::MutexLock lock(&mu_);
    meal = meal_;
  }
  if (meal != nullptr) UpdatePlateJpeg(*meal);
  absl::MutexLock lock(&mu_);
  if (jpeg_.empty()) {
    return absl::NotFoundError("the camera has not looked at a plate yet");
  }
  return std::make_pair(jpeg_version_, jpeg_);
}

void MealHost::UpdatePlateJpeg(const meals::Meal& meal) {
  const int version = meal.state().plate_version();
  {
    absl::MutexLock lock(&mu_);
    if (version == 0 || (version == jpeg_version_ && &meal == jpeg_meal_)) {
      return;
    }
  }
  const std::optional<v1::Frame> frame = meal.plate_frame();
  if (!frame.has_value()) return;
  absl::StatusOr<std::string> jpeg = EncodeJpeg(*frame);
  absl::MutexLock lock(&mu_);
  jpeg_version_ = version;
  jpeg_meal_ = &meal;
  jpeg_ = jpeg.ok() ? *std::move(jpeg) : std::string();
}

std::shared_ptr<Subscription> MealHost::Subscribe() {
  auto subscription = std::make_shared<Subscription>();
  subscription->Push(SseFrame("state", ToJson(State())));
  absl::MutexLock lock(&mu_);
  subscriptions_.push_back(subscription);
  return subscription;
}

void MealHost::CloseSubscriptions() {
  absl::MutexLock lock(&mu_);
  for (const auto& subscription : subscriptions_) subscription->Close();
  subscriptions_.clear();
}

void MealHost::Broadcast(const std::string& frame) {
  absl::MutexLock lock(&mu_);
  std::vector<std::shared_ptr<Subscription>> open;
  for (auto& subscription : subscriptions_) {
    subscription->Push(frame);
    if (!subscription->closed()) open.push_back(std::move(subscription));
  }
  subscriptions_ = std::move(open);
}

void MealHost::OnEvent(const mealpb::BiteEvent& event,
                       const mealpb::MealState& state) {
  if (event.state() == mealpb::STEP_STATE_PROGRESS) {
    Broadcast(SseFrame("progress", ToJson(event)));
    return;
  }
  std::shared_ptr<meals::Meal> meal;
  {
    absl::MutexLock lock(&mu_);
    meal = meal_;
    if (working_) task_published_ = true;
  }
  // Encoded before the state goes out, so a browser that fetches the
  // picture on seeing a new plate_version finds it.
  if (meal != nullptr) UpdatePlateJpeg(*meal);
  Broadcast(SseFrame("state", ToJson(state)));
}

void MealHost::OnNote(const std::string& note) {
  std::fprintf(stderr, "%s\n", note.c_str());
}

}  // namespace bitewise::console
