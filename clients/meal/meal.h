// Meal: one meal for one person, run bite by bite through the four services.
// This is the bite protocol as a library, shared by the CLI orchestrator and
// bitewise-console. Its explicit steps are:
//
//   LookAtPlate: capture (RobotService) and detect (PerceptionService);
//   Bite:        choose the item (the person's, or the robot's choice: the
//                most confident detection), featurize (and find or create
//                the person's model at the first bite), select
//                (BanditService), acquire with its progress (RobotService),
//                judge (the robot's verdict, or a question to the operator),
//                classify the force trace (HapticService), and learn
//                (BanditService.Update, or the journal when it cannot take
//                it);
//   Answer:      the operator's answer; it may change until the next bite
//                starts (or the meal finishes), and only then is it learned.
//
// Every step reports what happened as a BiteEvent and the whole meal as a
// MealState (bitewise/meal/v1/meal.proto) to a MealListener, which a UI shows.
//
// What a failure leaves behind:
//  - capture, detect, featurize or select fails: nothing is pending;
//  - acquire fails or STOP is pressed: the selected event stays pending in
//    the BanditService and nothing is learned from it;
//  - classify fails while post hoc context is on: nothing is learned, the
//    event stays pending (the post hoc learner cannot use a bite without
//    its haptic class);
//  - the fork felt no contact (Classify answers FAILED_PRECONDITION: the
//    force never held above the contact threshold): not a failure; the bite
//    is learned with no post hoc context (p = 0), from vision alone;
//  - the Update fails: the update goes to the journal and is delivered
//    later (the next answer, the next meal or the next run).
//
// Thread-safe: Bite and LookAtPlate run on one thread at a time (a second
// concurrent one is FAILED_PRECONDITION); Answer, Stop and state() may be
// called from other threads meanwhile. Listener calls are made without the
// meal's lock held, in order, from the thread that caused them.
#ifndef BITEWISE_CLIENTS_MEAL_MEAL_H_
#define BITEWISE_CLIENTS_MEAL_MEAL_H_

#include <cstdint>
#include <map>
#include <optional>
#include <string>

#include "absl/base/thread_annotations.h"
#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/synchronization/mutex.h"
#include "bitewise/meal/v1/meal.pb.h"
#include "clients/meal/service_clients.h"
#include "clients/meal/trace_recording.h"
#include "clients/meal/update_journal.h"
#include "services/domain/posthoc_context.h"

