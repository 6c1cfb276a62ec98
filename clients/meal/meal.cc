#include "clients/meal/meal.h"

#include <algorithm>
#include <utility>
#include <vector>

#include "absl/strings/ascii.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "absl/strings/strip.h"
#include "absl/time/clock.h"
#include "services/domain/context_ridge.h"
#include "services/domain/haptic_class.h"
#include "services/domain/skewering_actions.h"

namespace bitewise::meals {
namespace {

// The API's haptic category (0 is unspecified) for people.
const char* HapticLabel(v1::HapticCategory category) {
  const int index = static_cast<int>(category) - 1;
  if (index < 0 || index >= domain::kHapticClasses) return "unknown";
  return domain::HapticClassLabel(static_cast<domain::HapticClass>(index));
}

// The bandit's choice (its index among the person's actions, and the
// action's name) for people: the title and description of the skewering
// action of that name.
mealpb::ActionInfo DescribeAction(int index, const std::string& name) {
  mealpb::ActionInfo info;
  info.set_index(index);
  info.set_name(name);
  if (const domain::SkeweringAction* action =
          domain::FindSkeweringAction(name)) {
    info.set_title(action->title);
    info.set_description(action->description);
    info.set_max_force_n(action->max_force_n);
  }
  return info;
}

// "acquire" phases for people: "descend".
std::string PhaseWord(v1::AcquirePhase phase) {
  std::string name = v1::AcquirePhase_Name(phase);
  return absl::AsciiStrToLower(name.substr(name.rfind('_') + 1));
}

// The food as people read it: its name when known, else where it lay.
std::string FoodOf(const mealpb::Bite& bite) {
  if (!bite.food().empty()) return bite.food();
  return absl::StrCat("item ", bite.item_index() + 1);
}

// Holds the meal's busy lock, taken with TryLock, until the scope ends.
class BusyGuard {
 public:
  explicit BusyGuard(absl::Mutex* mu) : mu_(mu) {}
  ~BusyGuard() { mu_->Unlock(); }
  BusyGuard(const BusyGuard&) = delete;
  BusyGuard& operator=(const BusyGuard&) = delete;