namespace bitewise::meals {

namespace mealpb = ::bitewise::meal::v1;

// What the bandit learns from the haptic class.
enum class PosthocMode {
  kLogProbabilities,  // the default: best in every measured cell
  kProbabilities,
  kNone,  // vision only; new users get the context-only learner
};

// Who decides whether the food came up.
enum class ConfirmBy { kRobot, kOperator };

struct MealOptions {
  std::string user_id = "demo-user";
  std::string meal_id = "meal-1";
  PosthocMode posthoc = PosthocMode::kLogProbabilities;
  // What a bite whose trace the HapticService calls unfamiliar sends as its
  // post hoc context (services/domain/posthoc_context.h; measured in
  // docs/experiments.md, "Unfamiliar traces"). A service without a
  // familiarity model never calls a trace unfamiliar.
  domain::UnfamiliarPosthoc unfamiliar_posthoc =
      domain::kDefaultUnfamiliarPosthoc;
  // What a bite sends whose descent the action's force limit stopped, so
  // that its trace is cut short (docs/experiments.md, "A trace the robot cut
  // short"); it takes precedence over unfamiliar_posthoc. Unset: the rule
  // measured for the person's learner (domain::DefaultLimitReachedPosthoc:
  // zero for poLinUCB, asis for post hoc LinUCB).
  std::optional<domain::UnfamiliarPosthoc> limit_reached_posthoc;
  // For a NEW user: LEARNER_UNSPECIFIED picks post hoc LinUCB, or the
  // context-only learner with PosthocMode::kNone (ParseLearner;
  // docs/experiments.md, "The learner default").
  v1::Learner learner = v1::LEARNER_UNSPECIFIED;
  ConfirmBy confirm = ConfirmBy::kRobot;
  // For a NEW user: lambda_c > 0 is used exactly; otherwise lambda_c =
  // rho_c * the featurizer's E||c||^2 when it reports one
  // (services/domain/context_ridge.h).
  double lambda_c = 0.0;
  double rho_c = 1.0;
  // For a NEW user: alpha < 0 keeps the BanditService's default;
  // prior_rounds > 0 starts from the facility's population pool.
  double alpha = -1.0;
  double prior_rounds = 0.0;
  // When set (it must outlive the meal), every Acquire's trace is recorded
  // with its bite for retraining HapticNet (trace_recording.h). A failed
  // recording is noted and never stops the meal.
  TraceRecording* recording = nullptr;
};

// Hears every step and every change of the meal.
class MealListener {
 public:
  virtual ~MealListener() = default;
  // `state` is the meal after the event.
  virtual void OnEvent(const mealpb::BiteEvent& event,
                       const mealpb::MealState& state) = 0;
  // A line for logs: the user found or created, the context ridge.
  virtual void OnNote(const std::string& note) {}
};

// "1 failure", "2 failures".
std::string Count(int n, const char* singular, const char* plural);

// A --learner flag's value: "" (by the post hoc mode: posthoc, or
// context_only with kNone), "posthoc",
// "context_only" or "polinucb". INVALID_ARGUMENT naming the choices, or
// when the learner needs a post hoc context and `posthoc` is kNone.
absl::StatusOr<v1::Learner> ParseLearner(const std::string& name,
                                         PosthocMode posthoc);

// "3 attempts, 1 failure".
std::string SummaryText(int attempts, int failures);

// The question to the operator, naming the food (or the item) and the
// action.
std::string OperatorQuestion(const mealpb::Bite& bite);

class Meal {
 public:
  // `clients`, `journal` and `listener` (may be null) must outlive the meal.
  Meal(ServiceClients* clients, UpdateJournal* journal, MealOptions options,
       MealListener* listener);

  // Delivers updates left in the journal (an earlier run, or an answer not
  // yet learned). Returns how many left the journal (learned, or refused
  // for good); updates the BanditService refuses for good (not
  // UNAVAILABLE, DEADLINE_EXCEEDED or RESOURCE_EXHAUSTED) are dropped with
  // a note. `why_not`, if given, gets the last delivery's error; `results`,
  // if given, each delivered event's answer from the BanditService (OK:
  // learned; a code that is not retried: dropped; a retried one: kept).
  absl::StatusOr<int> DeliverJournal(
      std::string* why_not = nullptr,
      std::map<std::string, absl::Status>* results = nullptr);

  // Captures the plate and detects the food on it. An empty plate ends the
  // meal (phase "ended"). Errors name the service and call. On the JACO2
  // the RobotService first moves the arm back to its viewing pose if a bite
  // left it elsewhere. `stops_when_asked`: stops() when the look was asked
  // for (a console queues it); a STOP since then refuses it before the
  // robot is asked (FAILED_PRECONDITION), as for Bite.
  absl::Status LookAtPlate(
      std::optional<uint64_t> stops_when_asked = std::nullopt);

  // Runs one bite on item `item_index` of the plate last looked at, or the
  // robot's choice when it is absent. INVALID_ARGUMENT for an index not on
  // the plate; FAILED_PRECONDITION before LookAtPlate, when the last look
  // failed or a bite has used it already (state().plate_fresh() is false:
  // every bite needs a look of its own), on an empty plate, after Finish or
  // while another bite runs. Other errors name the service
  // and call that failed; the bite then says what was kept (above).
  // `stops_when_asked`: stops() when the bite was asked for (a console
  // queues it); a STOP after that ends it before the arm moves. Without it,
  // a STOP from the start of this call on does.
  absl::Status Bite(std::optional<int> item_index,
                    std::optional<uint64_t> stops_when_asked = std::nullopt);

  // How many times Stop was called.
  uint64_t stops() const;

  // The operator's answer to the current bite's question (`event_id` names
  // it). Saved in the journal at once; learned when the next bite starts
  // or the meal finishes. NOT_FOUND for another event,
  // FAILED_PRECONDITION when no question is open.
  absl::Status Answer(const std::string& event_id, bool success);

  // The open answer becomes final now and is learned (or, unanswered, the
  // event stays pending); for a caller with no window for changing it.
  // Bite and Finish call it too.
  void ConfirmAnswer();