 private:
  absl::Mutex* mu_;
};

// Worth journaling and sending again later: the service or its store is
// down or full (a store that refuses writes answers UNAVAILABLE or
// RESOURCE_EXHAUSTED until it takes them again).
bool Retryable(const absl::Status& status) {
  return absl::IsUnavailable(status) || absl::IsDeadlineExceeded(status) ||
         absl::IsResourceExhausted(status);
}

}  // namespace

absl::StatusOr<v1::Learner> ParseLearner(const std::string& name,
                                         PosthocMode posthoc) {
  if (name.empty()) return v1::LEARNER_UNSPECIFIED;
  v1::Learner learner = v1::LEARNER_UNSPECIFIED;
  if (!v1::Learner_Parse(absl::AsciiStrToUpper("LEARNER_" + name), &learner) ||
      learner == v1::LEARNER_UNSPECIFIED) {
    // The names the API knows, from its enum.
    std::vector<std::string> known;
    const google::protobuf::EnumDescriptor* learners = v1::Learner_descriptor();
    for (int i = 0; i < learners->value_count(); ++i) {
      if (learners->value(i)->number() == v1::LEARNER_UNSPECIFIED) continue;
      known.push_back(absl::AsciiStrToLower(
          absl::StripPrefix(learners->value(i)->name(), "LEARNER_")));
    }
    return absl::InvalidArgumentError(
        absl::StrCat("--learner: expected one of ", absl::StrJoin(known, ", "),
                     ", got ", name));
  }
  if (learner != v1::LEARNER_CONTEXT_ONLY && posthoc == PosthocMode::kNone) {
    return absl::InvalidArgumentError(absl::StrCat(
        "--learner=", name,
        " learns from the haptic class: use --posthoc=logprob or prob"));
  }
  return learner;
}

std::string Count(int n, const char* singular, const char* plural) {
  return absl::StrCat(n, " ", n == 1 ? singular : plural);
}

std::string SummaryText(int attempts, int failures) {
  return absl::StrCat(Count(attempts, "attempt", "attempts"), ", ",
                      Count(failures, "failure", "failures"));
}

std::string OperatorQuestion(const mealpb::Bite& bite) {
  const std::string food = bite.food().empty()
                               ? absl::StrCat("item ", bite.item_index() + 1)
                               : absl::StrCat("the ", bite.food());
  // The bite's number first, so the answer is given knowing which bite.
  const std::string which = bite.number() > 0
                                ? absl::StrCat("Bite ", bite.number(), ": did ")
                                : std::string("Did ");
  return absl::StrFormat("%s%s come up on the fork with %s (%s)?", which, food,
                         bite.action().name(), bite.action().title());
}

Meal::Meal(ServiceClients* clients, UpdateJournal* journal, MealOptions options,
           MealListener* listener)
    : clients_(clients),
      journal_(journal),
      options_(std::move(options)),
      listener_(listener) {
  state_.set_running(true);
  state_.set_meal_id(options_.meal_id);
  state_.set_user_id(options_.user_id);
  state_.set_phase("idle");
  state_.mutable_summary()->set_text(SummaryText(0, 0));
}

mealpb::MealState Meal::state() const {
  absl::MutexLock lock(&mu_);
  return state_;
}

void Meal::ForgetPlate() {
  absl::MutexLock lock(&mu_);
  state_.clear_items();
}

std::optional<v1::Frame> Meal::plate_frame() const {
  absl::MutexLock lock(&mu_);
  return frame_;
}

absl::StatusOr<int> Meal::DeliverJournal(
    std::string* why_not, std::map<std::string, absl::Status>* results) {
  return journal_->Drain([&](const JournaledUpdate& update) -> absl::Status {
    v1::UpdateRequest request;
    request.set_event_id(update.event_id);
    request.set_loss(update.loss);
    request.mutable_posthoc()->Add(update.posthoc.begin(),
                                   update.posthoc.end());
    const absl::StatusOr<v1::UpdateResponse> sent =
        clients_->bandit.Update(request);
    if (!sent.ok() && why_not != nullptr) {
      *why_not = std::string(sent.status().message());
    }
    if (results != nullptr) (*results)[update.event_id] = sent.status();
    if (sent.ok() || Retryable(sent.status())) return sent.status();
    if (listener_ != nullptr) {
      listener_->OnNote(absl::StrCat("journal: dropping the update of event ",
                                     update.event_id, ": ",
                                     sent.status().message()));
    }
    return absl::OkStatus();
  });
}

void Meal::Emit(mealpb::Step step, mealpb::StepState step_state,
                std::string text, std::string error) {
  mealpb::BiteEvent event;
  mealpb::MealState snapshot;
  {
    absl::MutexLock lock(&mu_);
    event.set_bite(state_.bite());
    event.set_step(step);
    event.set_state(step_state);
    event.set_text(std::move(text));
    event.set_error(std::move(error));
    event.set_wall_time_s(
        absl::ToDoubleSeconds(absl::Now() - absl::UnixEpoch()));
    const bool in_bite = step > mealpb::STEP_DETECT &&
                         state_.bites_size() > 0 &&
                         state_.bites().rbegin()->number() == state_.bite();
    if (in_bite) {
      mealpb::Bite* bite = state_.mutable_bites(state_.bites_size() - 1);
      *bite->add_steps() = event;
      *state_.mutable_current() = *bite;
    }
    state_.set_message(event.text());
    snapshot = state_;
  }
  if (listener_ != nullptr) listener_->OnEvent(event, snapshot);
}

void Meal::EmitProgress(const v1::AcquireProgress& progress) {
  mealpb::BiteEvent event;
  mealpb::MealState snapshot;
  {
    absl::MutexLock lock(&mu_);
    event.set_bite(state_.bite());
    event.set_step(mealpb::STEP_ACQUIRE);
    event.set_state(mealpb::STEP_STATE_PROGRESS);
    event.set_phase(progress.phase());
    event.set_elapsed_s(progress.elapsed_s());
    event.set_force_n(progress.force_n());
    event.set_wall_time_s(
        absl::ToDoubleSeconds(absl::Now() - absl::UnixEpoch()));
    if (state_.bites_size() == 0) return;
    mealpb::Bite* bite = state_.mutable_bites(state_.bites_size() - 1);
    if (bite->phase() != progress.phase()) {
      event.set_text(
          absl::StrCat("The arm is in ", PhaseWord(progress.phase()), "."));
      state_.set_message(event.text());
    }
    bite->set_phase(progress.phase());
    bite->set_force_n(progress.force_n());
    mealpb::ForceSample* sample = bite->add_forces();
    sample->set_t(progress.elapsed_s());
    sample->set_f(progress.force_n());
    *state_.mutable_current() = *bite;
    snapshot = state_;
  }
  if (listener_ != nullptr) listener_->OnEvent(event, snapshot);
}

void Meal::Recount() {
  int attempts = 0;
  int failures = 0;
  std::vector<mealpb::FoodTally> foods;
  for (const mealpb::Bite& bite : state_.bites()) {
    const bool failed = bite.outcome() == "failure";
    if (!failed && bite.outcome() != "success") continue;
    ++attempts;
    failures += failed ? 1 : 0;
    const std::string food = bite.food().empty() ? "unknown" : bite.food();
    auto it = std::find_if(
        foods.begin(), foods.end(),
        [&](const mealpb::FoodTally& tally) { return tally.food() == food; });
    if (it == foods.end()) {
      foods.emplace_back();
      it = foods.end() - 1;
      it->set_food(food);
    }
    it->set_attempts(it->attempts() + 1);
    it->set_failures(it->failures() + (failed ? 1 : 0));
  }
  std::sort(foods.begin(), foods.end(),
            [](const mealpb::FoodTally& a, const mealpb::FoodTally& b) {
              return a.food() < b.food();
            });
  mealpb::MealSummary* summary = state_.mutable_summary();
  summary->set_attempts(attempts);
  summary->set_failures(failures);
  summary->set_text(SummaryText(attempts, failures));
  summary->clear_foods();
  for (mealpb::FoodTally& tally : foods) *summary->add_foods() = tally;
}

absl::Status Meal::Fail(mealpb::Step step, const absl::Status& status,
                        const std::string& outcome, const std::string& kept) {
  std::string text;
  {
    absl::MutexLock lock(&mu_);
    text = absl::StrCat(status.message(), kept.empty() ? "" : "; ", kept);
    state_.set_phase("failed");
    state_.set_error(std::string(status.message()));
    const bool in_bite = step > mealpb::STEP_DETECT &&
                         state_.bites_size() > 0 &&
                         state_.bites().rbegin()->number() == state_.bite();
    if (in_bite) {
      mealpb::Bite* bite = state_.mutable_bites(state_.bites_size() - 1);
      bite->set_outcome(outcome);
      bite->set_error(std::string(status.message()));
      bite->set_text(text);
      bite->clear_question();
      if (bite->learned() == "pending" ||
          bite->learned() == "awaiting answer") {
        bite->set_learned("not learned");
      }
      update_.reset();
      Recount();
    }
  }
  Emit(step, mealpb::STEP_STATE_FAILED, text, std::string(status.message()));
  return status;
}

absl::Status Meal::LookAtPlate(std::optional<uint64_t> stops_when_asked) {
  if (!busy_mu_.TryLock()) {
    return absl::FailedPreconditionError(
        "a bite or a look at the plate is already running");
  }
  BusyGuard busy(&busy_mu_);
  bool stopped_since = false;
  {
    absl::MutexLock lock(&mu_);
    if (!state_.running()) {
      return absl::FailedPreconditionError(
          absl::StrCat("meal ", state_.meal_id(), " is over"));
    }
    stopped_since = stops_when_asked.has_value() && stops_ > *stops_when_asked;
  }
  if (stopped_since) {
    // The look may move the arm (back to its viewing pose): not after a
    // STOP the person pressed since asking. Said as a failed look, so the
    // page offers to look again.
    return Fail(mealpb::STEP_CAPTURE,
                absl::FailedPreconditionError(
                    "STOP was pressed after this look at the plate was asked "
                    "for; nothing was moved: look again when ready"),
                "", "nothing was moved");
  }
  {
    absl::MutexLock lock(&mu_);
    state_.set_phase("looking");
    state_.clear_error();
    state_.set_plate_fresh(false);
  }
  Emit(mealpb::STEP_CAPTURE, mealpb::STEP_STATE_STARTED,
       "Looking at the plate (the arm first goes back to where it looks "
       "from, if a bite left it elsewhere).");
  absl::StatusOr<v1::Frame> frame = clients_->robot.CaptureFrame();
  if (!frame.ok()) {
    ForgetPlate();
    return Fail(mealpb::STEP_CAPTURE, frame.status(), "", "no bite was tried");
  }
  Emit(mealpb::STEP_CAPTURE, mealpb::STEP_STATE_DONE,
       "The camera saw the plate.");
  Emit(mealpb::STEP_DETECT, mealpb::STEP_STATE_STARTED, "Finding the food.");
  absl::StatusOr<v1::DetectFoodResponse> detected =
      clients_->perception.DetectFood(*frame);
  if (!detected.ok()) {
    ForgetPlate();
    return Fail(mealpb::STEP_DETECT, detected.status(), "",
                "no bite was tried");
  }
  std::string text;
  {
    absl::MutexLock lock(&mu_);
    state_.set_plate_version(state_.plate_version() + 1);
    state_.set_frame_width(static_cast<int>(frame->width()));
    state_.set_frame_height(static_cast<int>(frame->height()));
    frame_ = *std::move(frame);
    *state_.mutable_items() = detected->items();
    if (detected->items_size() == 0) {
      state_.set_phase("ended");
      state_.set_running(false);
      text = absl::StrCat("The plate is empty. ", state_.summary().text(), ".");
    } else {
      state_.set_phase("choosing");
      state_.set_plate_fresh(true);
      text = absl::StrCat(
          Count(detected->items_size(), "item", "items"),
          " on the plate: choose the next bite, or let the robot choose.");
    }
  }
  Emit(mealpb::STEP_DETECT, mealpb::STEP_STATE_DONE, text);
  return absl::OkStatus();
}

absl::StatusOr<int> Meal::ChooseItem(std::optional<int> item_index) {
  absl::MutexLock lock(&mu_);
  const int count = state_.items_size();
  if (count == 0) {
    return absl::FailedPreconditionError("the plate is empty: nothing to eat");
  }
  if (item_index.has_value()) {
    if (*item_index < 0 || *item_index >= count) {
      return absl::InvalidArgumentError(absl::StrCat(
          "item_index ", *item_index, " is not on the plate (",
          Count(count, "item", "items"), ": 0 to ", count - 1, ")"));
    }
    return *item_index;
  }
  // The robot's choice: the most confident detection.
  const auto& items = state_.items();
  return static_cast<int>(
      std::max_element(items.begin(), items.end(),
                       [](const v1::FoodItem& a, const v1::FoodItem& b) {
                         return a.score() < b.score();
                       }) -
      items.begin());
}

absl::Status Meal::Bite(std::optional<int> item_index,
                        std::optional<uint64_t> stops_when_asked) {
  if (!busy_mu_.TryLock()) {
    return absl::FailedPreconditionError("a bite is already running");
  }
  BusyGuard busy(&busy_mu_);
  {
    absl::MutexLock lock(&mu_);
    if (!state_.running()) {
      return absl::FailedPreconditionError(
          absl::StrCat("meal ", state_.meal_id(), " is over"));
    }
    // A STOP pressed before this bite was asked for does not cancel it (as
    // the robot treats a Stop while idle); one pressed since does, until
    // the arm is back (Acquire below).
    stop_requested_ =
        stops_when_asked.has_value() && stops_ > *stops_when_asked;
    if (!stop_requested_) state_.set_stopped(false);
  }
  std::optional<v1::Frame> frame = plate_frame();
  if (!frame.has_value()) {
    return absl::FailedPreconditionError(
        "look at the plate before the first bite");
  }
  {
    // The items of a look are aimed at by one bite: that bite may have taken
    // or moved them, and a failed look leaves none.
    absl::MutexLock lock(&mu_);
    if (!state_.plate_fresh()) {
      return absl::FailedPreconditionError(
          state_.items_size() == 0
              ? std::string("the last look at the plate failed: look at the "
                            "plate again before a bite")
              : absl::StrCat("look at the plate again before a bite: the "
                             "items shown were seen before bite ",
                             state_.bite(),
                             ", which may have taken or moved "
                             "them"));
    }
  }
  absl::StatusOr<int> chosen_index = ChooseItem(item_index);
  if (!chosen_index.ok()) return chosen_index.status();
  // The previous bite's answer is final now.
  ConfirmAnswer();
  // Updates journaled while the BanditService or its store was down go
  // first, once it takes them again (an empty journal costs one read).
  if (absl::StatusOr<int> delivered = DeliverJournal();
      delivered.ok() && *delivered > 0 && listener_ != nullptr) {
    listener_->OnNote(absl::StrCat("journal: delivered ", *delivered,
                                   " update(s) saved earlier"));
  }

  v1::FoodItem item;
  {
    absl::MutexLock lock(&mu_);
    item = state_.items(*chosen_index);
    state_.set_bite(state_.bite() + 1);
    state_.set_phase("biting");
    state_.set_plate_fresh(false);
    state_.clear_error();
    update_.reset();
    // Earlier bites keep their outcome, not their force samples and steps,
    // so the state a UI is sent stays small through a long meal.
    for (mealpb::Bite& earlier : *state_.mutable_bites()) {
      earlier.clear_forces();
      earlier.clear_steps();
    }
    mealpb::Bite* bite = state_.add_bites();
    bite->set_number(state_.bite());
    bite->set_item_index(*chosen_index);
    bite->set_robots_choice(!item_index.has_value());
    bite->set_item_label(absl::StrFormat("item@%.0f,%.0f", item.center_px().u(),
                                         item.center_px().v()));
    bite->set_outcome("pending");
    bite->set_learned("pending");
  }
  Emit(mealpb::STEP_CHOOSE, mealpb::STEP_STATE_DONE,
       item_index.has_value()
           ? absl::StrCat("Item ", *chosen_index + 1, " is next.")
           : absl::StrCat("The robot chose item ", *chosen_index + 1, "."));

  absl::StatusOr<v1::FeaturizeResponse> features = Featurize(*frame, item);
  if (!features.ok()) return features.status();

  v1::SelectRequest select;
  {
    absl::MutexLock lock(&mu_);
    select.set_user_id(options_.user_id);
    select.set_meal_id(options_.meal_id);
    select.set_item_label(state_.bites().rbegin()->item_label());
  }
  *select.mutable_context() = features->context();
  absl::StatusOr<v1::SelectResponse> chosen = Select(select);
  if (!chosen.ok()) return chosen.status();

  absl::StatusOr<v1::AcquireResult> result =
      Acquire(item, chosen->action_name());
  if (!result.ok()) return result.status();
  Judge(*result);
  absl::Status classified = Classify(*result);
  if (!classified.ok()) return classified;
  Learn();
  return absl::OkStatus();
}

absl::StatusOr<v1::FeaturizeResponse> Meal::Featurize(
    const v1::Frame& frame, const v1::FoodItem& item) {
  Emit(mealpb::STEP_FEATURIZE, mealpb::STEP_STATE_STARTED,
       "Looking closely at the item.");
  absl::StatusOr<v1::FeaturizeResponse> features =
      clients_->perception.Featurize(frame, item.bbox());
  if (!features.ok()) {
    Fail(mealpb::STEP_FEATURIZE, features.status(), "error",
         "nothing was selected; nothing is pending")
        .IgnoreError();
    return features.status();
  }
  if (!user_.has_value()) {
    absl::Status ready = EnsureUser(features->context_size(),
                                    features->context_mean_squared_norm());
    if (!ready.ok()) {
      Fail(mealpb::STEP_FEATURIZE, ready, "error",
           "nothing was selected; nothing is pending")
          .IgnoreError();
      return ready;
    }
  }
  Emit(mealpb::STEP_FEATURIZE, mealpb::STEP_STATE_DONE,
       absl::StrCat("Described the item with ", features->context_size(),
                    " numbers (", features->featurizer(), ")."));
  return features;
}

absl::Status Meal::EnsureUser(int context_dim, double context_msn) {
  absl::StatusOr<v1::User> user = clients_->bandit.GetUser(options_.user_id);
  if (user.ok()) {
    if (static_cast<int>(user->config().context_dim()) != context_dim) {
      return absl::FailedPreconditionError(absl::StrFormat(
          "%s learns from %u context values but the featurizer gives %d; use "
          "another person or the featurizer %s started with",
          options_.user_id, user->config().context_dim(), context_dim,
          options_.user_id));
    }
    if (listener_ != nullptr) {
      listener_->OnNote(absl::StrFormat(
          "user %s continues from model version %lld (%s)", options_.user_id,
          static_cast<long long>(user->model_version()),
          v1::Learner_Name(user->config().learner())));
    }
    user_ = *std::move(user);
    return absl::OkStatus();
  }
  if (!absl::IsNotFound(user.status())) return user.status();
  v1::CreateUserRequest create;
  create.set_user_id(options_.user_id);
  v1::UserConfig* config = create.mutable_config();
  config->set_context_dim(context_dim);
  // Post hoc LinUCB by default: it failed less than poLinUCB on every
  // trace story the HapticNet of the time (two stories) never saw and at
  // most 1.0 more on the world's own
  // with the force limits, the rule fixed before its runs
  // (docs/experiments.md, "The learner default").
  config->set_learner(
      options_.learner != v1::LEARNER_UNSPECIFIED ? options_.learner
      : options_.posthoc == PosthocMode::kNone    ? v1::LEARNER_CONTEXT_ONLY
                                                  : v1::LEARNER_POSTHOC);
  const double lambda_c = domain::NewUserContextRidge(
      options_.lambda_c, options_.rho_c, context_msn);
  if (lambda_c > 0.0) config->set_lambda_c(lambda_c);
  if (listener_ != nullptr) {
    listener_->OnNote(
        options_.lambda_c > 0.0
            ? absl::StrFormat("context ridge lambda_c = %.4g (given)", lambda_c)
        : lambda_c > 0.0
            ? absl::StrFormat("context ridge lambda_c = %.4g (rho_c %.3g x "
                              "E||c||^2 %.4g of the featurizer on seen foods)",
                              lambda_c, options_.rho_c, context_msn)
            : std::string("the featurizer reports no E||c||^2: the "
                          "BanditService's default lambda_c applies"));
  }
  if (options_.alpha >= 0.0) config->set_alpha(options_.alpha);
  if (options_.prior_rounds > 0.0) {
    config->set_prior_rounds(options_.prior_rounds);
  }
  absl::StatusOr<v1::User> created = clients_->bandit.CreateUser(create);
  if (!created.ok()) return created.status();
  if (listener_ != nullptr) {
    listener_->OnNote(absl::StrFormat(
        "new user %s (%s, context dim %u%s)", options_.user_id,
        v1::Learner_Name(created->config().learner()),
        created->config().context_dim(),
        created->config().prior_pool_version() > 0
            ? absl::StrFormat(", population prior from pool %d worth %g rounds",
                              created->config().prior_pool_version(),
                              created->config().prior_rounds())
            : ""));
  }
  user_ = *std::move(created);
  return absl::OkStatus();
}

absl::StatusOr<v1::SelectResponse> Meal::Select(
    const v1::SelectRequest& request) {
  Emit(mealpb::STEP_SELECT, mealpb::STEP_STATE_STARTED,
       "Choosing how to pick it up.");
  absl::StatusOr<v1::SelectResponse> chosen = clients_->bandit.Select(request);
  if (!chosen.ok()) {
    Fail(mealpb::STEP_SELECT, chosen.status(), "error",
         "nothing is pending unless the BanditService recorded the selection "
         "before failing")
        .IgnoreError();
    return chosen.status();
  }
  std::string text;
  {
    absl::MutexLock lock(&mu_);
    mealpb::Bite* bite = state_.mutable_bites(state_.bites_size() - 1);
    *bite->mutable_action() =
        DescribeAction(chosen->action(), chosen->action_name());
    *bite->mutable_estimates() = chosen->estimates();
    bite->set_event_id(chosen->event_id());
    // Kept only in the shape an Update takes, so that "has a prediction"
    // is one test (empty()) everywhere below.
    predicted_posthoc_.clear();
    if (chosen->predicted_posthoc_size() == domain::kHapticClasses) {
      predicted_posthoc_.assign(chosen->predicted_posthoc().begin(),
                                chosen->predicted_posthoc().end());
    }
    text =
        absl::StrFormat("%s: %s. %s", chosen->action_name(),
                        bite->action().title(), bite->action().description());
  }
  Emit(mealpb::STEP_SELECT, mealpb::STEP_STATE_DONE, text);
  return chosen;
}

absl::StatusOr<int> Meal::RobotActionNumber(const std::string& name) {
  if (robot_actions_.empty()) {
    absl::StatusOr<v1::ListActionsResponse> listed =
        clients_->robot.ListActions();
    if (!listed.ok()) return listed.status();
    for (const v1::Action& action : listed->actions()) {
      robot_actions_[action.name()] = action.index();
    }
  }
  auto found = robot_actions_.find(name);
  if (found == robot_actions_.end()) {
    std::vector<std::string> names;
    for (const auto& [known, number] : robot_actions_) names.push_back(known);
    return absl::FailedPreconditionError(absl::StrCat(
        "the BanditService chose action \"", name, "\" for ", options_.user_id,
        " but the robot has no action of that name (it has ",
        absl::StrJoin(names, ", "), ")"));
  }
  return found->second;
}

absl::StatusOr<v1::AcquireResult> Meal::Acquire(const v1::FoodItem& item,
                                                const std::string& action) {
  absl::StatusOr<int> number = RobotActionNumber(action);
  if (!number.ok()) {
    Fail(mealpb::STEP_ACQUIRE, number.status(), "error",
         "nothing is learned from this bite (it stays pending)")
        .IgnoreError();
    return number.status();
  }
  v1::AcquireRequest request;
  *request.mutable_target()->mutable_center_camera_m() = item.center_camera_m();
  request.mutable_target()->set_major_axis_angle_rad(
      item.major_axis_angle_rad());
  *request.mutable_target()->mutable_bbox() = item.bbox();
  request.set_action(*number);
  // A STOP pressed while this bite was being chosen (Featurize, Select: the
  // arm idle, so the robot's Stop did not carry over) ends it here, before
  // the arm moves.
  bool stopped_before = false;
  {
    absl::MutexLock lock(&mu_);
    stopped_before = stop_requested_;
  }
  if (stopped_before) {
    const absl::Status stopped =
        absl::AbortedError("Stopped by STOP before the arm moved");
    Fail(mealpb::STEP_ACQUIRE, stopped, "stopped",
         "nothing is learned from this bite (it stays pending)")
        .IgnoreError();
    return stopped;
  }
  Emit(mealpb::STEP_ACQUIRE, mealpb::STEP_STATE_STARTED, "The arm is moving.");
  // And one pressed between that check and the robot's start (its Stop
  // found the arm idle) is sent again at the first progress report, which
  // the robot sends as the approach begins.
  bool stop_sent_again = false;
  absl::StatusOr<v1::AcquireResult> result = clients_->robot.Acquire(
      request, [&](const v1::AcquireProgress& progress) {
        bool stop_now = false;
        {
          absl::MutexLock lock(&mu_);
          stop_now = stop_requested_ && !stop_sent_again;
        }
        if (stop_now) {
          stop_sent_again = true;
          clients_->robot.Stop()
              .IgnoreError();  // the Acquire says how it ended
        }
        if (!progress.has_result()) EmitProgress(progress);
      });
  if (!result.ok()) {
    bool stopped = false;
    std::string phase;
    {
      absl::MutexLock lock(&mu_);
      stopped = stop_requested_;
      phase = PhaseWord(state_.bites().rbegin()->phase());
    }
    if (stopped) {
      Fail(mealpb::STEP_ACQUIRE,
           absl::AbortedError(absl::StrCat("Stopped by STOP during ", phase,
                                           "; the arm is halted")),
           "stopped", "nothing is learned from this bite (it stays pending)")
          .IgnoreError();
    } else {
      Fail(mealpb::STEP_ACQUIRE, result.status(), "error",
           "nothing is learned from this bite (it stays pending)")
          .IgnoreError();
    }
    return result.status();
  }
  std::string text;
  {
    absl::MutexLock lock(&mu_);
    mealpb::Bite* bite = state_.mutable_bites(state_.bites_size() - 1);
    bite->set_phase(v1::ACQUIRE_PHASE_DONE);
    bite->set_food(result->true_food_type());
    bite->set_peak_force_n(result->peak_force_n());
    bite->set_force_limit_reached(result->force_limit_reached());
    if (result->force_limit_reached()) {
      const mealpb::ActionInfo& action = bite->action();
      text = action.max_force_n() > 0.0
                 ? absl::StrFormat(
                       " The fork stopped pushing at %s's %.0f N limit.",
                       action.name(), action.max_force_n())
                 : absl::StrFormat(" The fork stopped pushing at %s's limit.",
                                   action.name());
    }
  }
  Emit(mealpb::STEP_ACQUIRE, mealpb::STEP_STATE_DONE,
       absl::StrFormat("The arm is back (peak force %.1f N).%s",
                       result->peak_force_n(), text));
  return result;
}

void Meal::Judge(const v1::AcquireResult& result) {
  const bool ask = options_.confirm == ConfirmBy::kOperator ||
                   result.success_decided_by_operator();
  std::string text;
  {
    absl::MutexLock lock(&mu_);
    mealpb::Bite* bite = state_.mutable_bites(state_.bites_size() - 1);
    update_.emplace();
    update_->event_id = bite->event_id();
    if (ask) {
      bite->set_question(OperatorQuestion(*bite));
      bite->set_learned("awaiting answer");
      text = bite->question();
    } else {
      update_->loss = result.success() ? 0.0 : 1.0;
      bite->set_outcome(result.success() ? "success" : "failure");
      text = absl::StrCat(
          result.success() ? "Success: " : "Failure: ", FoodOf(*bite),
          result.success() ? " came" : " did not come", " up on the fork.");
      Recount();
    }
  }
  Emit(mealpb::STEP_JUDGE,
       ask ? mealpb::STEP_STATE_WAITING : mealpb::STEP_STATE_DONE, text);
}

domain::UnfamiliarPosthoc Meal::LimitReachedRule() const {
  return options_.limit_reached_posthoc.value_or(
      domain::DefaultLimitReachedPosthoc(user_.has_value() &&
                                         user_->config().learner() ==
                                             v1::LEARNER_POLINUCB));
}

std::vector<double> Meal::MissingPosthoc() const {
  if (!predicted_posthoc_.empty()) return predicted_posthoc_;
  return std::vector<double>(domain::kHapticClasses, 0.0);
}

std::string Meal::Felt(const v1::ClassifyResponse& haptic, mealpb::Bite* bite) {
  const int category = static_cast<int>(haptic.category());
  mealpb::HapticSummary* summary = bite->mutable_haptic();
  summary->set_label(HapticLabel(haptic.category()));
  summary->set_probability(category > 0 &&
                                   haptic.probabilities_size() >= category
                               ? haptic.probabilities(category - 1)
                               : 0.0);
  *summary->mutable_probabilities() = haptic.probabilities();
  // A trace cut short by the force limit is replaced by its own rule
  // (measured), whatever its familiarity.
  const bool cut = bite->force_limit_reached();
  const domain::UnfamiliarPosthoc rule =
      cut ? LimitReachedRule() : options_.unfamiliar_posthoc;
  if (update_.has_value() && options_.posthoc != PosthocMode::kNone) {
    const bool log_form = options_.posthoc == PosthocMode::kLogProbabilities;
    const auto& answer =
        log_form ? haptic.log_probabilities() : haptic.probabilities();
    update_->posthoc = domain::PosthocContext(
        std::vector<double>(answer.begin(), answer.end()), log_form,
        cut || haptic.unfamiliar(), rule);
    // A cut trace's answer left out is a missing post hoc context.
    if (cut && rule == domain::UnfamiliarPosthoc::kZero) {
      update_->posthoc = MissingPosthoc();
    }
  }
  std::string text =
      absl::StrFormat("It felt %s (%.0f%% sure).", summary->label(),
                      100.0 * summary->probability());
  const char* use = rule == domain::UnfamiliarPosthoc::kAsIs
                        ? "its answer is still used for learning"
                    : rule == domain::UnfamiliarPosthoc::kUniform
                        ? "learning treats how it felt as unknown (uniform)"
                    : cut && !predicted_posthoc_.empty()
                        ? "learning uses what the learner expected it to feel "
                          "from what the camera saw"
                        : "learning leaves out how it felt";
  if (options_.posthoc == PosthocMode::kNone) {
    // Vision only: nothing of the feel is learned anyway.
  } else if (cut) {
    absl::StrAppend(&text,
                    " The trace is cut short where the fork stopped at the "
                    "force limit, a shape HapticNet never learned from, so "
                    "this may be wrong; ",
                    use, ".");
  } else if (haptic.unfamiliar()) {
    absl::StrAppendFormat(
        &text,
        " This bite felt unusual, unlike what HapticNet learned from "
        "(familiarity %.3f); %s.",
        haptic.familiarity(), use);
  }
  return text;
}

absl::Status Meal::Classify(const v1::AcquireResult& result) {
  Emit(mealpb::STEP_CLASSIFY, mealpb::STEP_STATE_STARTED,
       "Feeling what the food was like.");
  absl::StatusOr<v1::ClassifyResponse> haptic =
      clients_->haptic.Classify(result.trace());
  Record(result, haptic.ok() ? &*haptic : nullptr,
         absl::IsFailedPrecondition(haptic.status()));
  // No contact: the force never held above the HapticService's contact
  // threshold (the fork missed the food, or the food is softer than the
  // threshold), so there is no haptic class, only a fact about the bite. It
  // is learned with no post hoc context (p = 0, so post hoc LinUCB's post
  // hoc part learns nothing and its visual part does; for poLinUCB too: its
  // own prediction did worse on a fork where many soft bites never reach
  // contact, docs/experiments.md "A missing post hoc context for
  // poLinUCB"), not failed: failing it would leave every such bite
  // unlearned and stop the meal at each one.
  const bool no_contact =
      !haptic.ok() && absl::IsFailedPrecondition(haptic.status());
  if (!haptic.ok() && !no_contact) {
    if (options_.posthoc != PosthocMode::kNone) {
      // Without a haptic class the post hoc learner cannot use this bite.
      return Fail(mealpb::STEP_CLASSIFY, haptic.status(),
                  state().current().outcome(),
                  "nothing is learned from this bite (it stays pending)");
    }
    Emit(mealpb::STEP_CLASSIFY, mealpb::STEP_STATE_DONE,
         absl::StrCat("No haptic class (", haptic.status().message(),
                      "); vision only, so the bite is still learned."));
    return absl::OkStatus();
  }
  std::string text;
  std::optional<JournaledUpdate> answered;
  {
    absl::MutexLock lock(&mu_);
    mealpb::Bite* bite = state_.mutable_bites(state_.bites_size() - 1);
    if (no_contact) {
      bite->mutable_haptic()->set_label("no contact");
      if (update_.has_value() && options_.posthoc != PosthocMode::kNone) {
        update_->posthoc.assign(domain::kHapticClasses, 0.0);
      }
      text = absl::StrCat(
          "The fork felt no contact, so there is no haptic class (",
          haptic.status().message(), "); ",
          options_.posthoc == PosthocMode::kNone
              ? "vision only, so the bite is still learned."
              : "the bite is learned from what the camera saw, with no post "
                "hoc context.");
    } else {
      text = Felt(*haptic, bite);
    }
    // An answer given while the trace was being classified is saved now.
    if (!bite->answer().empty() && update_.has_value()) answered = *update_;
  }
  Emit(mealpb::STEP_CLASSIFY, mealpb::STEP_STATE_DONE, text);
  if (answered.has_value()) {
    absl::Status saved = journal_->Append(*answered);
    if (!saved.ok()) {
      absl::MutexLock lock(&mu_);
      state_.mutable_bites(state_.bites_size() - 1)
          ->set_learned(absl::StrCat("LOST: ", saved.message()));
    }
  }
  return absl::OkStatus();
}

void Meal::Record(const v1::AcquireResult& result,
                  const v1::ClassifyResponse* haptic, bool no_contact) {
  if (options_.recording == nullptr || result.trace().empty()) return;
  RecordedBite bite;
  bite.user_id = options_.user_id;
  bite.meal_id = options_.meal_id;
  {
    absl::MutexLock lock(&mu_);
    const mealpb::Bite& current = state_.bites(state_.bites_size() - 1);
    bite.event_id = current.event_id();
    bite.food = current.food();
    bite.action = current.action().name();
    bite.outcome =
        current.question().empty() ? current.outcome() : "asked the operator";
  }
  const int true_category = static_cast<int>(result.true_haptic_category());
  if (true_category >= 1 && true_category <= domain::kHapticClasses) {
    bite.label = static_cast<domain::HapticClass>(true_category - 1);
  }
  const int category =
      haptic == nullptr ? 0 : static_cast<int>(haptic->category());
  if (category >= 1 && category <= domain::kHapticClasses) {
    bite.haptic = static_cast<domain::HapticClass>(category - 1);
    bite.probabilities.assign(haptic->probabilities().begin(),
                              haptic->probabilities().end());
  }
  bite.no_contact = no_contact;
  bite.force_limit_reached = result.force_limit_reached();
  if (haptic != nullptr && haptic->has_familiarity()) {
    bite.familiarity = haptic->familiarity();
    bite.unfamiliar = haptic->unfamiliar();
  }
  absl::StatusOr<std::string> id =
      options_.recording->Record(bite, result.trace());
  if (!id.ok() && listener_ != nullptr) {
    listener_->OnNote(
        absl::StrCat("the trace was not recorded: ", id.status().message()));
  }
}

void Meal::Learn() {
  JournaledUpdate update;
  std::string waiting;
  {
    absl::MutexLock lock(&mu_);
    mealpb::Bite* bite = state_.mutable_bites(state_.bites_size() - 1);
    if (!bite->question().empty()) {
      // The operator's answer, when given, is learned when it is final.
      waiting =
          bite->answer().empty()
              ? "Learned once the question is answered."
              : "The answer is saved; it is learned when the next bite starts.";
      bite->set_text(absl::StrCat(FoodOf(*bite), " with ",
                                  bite->action().name(), ": ",
                                  bite->question()));
    } else {
      update = *update_;
    }
  }
  if (!waiting.empty()) {
    Emit(mealpb::STEP_LEARN, mealpb::STEP_STATE_WAITING, waiting);
    return;
  }
  Emit(mealpb::STEP_LEARN, mealpb::STEP_STATE_STARTED, "Learning.");
  v1::UpdateRequest request;
  request.set_event_id(update.event_id);
  request.set_loss(update.loss);
  request.mutable_posthoc()->Add(update.posthoc.begin(), update.posthoc.end());
  const absl::StatusOr<v1::UpdateResponse> sent =
      clients_->bandit.Update(request);
  std::string learned;
  std::string error;
  if (sent.ok()) {
    learned = "learned";
  } else {
    error = std::string(sent.status().message());
    const absl::Status journaled = journal_->Append(update);
    learned = journaled.ok() ? "journaled"
                             : absl::StrCat("LOST: ", journaled.message());
  }
  std::string text;
  {
    absl::MutexLock lock(&mu_);
    mealpb::Bite* bite = state_.mutable_bites(state_.bites_size() - 1);
    bite->set_learned(learned);
    bite->set_error(error);
    text = absl::StrCat(
        FoodOf(*bite), " with ", bite->action().name(), ": ", bite->outcome(),
        "; ",
        sent.ok() ? absl::StrCat("learned (model version ",
                                 sent->model_version(), ")")
        : learned == "journaled"
            ? absl::StrCat("saved to be learned later (", error, ")")
            : learned);
    bite->set_text(text);
  }
  Emit(mealpb::STEP_LEARN,
       sent.ok() || learned == "journaled" ? mealpb::STEP_STATE_DONE
                                           : mealpb::STEP_STATE_FAILED,
       text, error);
}

absl::Status Meal::Answer(const std::string& event_id, bool success) {
  std::optional<JournaledUpdate> to_save;
  std::string text;
  {
    absl::MutexLock lock(&mu_);
    if (state_.bites_size() == 0 ||
        state_.bites().rbegin()->question().empty()) {
      return absl::FailedPreconditionError(
          "no question is open: the robot judged this bite, or its answer is "
          "already final");
    }
    mealpb::Bite* bite = state_.mutable_bites(state_.bites_size() - 1);
    if (bite->event_id() != event_id) {
      return absl::NotFoundError(absl::StrCat(
          "event ", event_id, " is not the bite awaiting an answer (event ",
          bite->event_id(), ")"));
    }
    bite->set_answer(success ? "yes" : "no");
    bite->set_outcome(success ? "success" : "failure");
    if (update_.has_value()) {
      update_->loss = success ? 0.0 : 1.0;
      // Saved once the trace is classified (the update needs its post hoc
      // context); before that, Classify saves it.
      const bool classified =
          options_.posthoc == PosthocMode::kNone || !update_->posthoc.empty();
      if (classified) to_save = *update_;
    }
    bite->set_learned("answer saved");
    text = absl::StrFormat(
        "Answer: %s. It can be changed until the next bite starts.",
        success ? "yes" : "no");
    Recount();
  }
  if (to_save.has_value()) {
    absl::Status saved = journal_->Append(*to_save);
    if (!saved.ok()) {
      {
        absl::MutexLock lock(&mu_);
        state_.mutable_bites(state_.bites_size() - 1)
            ->set_learned(absl::StrCat("LOST: ", saved.message()));
      }
      Emit(mealpb::STEP_JUDGE, mealpb::STEP_STATE_FAILED,
           "The answer could not be saved.", std::string(saved.message()));
      return saved;
    }
  }
  Emit(mealpb::STEP_JUDGE, mealpb::STEP_STATE_DONE, text);
  return absl::OkStatus();
}

void Meal::ConfirmAnswer() {
  bool answered = false;
  {
    absl::MutexLock lock(&mu_);
    if (state_.bites_size() == 0) return;
    mealpb::Bite* bite = state_.mutable_bites(state_.bites_size() - 1);
    if (bite->question().empty()) return;
    bite->clear_question();
    answered = !bite->answer().empty() && bite->learned() == "answer saved";
    if (!answered) {
      bite->set_learned("not learned");
      bite->set_text(absl::StrCat(FoodOf(*bite), " with ",
                                  bite->action().name(),
                                  ": not answered; nothing learned (the "
                                  "event stays pending)"));
      *state_.mutable_current() = *bite;
      return;
    }
  }
  std::string why_not;
  std::map<std::string, absl::Status> results;
  const absl::StatusOr<int> delivered = DeliverJournal(&why_not, &results);
  std::string text;
  {
    absl::MutexLock lock(&mu_);
    mealpb::Bite* bite = state_.mutable_bites(state_.bites_size() - 1);
    // This bite's answer, not merely something from the journal (an older
    // entry delivered, or this one refused for good and dropped).
    const auto result = results.find(bite->event_id());
    const bool learned =
        delivered.ok() && result != results.end() && result->second.ok();
    const bool dropped = delivered.ok() && result != results.end() &&
                         !result->second.ok() && !Retryable(result->second);
    bite->set_learned(learned   ? "learned"
                      : dropped ? "not learned"
                                : "journaled");
    if (!learned) {
      // This event's own error where it was tried, else the last one's.
      bite->set_error(
          !delivered.ok()           ? std::string(delivered.status().message())
          : result != results.end() ? std::string(result->second.message())
                                    : why_not);
    }
    text = absl::StrCat(
        FoodOf(*bite), " with ", bite->action().name(), ": ", bite->outcome(),
        " (operator); ",
        learned ? "learned"
        : dropped
            ? absl::StrCat("not learned: the BanditService refused it (",
                           bite->error(), ")")
            : absl::StrCat("saved to be learned later (",
                           bite->error().empty() ? "BanditService unavailable"
                                                 : bite->error(),
                           ")"));
    bite->set_text(text);
    *state_.mutable_current() = *bite;
  }
  Emit(mealpb::STEP_LEARN, mealpb::STEP_STATE_DONE, text);
}

uint64_t Meal::stops() const {
  absl::MutexLock lock(&mu_);
  return stops_;
}

absl::StatusOr<v1::StopResponse> Meal::Stop() {
  {
    absl::MutexLock lock(&mu_);
    ++stops_;
    stop_requested_ = true;
    state_.set_stopped(true);
  }
  return clients_->robot.Stop();
}

absl::Status Meal::Finish() {
  if (!busy_mu_.TryLock()) {
    return absl::FailedPreconditionError(
        "a bite is running: press STOP or wait for it to end");
  }
  BusyGuard busy(&busy_mu_);
  ConfirmAnswer();
  std::string text;
  {
    absl::MutexLock lock(&mu_);
    state_.set_running(false);
    state_.set_phase("ended");
    text = absl::StrCat("Meal ", state_.meal_id(),
                        " is over: ", state_.summary().text(), ".");
  }
  Emit(mealpb::STEP_UNSPECIFIED, mealpb::STEP_STATE_DONE, text);
  return absl::OkStatus();
}

}  // namespace bitewise::meals