  // RobotService.Stop; a running Acquire ends as "stopped".
  absl::StatusOr<v1::StopResponse> Stop();

  // Ends the meal: the open answer (if any) becomes final and is learned.
  absl::Status Finish();

  mealpb::MealState state() const;

  // The frame of the plate last looked at (absent before the first look);
  // its items are state().items(), none after a failed look.
  std::optional<v1::Frame> plate_frame() const;

 private:
  // The bite's steps, in order; each reports its events.
  absl::StatusOr<int> ChooseItem(std::optional<int> item_index);
  // A look failed: no items are kept to aim a bite at.
  void ForgetPlate();
  absl::StatusOr<v1::FeaturizeResponse> Featurize(const v1::Frame& frame,
                                                  const v1::FoodItem& item);
  absl::Status EnsureUser(int context_dim, double context_msn);
  absl::StatusOr<v1::SelectResponse> Select(const v1::SelectRequest& request);
  // The RobotService's number for the action named `name` (ListActions,
  // asked once); FAILED_PRECONDITION naming the action and the robot's
  // actions when it has none of that name.
  absl::StatusOr<int> RobotActionNumber(const std::string& name);
  // Runs the action named `action` (the person's choice, by name) on `item`.
  absl::StatusOr<v1::AcquireResult> Acquire(const v1::FoodItem& item,
                                            const std::string& action);
  void Judge(const v1::AcquireResult& result);
  absl::Status Classify(const v1::AcquireResult& result);
  // What the person reads about how the bite felt; keeps HapticNet's
  // answer in `bite` and the post hoc context it gives in update_.
  // The rule for a trace the force limit cut short: the option, or the one
  // measured for the person's learner.
  domain::UnfamiliarPosthoc LimitReachedRule() const;
  // What a trace the force limit cut short sends under the zero rule: the
  // post hoc context its Select predicted (poLinUCB: measured better than
  // zeros on the world's traces, docs/experiments.md "A missing post hoc
  // context for poLinUCB"), or p = 0 for learners that predict none. A bite
  // with no contact sends p = 0 for every learner.
  std::vector<double> MissingPosthoc() const ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_);
  std::string Felt(const v1::ClassifyResponse& haptic, mealpb::Bite* bite)
      ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_);
  // Records the trace when options_.recording is set (`haptic` null when
  // the HapticService did not answer; `no_contact` when it answered that
  // the trace has no contact).
  void Record(const v1::AcquireResult& result,
              const v1::ClassifyResponse* haptic, bool no_contact);
  void Learn();

  void Emit(mealpb::Step step, mealpb::StepState state, std::string text,
            std::string error = "");
  void EmitProgress(const v1::AcquireProgress& progress);
  void Recount() ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_);
  absl::Status Fail(mealpb::Step step, const absl::Status& status,
                    const std::string& outcome, const std::string& kept);

  ServiceClients* const clients_;
  UpdateJournal* const journal_;
  const MealOptions options_;
  MealListener* const listener_;

  // Touched only by the thread running LookAtPlate or Bite.
  std::optional<v1::User> user_;
  // The robot's actions: name -> its wire number.
  std::map<std::string, int> robot_actions_;
  absl::Mutex busy_mu_;  // held through LookAtPlate and Bite

  mutable absl::Mutex mu_;
  std::optional<v1::Frame> frame_ ABSL_GUARDED_BY(mu_);
  mealpb::MealState state_ ABSL_GUARDED_BY(mu_);
  // The update of the current bite, once its loss is known (or while the
  // operator's answer is awaited: loss unset).
  std::optional<JournaledUpdate> update_ ABSL_GUARDED_BY(mu_);
  // The current bite's Select: the post hoc context the learner predicts
  // (poLinUCB; empty for other learners), sent when the bite has none.
  std::vector<double> predicted_posthoc_ ABSL_GUARDED_BY(mu_);
  bool stop_requested_ ABSL_GUARDED_BY(mu_) = false;
  uint64_t stops_ ABSL_GUARDED_BY(mu_) = 0;
};

}  // namespace bitewise::meals

#endif  // BITEWISE_CLIENTS_MEAL_MEAL_H_
