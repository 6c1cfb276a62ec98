// The meal library against the four real services in this process (the
// simulated robot streams real UDP): every step of a bite and its events,
// the person's choice, the operator's answer and its change, STOP during the
// descent, and the failure of each service at each step: what the person is
// told, what stays pending in the BanditService and what is journaled.
#include "clients/meal/meal.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <memory>
#include <optional>
#include <ostream>
#include <string>
#include <thread>
#include <vector>

#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_split.h"
#include "absl/synchronization/mutex.h"
#include "clients/meal/trace_recording.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "services/domain/context_ridge.h"
#include "tests/common/status_matchers.h"
#include "tests/meal/four_services.h"

#define ASSERT_OK(expr) ASSERT_THAT(expr, IsOk())

namespace bitewise::meals {
namespace {

using ::bitewise::testing::FourServices;
using ::bitewise::testing::FourServicesOptions;
using ::bitewise::testing::IsOk;
using ::bitewise::testing::SharedFourServicesTest;
using ::bitewise::testing::StatusIs;
using ::testing::HasSubstr;

// Records every event; can act on one (STOP at the descent).
class RecordingListener : public MealListener {
 public:
  void OnEvent(const mealpb::BiteEvent& event,
               const mealpb::MealState& state) override {
    std::function<void(const mealpb::BiteEvent&)> hook;
    {
      absl::MutexLock lock(&mu_);
      events_.push_back(event);
      hook = hook_;
    }
    if (hook) hook(event);
  }
  void OnNote(const std::string& note) override {
    absl::MutexLock lock(&mu_);
    notes_.push_back(note);
  }
  void SetHook(std::function<void(const mealpb::BiteEvent&)> hook) {
    absl::MutexLock lock(&mu_);
    hook_ = std::move(hook);
  }
  std::vector<mealpb::BiteEvent> events() const {
    absl::MutexLock lock(&mu_);
    return events_;
  }
  std::vector<std::string> notes() const {
    absl::MutexLock lock(&mu_);
    return notes_;
  }
  // The steps' (step, state) pairs without progress reports.
  std::vector<std::pair<mealpb::Step, mealpb::StepState>> Steps() const {
    std::vector<std::pair<mealpb::Step, mealpb::StepState>> steps;
    for (const mealpb::BiteEvent& e : events()) {
      if (e.state() != mealpb::STEP_STATE_PROGRESS) {
        steps.emplace_back(e.step(), e.state());
      }
    }
    return steps;
  }

 private:
  mutable absl::Mutex mu_;
  std::vector<mealpb::BiteEvent> events_;
  std::vector<std::string> notes_;
  std::function<void(const mealpb::BiteEvent&)> hook_;
};

// Opens a trace recording in `dir` and has the meal of `options` record
// into it (the recording must outlive the meal).
absl::StatusOr<std::unique_ptr<TraceRecording>> RecordInto(
    const std::string& dir, MealOptions* options) {
  absl::StatusOr<std::unique_ptr<TraceRecording>> recording =
      TraceRecording::Open(dir);
  if (recording.ok()) options->recording = recording->get();
  return recording;
}

// A meal's surroundings on services of its own: the services with
// `service_options`, clients, a journal and the options of `user_id`'s
// lunch.
struct OwnServices {
  std::unique_ptr<FourServices> services;
  std::unique_ptr<ServiceClients> clients;
  std::unique_ptr<UpdateJournal> journal;
  MealOptions options;
};

absl::StatusOr<OwnServices> StartOwnServices(
    const FourServicesOptions& service_options, const std::string& user_id) {
  OwnServices own;
  absl::StatusOr<std::unique_ptr<FourServices>> services =
      FourServices::Start(service_options);
  if (!services.ok()) return services.status();
  own.services = *std::move(services);
  own.clients = std::make_unique<ServiceClients>(own.services->channels(),
                                                 CallDeadlines());
  own.journal = std::make_unique<UpdateJournal>(
      absl::StrCat(own.services->dir(), "/", user_id, ".journal"));
  own.options.user_id = user_id;
  own.options.meal_id = "lunch";
  return own;
}

// A Select at `event`'s context predicts the post hoc context `event` was
// learned with: what a poLinUCB bite without one sends (the prediction the
// model made at its own Select; learning it leaves the prediction as it
// was, so a new Select at the same context gives it again). A person's
// first bite predicts zeros (nothing learned yet); later ones must not.
void ExpectPredictedAt(ServiceClients& clients, const v1::Event& event,
                       bool first_bite = false) {
  v1::SelectRequest select;
  select.set_user_id(event.user_id());
  select.set_meal_id("check");
  *select.mutable_context() = event.context();
  absl::StatusOr<v1::SelectResponse> chosen = clients.bandit.Select(select);
  ASSERT_TRUE(chosen.ok()) << chosen.status();
  ASSERT_EQ(chosen->predicted_posthoc_size(), 4);
  ASSERT_EQ(event.posthoc_size(), 4);
  double norm = 0.0;
  for (int k = 0; k < 4; ++k) {
    EXPECT_NEAR(event.posthoc(k), chosen->predicted_posthoc(k),
                1e-8 * (1.0 + std::abs(event.posthoc(k))))
        << k;
    norm += event.posthoc(k) * event.posthoc(k);
  }
  if (first_bite) {
    EXPECT_EQ(norm, 0.0);
  } else {
    EXPECT_GT(norm, 0.0);
  }
}

class MealTest : public SharedFourServicesTest<MealTest> {
 public:
  static FourServicesOptions Options() {
    FourServicesOptions options;
    options.foods = {"strawberry", "carrot", "banana",
                     "grape",      "kiwi",   "celery"};
    return options;
  }

 protected:
  void SetUp() override {
    ASSERT_NE(services_, nullptr);
    services_->faults().Clear();
    clients_ = std::make_unique<ServiceClients>(services_->channels(),
                                                CallDeadlines());
    std::string name =
        ::testing::UnitTest::GetInstance()->current_test_info()->name();
    std::replace(name.begin(), name.end(), '/', '-');
    journal_ = std::make_unique<UpdateJournal>(
        absl::StrCat(services_->dir(), "/", name, ".journal"));
    options_.user_id = absl::StrCat("user-", name);
    options_.meal_id = "lunch";
  }

  std::unique_ptr<Meal> NewMeal() {
    return std::make_unique<Meal>(clients_.get(), journal_.get(), options_,
                                  &listener_);
  }

  std::vector<v1::Event> Events() {
    v1::ListEventsRequest request;
    request.set_user_id(options_.user_id);
    request.set_page_size(1000);
    absl::StatusOr<v1::ListEventsResponse> events =
        clients_->bandit.ListEvents(request);
    if (absl::IsNotFound(events.status())) return {};
    EXPECT_TRUE(events.ok()) << events.status();
    if (!events.ok()) return {};
    return {events->events().begin(), events->events().end()};
  }

  // Makes the test's person a context-only learner over `actions`, with
  // the featurizer's context size.
  absl::Status CreateUserWithActions(const std::vector<std::string>& actions) {
    const int context_dim = ContextDim();
    if (context_dim <= 0) return absl::InternalError("no context size");
    v1::CreateUserRequest create;
    create.set_user_id(options_.user_id);
    create.mutable_config()->set_context_dim(context_dim);
    create.mutable_config()->set_learner(v1::LEARNER_CONTEXT_ONLY);
    for (const std::string& name : actions) {
      create.mutable_config()->add_action_names(name);
    }
    return clients_->bandit.CreateUser(create).status();
  }

  // The featurizer's context size, from a person who is not the test's.
  int ContextDim() {
    MealOptions other = options_;
    other.user_id = options_.user_id + "-probe";
    Meal probe(clients_.get(), journal_.get(), other, nullptr);
    if (!probe.LookAtPlate().ok() || !probe.Bite(std::nullopt).ok()) return 0;
    absl::StatusOr<v1::User> user = clients_->bandit.GetUser(other.user_id);
    return user.ok() ? static_cast<int>(user->config().context_dim()) : 0;
  }

  std::unique_ptr<ServiceClients> clients_;
  std::unique_ptr<UpdateJournal> journal_;
  MealOptions options_;
  RecordingListener listener_;
};

// A HapticService that calls (nearly) every trace unfamiliar: with
// --unfamiliar_posthoc=uniform the bite's post hoc context is flattened to
// the uniform log-probabilities, the person is told why, and the recording
// keeps the score and the verdict.
TEST(UnfamiliarMealTest, AnUnfamiliarBiteSendsFlattenedPosthocContext) {
  FourServicesOptions service_options;
  // Neither pushes back with 10 N, so no action's force limit cuts the
  // trace short (a cut bite follows its own rule).
  service_options.foods = {"strawberry", "banana"};
  service_options.familiarity_threshold = 1.0;
  absl::StatusOr<OwnServices> own =
      StartOwnServices(service_options, "unfamiliar-user");
  ASSERT_OK(own.status());
  FourServices* services = own->services.get();
  ServiceClients& clients = *own->clients;
  UpdateJournal& journal = *own->journal;
  MealOptions& options = own->options;
  // The default sends HapticNet's answer as it is (measured); this test
  // checks the flattening path the flag chooses.
  EXPECT_EQ(options.unfamiliar_posthoc, domain::UnfamiliarPosthoc::kAsIs);
  options.unfamiliar_posthoc = domain::UnfamiliarPosthoc::kUniform;
  const std::string recorded = absl::StrCat(services->dir(), "/recorded");
  absl::StatusOr<std::unique_ptr<TraceRecording>> recording =
      RecordInto(recorded, &options);
  ASSERT_OK(recording.status());
  RecordingListener listener;
  Meal meal(&clients, &journal, options, &listener);
  ASSERT_OK(meal.LookAtPlate());
  ASSERT_OK(meal.Bite(std::nullopt));
  bool told = false;
  for (const mealpb::BiteEvent& e : listener.events()) {
    told = told || (e.step() == mealpb::STEP_CLASSIFY &&
                    absl::StrContains(e.text(), "This bite felt unusual") &&
                    absl::StrContains(
                        e.text(), "treats how it felt as unknown (uniform)"));
  }
  EXPECT_TRUE(told);
  v1::ListEventsRequest request;
  request.set_user_id(options.user_id);
  absl::StatusOr<v1::ListEventsResponse> events =
      clients.bandit.ListEvents(request);
  ASSERT_OK(events.status());
  ASSERT_EQ(events->events_size(), 1);
  EXPECT_THAT(events->events(0).posthoc(),
              ::testing::Each(::testing::DoubleEq(std::log(0.25))));

  std::ifstream bites(absl::StrCat(recorded, "/bites.csv"));
  std::string header, line;
  ASSERT_TRUE(std::getline(bites, header) && std::getline(bites, line));
  EXPECT_TRUE(
      absl::EndsWith(header, ",familiarity,unfamiliar,force_limit_reached"))
      << header;
  const std::vector<std::string> row = absl::StrSplit(line, ',');
  ASSERT_EQ(row.size(), 17u) << line;
  double familiarity = -1.0;
  EXPECT_TRUE(absl::SimpleAtod(row[14], &familiarity)) << line;
  EXPECT_GE(familiarity, 0.0);
  EXPECT_LE(familiarity, 1.0);
  EXPECT_EQ(row[15], "1") << line;  // the threshold 1 flags it
  EXPECT_EQ(row[16], "0") << line;  // not cut short
}

// A bite the fork never feels: the only item (a strawberry, taller than the
// descent's depth limit, so the fork stops in the air where it was) has been
// eaten, and the robot bites where it was seen. The HapticService finds no
// contact (FAILED_PRECONDITION); the meal goes on and learns the failure
// from what the camera saw, with no post hoc context of its own (the person
// learns with poLinUCB, so the one its Select predicted), the robot's
// verdict or the operator's answer alike.
class NoContactMealTest : public ::testing::TestWithParam<ConfirmBy> {};

TEST_P(NoContactMealTest, IsLearnedFromVisionWithNoPosthocContext) {
  FourServicesOptions service_options;
  service_options.foods = {"strawberry"};
  absl::StatusOr<OwnServices> own =
      StartOwnServices(service_options, "miss-user");
  ASSERT_OK(own.status());
  FourServices* services = own->services.get();
  ServiceClients& clients = *own->clients;
  UpdateJournal& journal = *own->journal;
  MealOptions& options = own->options;
  options.confirm = GetParam();
  // The learner that predicts a post hoc context (the default, post hoc
  // LinUCB, sends p = 0 for such a bite anyway).
  options.learner = v1::LEARNER_POLINUCB;
  ASSERT_EQ(options.posthoc, PosthocMode::kLogProbabilities);
  const std::string recorded = absl::StrCat(services->dir(), "/recorded");
  absl::StatusOr<std::unique_ptr<TraceRecording>> recording =
      RecordInto(recorded, &options);
  ASSERT_OK(recording.status());
  RecordingListener listener;
  Meal meal(&clients, &journal, options, &listener);
  // A second console's look at the plate, taken now: by the time it is
  // bitten at, the strawberry is gone (each bite needs a look of its own,
  // so a gone item is reached only through a look taken before).
  Meal late(&clients, &journal, options, &listener);
  ASSERT_OK(late.LookAtPlate());
  ASSERT_EQ(late.state().items_size(), 1);
  const auto answer_if_asked = [&](Meal& asked, bool success) {
    const mealpb::Bite bite = asked.state().current();
    if (options.confirm == ConfirmBy::kOperator) {
      ASSERT_OK(asked.Answer(bite.event_id(), success));
    }
  };
  // Bite until the strawberry comes up (the operator tells the truth).
  int bites = 0;
  for (; bites < 12; ++bites) {
    ASSERT_OK(meal.LookAtPlate());
    ASSERT_EQ(meal.state().items_size(), 1);
    ASSERT_OK(meal.Bite(0));
    const bool felt = meal.state().current().haptic().probabilities_size() > 0;
    ASSERT_TRUE(felt) << meal.state().current().text();
    bool came_up = false;
    for (const mealpb::BiteEvent& e : listener.events()) {
      came_up = came_up || (e.step() == mealpb::STEP_JUDGE &&
                            e.bite() == meal.state().bite() &&
                            absl::StrContains(e.text(), "came up"));
    }
    if (options.confirm == ConfirmBy::kOperator) {
      // The robot's verdict is not shown; the world's is.
      came_up = services->ItemsLeft() == 0;
    }
    answer_if_asked(meal, came_up);
    if (came_up) break;
  }
  ASSERT_LT(bites, 12) << "the strawberry never came up";
  ASSERT_EQ(services->ItemsLeft(), 0);
  ASSERT_OK(meal.Finish());

  // The same item from the earlier look: it is gone.
  ASSERT_OK(late.Bite(0));
  answer_if_asked(late, false);
  const mealpb::MealState state = late.state();
  EXPECT_NE(state.phase(), "failed") << state.error();
  const mealpb::Bite& missed = state.current();
  EXPECT_EQ(missed.outcome(), "failure");
  EXPECT_EQ(missed.haptic().label(), "no contact");
  EXPECT_EQ(missed.haptic().probabilities_size(), 0);
  EXPECT_TRUE(missed.error().empty()) << missed.error();
  bool told = false;
  for (const mealpb::BiteEvent& e : listener.events()) {
    told = told ||
           (e.step() == mealpb::STEP_CLASSIFY &&
            e.state() == mealpb::STEP_STATE_DONE && e.bite() == state.bite() &&
            absl::StrContains(e.text(), "felt no contact") &&
            absl::StrContains(e.text(), "peak force") &&
            absl::StrContains(e.text(), "with no post hoc context"));
  }
  EXPECT_TRUE(told);
  std::vector<double> saved_posthoc;
  if (options.confirm == ConfirmBy::kOperator) {
    // The answer is saved now, and learned when the next bite starts.
    absl::StatusOr<std::vector<JournaledUpdate>> saved = journal.ReadAll();
    ASSERT_OK(saved.status());
    ASSERT_FALSE(saved->empty());
    EXPECT_EQ(saved->back().event_id, missed.event_id());
    EXPECT_EQ(saved->back().loss, 1.0);
    ASSERT_EQ(saved->back().posthoc.size(), 4u);
    saved_posthoc = saved->back().posthoc;
    ASSERT_OK(late.Finish());
  } else {
    EXPECT_EQ(missed.learned(), "learned");
  }
  v1::ListEventsRequest request;
  request.set_user_id(options.user_id);
  request.set_page_size(100);
  absl::StatusOr<v1::ListEventsResponse> events =
      clients.bandit.ListEvents(request);
  ASSERT_OK(events.status());
  const auto event = std::find_if(
      events->events().begin(), events->events().end(),
      [&](const v1::Event& e) { return e.event_id() == missed.event_id(); });
  ASSERT_NE(event, events->events().end());
  EXPECT_TRUE(event->completed());
  EXPECT_EQ(event->loss(), 1.0);
  // The person's learner is poLinUCB, and the bite sent p = 0, not the post
  // hoc context its Select predicted (measured worse for contact-less
  // bites). A Select at its context now predicts a non-zero context, so
  // zeros here are the rule, not an empty prediction.
  EXPECT_THAT(event->posthoc(), ::testing::Each(0.0));
  if (options.confirm == ConfirmBy::kOperator) {
    EXPECT_THAT(saved_posthoc, ::testing::Each(0.0));
  }
  v1::SelectRequest select;
  select.set_user_id(event->user_id());
  select.set_meal_id("check");
  *select.mutable_context() = event->context();
  absl::StatusOr<v1::SelectResponse> chosen = clients.bandit.Select(select);
  ASSERT_OK(chosen.status());
  ASSERT_EQ(chosen->predicted_posthoc_size(), 4);
  double predicted_norm = 0.0;
  for (double p : chosen->predicted_posthoc()) predicted_norm += p * p;
  EXPECT_GT(predicted_norm, 0.0);
  // The lab's recording keeps the trace and says it had no contact.
  std::ifstream bites_csv(absl::StrCat(recorded, "/bites.csv"));
  std::string line, missed_row;
  while (std::getline(bites_csv, line)) {
    if (absl::StrContains(line, missed.event_id())) missed_row = line;
  }
  const std::vector<std::string> row = absl::StrSplit(missed_row, ',');
  ASSERT_GE(row.size(), 10u) << missed_row;
  EXPECT_EQ(row[9], "no contact") << missed_row;
}

INSTANTIATE_TEST_SUITE_P(RobotOrOperator, NoContactMealTest,
                         ::testing::Values(ConfirmBy::kRobot,
                                           ConfirmBy::kOperator),
                         [](const ::testing::TestParamInfo<ConfirmBy>& info) {
                           return info.param == ConfirmBy::kRobot
                                      ? std::string("RobotJudges")
                                      : std::string("OperatorAnswers");
                         });

// A person whose only action is TA90, at a carrot: the world's hard items
// push back with 10-18 N, so the fork stops pushing at TA90's 10 N limit and
// the trace is cut short there. The bite says so (its flag, the action's
// limit, the Acquire's and the Classify's words), and the post hoc learner
// gets what the rule says. By default the rule measured for the person's
// learner (docs/experiments.md, "A trace the robot cut short"): for
// poLinUCB no post hoc context of its own, so its prediction; for post hoc
// LinUCB HapticNet's answer on the cut trace. Zero for post hoc LinUCB
// sends zeros.
struct ForceLimitCase {
  std::optional<domain::UnfamiliarPosthoc> rule;  // nullopt: the default
  v1::Learner learner;
  const char* name;
};

class ForceLimitMealTest : public ::testing::TestWithParam<ForceLimitCase> {};

TEST_P(ForceLimitMealTest, ABiteStoppedAtTheLimitSaysSoAndFollowsTheRule) {
  FourServicesOptions service_options;
  service_options.foods = {"carrot"};
  absl::StatusOr<OwnServices> own =
      StartOwnServices(service_options, "limit-user");
  ASSERT_OK(own.status());
  ServiceClients& clients = *own->clients;
  EXPECT_EQ(own->options.limit_reached_posthoc, std::nullopt);
  own->options.limit_reached_posthoc = GetParam().rule;
  const std::string recorded = absl::StrCat(own->services->dir(), "/recorded");
  absl::StatusOr<std::unique_ptr<TraceRecording>> recording =
      RecordInto(recorded, &own->options);
  ASSERT_OK(recording.status());
  // The featurizer's context size, without a bite.
  absl::StatusOr<v1::Frame> frame = clients.robot.CaptureFrame();
  ASSERT_OK(frame.status());
  absl::StatusOr<v1::DetectFoodResponse> detected =
      clients.perception.DetectFood(*frame);
  ASSERT_OK(detected.status());
  ASSERT_EQ(detected->items_size(), 1);
  absl::StatusOr<v1::FeaturizeResponse> features =
      clients.perception.Featurize(*frame, detected->items(0).bbox());
  ASSERT_OK(features.status());
  v1::CreateUserRequest create;
  create.set_user_id(own->options.user_id);
  create.mutable_config()->set_context_dim(features->context_size());
  create.mutable_config()->set_learner(GetParam().learner);
  create.mutable_config()->add_action_names("TA90");
  ASSERT_OK(clients.bandit.CreateUser(create).status());

  RecordingListener listener;
  Meal meal(&clients, own->journal.get(), own->options, &listener);
  ASSERT_OK(meal.LookAtPlate());
  ASSERT_OK(meal.Bite(0));
  const mealpb::MealState state = meal.state();
  const mealpb::Bite& bite = state.current();
  EXPECT_NE(state.phase(), "failed") << state.error();
  EXPECT_EQ(bite.food(), "carrot");
  EXPECT_EQ(bite.action().name(), "TA90");
  EXPECT_EQ(bite.action().max_force_n(), 10.0);
  EXPECT_TRUE(bite.force_limit_reached());
  EXPECT_GE(bite.peak_force_n(), 10.0);
  EXPECT_EQ(bite.learned(), "learned");
  const bool zero = GetParam().rule.value_or(domain::DefaultLimitReachedPosthoc(
                        GetParam().learner == v1::LEARNER_POLINUCB)) ==
                    domain::UnfamiliarPosthoc::kZero;
  // A missing post hoc context: poLinUCB's own prediction, else p = 0.
  const bool predicted = zero && GetParam().learner == v1::LEARNER_POLINUCB;
  bool acquire_told = false, classify_told = false;
  for (const mealpb::BiteEvent& e : listener.events()) {
    if (e.state() != mealpb::STEP_STATE_DONE) continue;
    acquire_told = acquire_told ||
                   (e.step() == mealpb::STEP_ACQUIRE &&
                    absl::StrContains(e.text(),
                                      "The fork stopped pushing at TA90's 10 N "
                                      "limit."));
    classify_told =
        classify_told ||
        (e.step() == mealpb::STEP_CLASSIFY &&
         absl::StrContains(e.text(), "cut short where the fork stopped") &&
         absl::StrContains(
             e.text(), predicted ? "learning uses what the learner expected it "
                                   "to feel from what the camera saw"
                       : zero    ? "learning leaves out how it felt"
                                 : "its answer is still used for learning"));
  }
  EXPECT_TRUE(acquire_told);
  EXPECT_TRUE(classify_told);
  // HapticNet's answer is shown; the learner got what the rule says.
  ASSERT_EQ(bite.haptic().probabilities_size(), 4);
  v1::ListEventsRequest request;
  request.set_user_id(own->options.user_id);
  absl::StatusOr<v1::ListEventsResponse> events =
      clients.bandit.ListEvents(request);
  ASSERT_OK(events.status());
  ASSERT_EQ(events->events_size(), 1);
  ASSERT_EQ(events->events(0).posthoc_size(), 4);
  if (predicted) {
    // The person's first bite: the prediction is still zeros
    // (NoContactMealTest sees a later one).
    ExpectPredictedAt(clients, events->events(0), /*first_bite=*/true);
  } else {
    for (int k = 0; k < 4; ++k) {
      EXPECT_NEAR(events->events(0).posthoc(k),
                  zero ? 0.0 : std::log(bite.haptic().probabilities(k)), 1e-4)
          << k;
    }
  }
  // The lab's recording marks the trace as cut short.
  std::ifstream bites_csv(absl::StrCat(recorded, "/bites.csv"));
  std::string header, line;
  ASSERT_TRUE(std::getline(bites_csv, header) && std::getline(bites_csv, line));
  EXPECT_TRUE(absl::EndsWith(header, ",force_limit_reached")) << header;
  EXPECT_TRUE(absl::EndsWith(line, ",1")) << line;
}

INSTANTIATE_TEST_SUITE_P(
    Rules, ForceLimitMealTest,
    ::testing::Values(
        ForceLimitCase{std::nullopt, v1::LEARNER_POLINUCB,
                       "PoLinUcbSendsItsPredictionByDefault"},
        ForceLimitCase{std::nullopt, v1::LEARNER_POSTHOC,
                       "PostHocLinUcbSendsHapticNetsAnswerByDefault"},
        ForceLimitCase{domain::UnfamiliarPosthoc::kZero, v1::LEARNER_POSTHOC,
                       "PostHocLinUcbSendsZerosUnderZero"},
        ForceLimitCase{domain::UnfamiliarPosthoc::kAsIs, v1::LEARNER_POLINUCB,
                       "PoLinUcbSendsHapticNetsAnswerUnderAsIs"}),
    [](const ::testing::TestParamInfo<ForceLimitCase>& info) {
      return std::string(info.param.name);
    });

TEST(MealWordsTest, SingularAndPlural) {
  EXPECT_EQ(SummaryText(1, 1), "1 attempt, 1 failure");
  EXPECT_EQ(SummaryText(2, 0), "2 attempts, 0 failures");
  EXPECT_EQ(SummaryText(0, 0), "0 attempts, 0 failures");
  EXPECT_EQ(Count(1, "item", "items"), "1 item");
}

TEST(MealWordsTest, QuestionNamesTheBiteTheFoodAndTheAction) {
  mealpb::Bite bite;
  bite.set_food("strawberry");
  bite.mutable_action()->set_name("VS0");
  bite.mutable_action()->set_title("Vertical skewer");
  EXPECT_EQ(OperatorQuestion(bite),
            "Did the strawberry come up on the fork with VS0 (Vertical "
            "skewer)?");
  bite.set_number(4);
  EXPECT_EQ(OperatorQuestion(bite),
            "Bite 4: did the strawberry come up on the fork with VS0 "
            "(Vertical skewer)?");
  bite.clear_food();
  bite.set_item_index(2);
  EXPECT_THAT(OperatorQuestion(bite), HasSubstr("Bite 4: did item 3 come up"));
}

TEST(ContextRidgeTest, ExplicitThenScaledThenServiceDefault) {
  EXPECT_EQ(domain::NewUserContextRidge(250.0, 1.0, 45.0), 250.0);
  EXPECT_EQ(domain::NewUserContextRidge(0.0, 2.0, 45.0), 90.0);
  EXPECT_EQ(domain::NewUserContextRidge(0.0, 1.0, 0.0), 0.0);
}

TEST_F(MealTest, RobotsChoiceRunsEveryStepInOrderAndLearns) {
  auto meal = NewMeal();
  ASSERT_OK(meal->LookAtPlate());
  mealpb::MealState looked = meal->state();
  EXPECT_EQ(looked.phase(), "choosing");
  ASSERT_GT(looked.items_size(), 0);
  EXPECT_EQ(looked.plate_version(), 1);
  EXPECT_EQ(looked.frame_width(), 640);
  ASSERT_OK(meal->Bite(std::nullopt));

  using P = std::pair<mealpb::Step, mealpb::StepState>;
  const std::vector<P> expected = {
      {mealpb::STEP_CAPTURE, mealpb::STEP_STATE_STARTED},
      {mealpb::STEP_CAPTURE, mealpb::STEP_STATE_DONE},
      {mealpb::STEP_DETECT, mealpb::STEP_STATE_STARTED},
      {mealpb::STEP_DETECT, mealpb::STEP_STATE_DONE},
      {mealpb::STEP_CHOOSE, mealpb::STEP_STATE_DONE},
      {mealpb::STEP_FEATURIZE, mealpb::STEP_STATE_STARTED},
      {mealpb::STEP_FEATURIZE, mealpb::STEP_STATE_DONE},
      {mealpb::STEP_SELECT, mealpb::STEP_STATE_STARTED},
      {mealpb::STEP_SELECT, mealpb::STEP_STATE_DONE},
      {mealpb::STEP_ACQUIRE, mealpb::STEP_STATE_STARTED},
      {mealpb::STEP_ACQUIRE, mealpb::STEP_STATE_DONE},
      {mealpb::STEP_JUDGE, mealpb::STEP_STATE_DONE},
      {mealpb::STEP_CLASSIFY, mealpb::STEP_STATE_STARTED},
      {mealpb::STEP_CLASSIFY, mealpb::STEP_STATE_DONE},
      {mealpb::STEP_LEARN, mealpb::STEP_STATE_STARTED},
      {mealpb::STEP_LEARN, mealpb::STEP_STATE_DONE}};
  EXPECT_EQ(listener_.Steps(), expected);

  // Progress streamed through every phase of the motion.
  std::vector<v1::AcquirePhase> phases;
  for (const mealpb::BiteEvent& e : listener_.events()) {
    if (e.state() != mealpb::STEP_STATE_PROGRESS) continue;
    EXPECT_EQ(e.bite(), 1);
    EXPECT_GT(e.wall_time_s(), 1.6e9);
    if (phases.empty() || phases.back() != e.phase()) {
      phases.push_back(e.phase());
    }
  }
  EXPECT_THAT(phases, ::testing::ElementsAre(v1::ACQUIRE_PHASE_APPROACH,
                                             v1::ACQUIRE_PHASE_ORIENT,
                                             v1::ACQUIRE_PHASE_DESCEND,
                                             v1::ACQUIRE_PHASE_EXTRACT));

  const mealpb::MealState state = meal->state();
  const mealpb::Bite& bite = state.current();
  EXPECT_EQ(bite.number(), 1);
  EXPECT_TRUE(bite.robots_choice());
  // The robot's choice is the most confident detection.
  int best = 0;
  for (int i = 1; i < looked.items_size(); ++i) {
    if (looked.items(i).score() > looked.items(best).score()) best = i;
  }
  EXPECT_EQ(bite.item_index(), best);
  EXPECT_FALSE(bite.food().empty());
  EXPECT_FALSE(bite.action().title().empty());
  EXPECT_FALSE(bite.action().description().empty());
  EXPECT_EQ(bite.estimates_size(), 6);
  EXPECT_GT(bite.forces_size(), 5);
  EXPECT_THAT(bite.outcome(), ::testing::AnyOf("success", "failure"));
  EXPECT_EQ(bite.learned(), "learned");
  EXPECT_FALSE(bite.haptic().label().empty());
  EXPECT_EQ(state.summary().attempts(), 1);
  EXPECT_EQ(state.bites_size(), 1);

  // The BanditService holds the completed event, as the person was told.
  const std::vector<v1::Event> events = Events();
  ASSERT_EQ(events.size(), 1u);
  EXPECT_TRUE(events[0].completed());
  EXPECT_EQ(events[0].event_id(), bite.event_id());
  EXPECT_EQ(events[0].meal_id(), "lunch");
  EXPECT_EQ(events[0].item_label(), bite.item_label());
  EXPECT_EQ(events[0].loss(), bite.outcome() == "success" ? 0.0 : 1.0);
  EXPECT_EQ(events[0].posthoc_size(), 4);

  // A new user's context ridge is rho_c x the featurizer's E||c||^2, and
  // its learner post hoc LinUCB (the default).
  absl::StatusOr<v1::User> user = clients_->bandit.GetUser(options_.user_id);
  ASSERT_OK(user.status());
  EXPECT_EQ(user->config().learner(), v1::LEARNER_POSTHOC);
  EXPECT_GT(user->config().lambda_c(), 0.0);
  EXPECT_THAT(listener_.notes(),
              ::testing::Contains(HasSubstr("context ridge lambda_c")));
}

TEST(ParseLearnerTest, NamesFromTheApiAndThePosthocTheyNeed) {
  EXPECT_EQ(*ParseLearner("", PosthocMode::kLogProbabilities),
            v1::LEARNER_UNSPECIFIED);
  EXPECT_EQ(*ParseLearner("polinucb", PosthocMode::kProbabilities),
            v1::LEARNER_POLINUCB);
  EXPECT_EQ(*ParseLearner("context_only", PosthocMode::kNone),
            v1::LEARNER_CONTEXT_ONLY);
  absl::StatusOr<v1::Learner> unknown =
      ParseLearner("thompson", PosthocMode::kLogProbabilities);
  EXPECT_THAT(unknown.status(),
              StatusIs(absl::StatusCode::kInvalidArgument,
                       HasSubstr("expected one of posthoc, context_only, "
                                 "polinucb, got thompson")));
  EXPECT_THAT(
      ParseLearner("unspecified", PosthocMode::kLogProbabilities).status(),
      StatusIs(absl::StatusCode::kInvalidArgument, HasSubstr("got")));
  EXPECT_THAT(ParseLearner("polinucb", PosthocMode::kNone).status(),
              StatusIs(absl::StatusCode::kInvalidArgument,
                       HasSubstr("--posthoc=logprob or prob")));
}

// A new user with --learner=polinucb gets poLinUCB and learns from its
// bites through the real services.
TEST_F(MealTest, AChosenLearnerIsTheNewUsers) {
  options_.learner = v1::LEARNER_POLINUCB;
  auto meal = NewMeal();
  ASSERT_OK(meal->LookAtPlate());
  ASSERT_OK(meal->Bite(std::nullopt));
  ASSERT_OK(meal->LookAtPlate());
  ASSERT_OK(meal->Bite(std::nullopt));
  absl::StatusOr<v1::User> user = clients_->bandit.GetUser(options_.user_id);
  ASSERT_TRUE(user.ok()) << user.status();
  EXPECT_EQ(user->config().learner(), v1::LEARNER_POLINUCB);
  EXPECT_EQ(user->model_version(), 2);
  for (const v1::Event& event : Events()) {
    EXPECT_TRUE(event.completed());
    EXPECT_EQ(event.posthoc_size(), 4);
  }
}

// A person's actions are the robot's by name, in any order: the bandit's
// first choice (index 0, untrained) is TA90 here, and the bite is told as
// TA90, not as the robot's action 0.
TEST_F(MealTest, ThePersonsActionsAreTheRobotsByName) {
  ASSERT_OK(
      CreateUserWithActions({"TA90", "TA0", "TV90", "TV0", "VS90", "VS0"}));
  auto meal = NewMeal();
  ASSERT_OK(meal->LookAtPlate());
  ASSERT_OK(meal->Bite(std::nullopt));
  const mealpb::Bite bite = meal->state().current();
  EXPECT_EQ(bite.action().index(), 0);
  EXPECT_EQ(bite.action().name(), "TA90");
  EXPECT_EQ(bite.action().title(), "Tilted, angled, turned");
  const std::vector<v1::Event> events = Events();
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].action(), 0);
  EXPECT_TRUE(events[0].completed());
}

// An action the robot does not have is refused before the arm moves,
// naming it and the robot's actions; the selection stays pending.
TEST_F(MealTest, AnActionTheRobotLacksIsRefusedByName) {
  ASSERT_OK(CreateUserWithActions({"SCOOP", "VS0"}));
  auto meal = NewMeal();
  ASSERT_OK(meal->LookAtPlate());
  EXPECT_THAT(
      meal->Bite(std::nullopt),
      StatusIs(absl::StatusCode::kFailedPrecondition,
               HasSubstr("chose action \"SCOOP\" for " + options_.user_id +
                         " but the robot has no action of that name "
                         "(it has TA0, TA90, TV0, TV90, VS0, VS90)")));
  // The arm never started.
  for (const auto& [step, state] : listener_.Steps()) {
    EXPECT_FALSE(step == mealpb::STEP_ACQUIRE &&
                 state == mealpb::STEP_STATE_STARTED);
  }
  const std::vector<v1::Event> events = Events();
  ASSERT_EQ(events.size(), 1u);
  EXPECT_FALSE(events[0].completed());
}

TEST_F(MealTest, ThePersonChoosesTheItem) {
  auto meal = NewMeal();
  ASSERT_OK(meal->LookAtPlate());
  const mealpb::MealState looked = meal->state();
  ASSERT_GE(looked.items_size(), 3);
  ASSERT_OK(meal->Bite(2));
  const mealpb::Bite bite = meal->state().current();
  EXPECT_EQ(bite.item_index(), 2);
  EXPECT_FALSE(bite.robots_choice());
  EXPECT_EQ(bite.item_label(),
            absl::StrFormat("item@%.0f,%.0f", looked.items(2).center_px().u(),
                            looked.items(2).center_px().v()));
}

// Each bite aims at a look of its own: a bite may have taken or moved the
// items of the look before it, and a failed look leaves nothing to aim at
// (the items of the look before used to stay, and be bitten at).
TEST_F(MealTest, EveryBiteNeedsALookOfItsOwn) {
  auto meal = NewMeal();
  ASSERT_OK(meal->LookAtPlate());
  EXPECT_TRUE(meal->state().plate_fresh());
  ASSERT_OK(meal->Bite(std::nullopt));
  EXPECT_FALSE(meal->state().plate_fresh());
  EXPECT_THAT(meal->Bite(0),
              StatusIs(absl::StatusCode::kFailedPrecondition,
                       HasSubstr("look at the plate again before a bite: the "
                                 "items shown were seen before bite 1")));
  EXPECT_EQ(meal->state().bites_size(), 1);
  EXPECT_EQ(Events().size(), 1u);

  // A look that fails forgets the plate.
  services_->faults().Fail("/bitewise.v1.PerceptionService/DetectFood",
                           absl::UnavailableError("the service is down"));
  EXPECT_FALSE(meal->LookAtPlate().ok());
  EXPECT_EQ(meal->state().items_size(), 0);
  EXPECT_FALSE(meal->state().plate_fresh());
  EXPECT_THAT(meal->Bite(std::nullopt),
              StatusIs(absl::StatusCode::kFailedPrecondition,
                       HasSubstr("the last look at the plate failed")));
  EXPECT_EQ(Events().size(), 1u);

  services_->faults().Clear();
  ASSERT_OK(meal->LookAtPlate());
  ASSERT_OK(meal->Bite(std::nullopt));
  EXPECT_EQ(Events().size(), 2u);
}

// A look may move the arm (back to its viewing pose, on the JACO2): one
// asked for before a STOP is not run after it.
TEST_F(MealTest, ALookAskedForBeforeAStopIsNotRun) {
  auto meal = NewMeal();
  const uint64_t asked = meal->stops();
  ASSERT_OK(meal->Stop().status());
  EXPECT_THAT(meal->LookAtPlate(asked),
              StatusIs(absl::StatusCode::kFailedPrecondition,
                       HasSubstr("STOP was pressed after this look at the "
                                 "plate was asked for; nothing was moved")));
  EXPECT_EQ(meal->state().plate_version(), 0);
  ASSERT_OK(meal->LookAtPlate(meal->stops()));
  EXPECT_TRUE(meal->state().plate_fresh());
}

TEST_F(MealTest, AnItemNotOnThePlateChangesNothing) {
  auto meal = NewMeal();
  EXPECT_THAT(meal->Bite(0), StatusIs(absl::StatusCode::kFailedPrecondition,
                                      HasSubstr("look at the plate")));
  ASSERT_OK(meal->LookAtPlate());
  const int count = meal->state().items_size();
  EXPECT_THAT(meal->Bite(count), StatusIs(absl::StatusCode::kInvalidArgument,
                                          HasSubstr("is not on the plate")));
  EXPECT_THAT(meal->Bite(-1),
              StatusIs(absl::StatusCode::kInvalidArgument, ::testing::_));
  EXPECT_EQ(meal->state().bites_size(), 0);
  EXPECT_EQ(meal->state().bite(), 0);
  EXPECT_TRUE(Events().empty());
}

TEST_F(MealTest, OperatorAnswerCanChangeAndIsLearnedWhenFinal) {
  options_.confirm = ConfirmBy::kOperator;
  auto meal = NewMeal();
  ASSERT_OK(meal->LookAtPlate());
  ASSERT_OK(meal->Bite(std::nullopt));
  mealpb::Bite bite = meal->state().current();
  // The question names the food and the action.
  EXPECT_THAT(bite.question(), ::testing::StartsWith(
                                   absl::StrCat("Bite ", bite.number(), ": ")));
  EXPECT_THAT(bite.question(), HasSubstr(bite.food()));
  EXPECT_THAT(bite.question(), HasSubstr(bite.action().name()));
  EXPECT_EQ(bite.outcome(), "pending");
  EXPECT_EQ(bite.learned(), "awaiting answer");
  EXPECT_EQ(meal->state().summary().attempts(), 0);
  // Nothing is learned before the answer.
  ASSERT_EQ(Events().size(), 1u);
  EXPECT_FALSE(Events()[0].completed());

  EXPECT_THAT(meal->Answer("no-such-event", true),
              StatusIs(absl::StatusCode::kNotFound, ::testing::_));
  ASSERT_OK(meal->Answer(bite.event_id(), true));
  EXPECT_EQ(meal->state().current().answer(), "yes");
  EXPECT_EQ(meal->state().summary().text(), "1 attempt, 0 failures");
  // Changed once: still not learned, but saved.
  ASSERT_OK(meal->Answer(bite.event_id(), false));
  bite = meal->state().current();
  EXPECT_EQ(bite.answer(), "no");
  EXPECT_EQ(bite.learned(), "answer saved");
  EXPECT_EQ(meal->state().summary().text(), "1 attempt, 1 failure");
  EXPECT_FALSE(Events()[0].completed());
  absl::StatusOr<std::vector<JournaledUpdate>> saved = journal_->ReadAll();
  ASSERT_OK(saved.status());
  ASSERT_EQ(saved->size(), 2u);
  EXPECT_EQ(saved->back().loss, 1.0);

  // The next bite makes the answer final: learned as "no".
  ASSERT_OK(meal->LookAtPlate());
  ASSERT_OK(meal->Bite(std::nullopt));
  const mealpb::MealState state = meal->state();
  EXPECT_EQ(state.bites(0).learned(), "learned");
  EXPECT_TRUE(state.bites(0).question().empty());
  // Only the current bite keeps its force samples.
  EXPECT_EQ(state.bites(0).forces_size(), 0);
  EXPECT_GT(state.bites(1).forces_size(), 0);
  std::vector<v1::Event> events = Events();
  ASSERT_EQ(events.size(), 2u);
  EXPECT_TRUE(events[0].completed());
  EXPECT_EQ(events[0].loss(), 1.0);
  EXPECT_EQ(events[0].posthoc_size(), 4);
  EXPECT_TRUE(journal_->ReadAll()->empty());
  // Finishing the meal settles the second bite: unanswered, not learned.
  EXPECT_THAT(meal->Answer(state.bites(0).event_id(), true),
              StatusIs(absl::StatusCode::kNotFound, ::testing::_));
  ASSERT_OK(meal->Finish());
  EXPECT_EQ(meal->state().bites(1).learned(), "not learned");
  EXPECT_FALSE(Events()[1].completed());
  EXPECT_THAT(meal->Answer(state.bites(1).event_id(), true),
              StatusIs(absl::StatusCode::kFailedPrecondition, ::testing::_));
  EXPECT_EQ(meal->state().phase(), "ended");
  EXPECT_THAT(meal->LookAtPlate(),
              StatusIs(absl::StatusCode::kFailedPrecondition, ::testing::_));
}

// An operator's answer the BanditService refuses for good is dropped from
// the journal: the bite says "not learned" and why, not "learned" (it did:
// any delivery from the journal counted as this answer's).
TEST_F(MealTest, AnAnswerTheBanditRefusesIsNotCalledLearned) {
  options_.confirm = ConfirmBy::kOperator;
  auto meal = NewMeal();
  ASSERT_OK(meal->LookAtPlate());
  ASSERT_OK(meal->Bite(std::nullopt));
  const mealpb::Bite bite = meal->state().current();
  services_->faults().Fail(
      "/bitewise.v1.BanditService/Update",
      absl::FailedPreconditionError("the user was reset meanwhile"));
  ASSERT_OK(meal->Answer(bite.event_id(), false));
  meal->ConfirmAnswer();
  const mealpb::Bite after = meal->state().current();
  EXPECT_EQ(after.learned(), "not learned");
  EXPECT_THAT(after.text(),
              HasSubstr("not learned: the BanditService refused it"));
  EXPECT_THAT(after.error(), HasSubstr("the user was reset meanwhile"));
  EXPECT_TRUE(journal_->ReadAll()->empty());  // dropped, not kept
  EXPECT_FALSE(Events()[0].completed());
  services_->faults().Clear();
}

TEST_F(MealTest, StopDuringTheDescentEndsTheBiteAsStopped) {
  auto meal = NewMeal();
  ASSERT_OK(meal->LookAtPlate());
  std::optional<absl::StatusOr<v1::StopResponse>> stopped;
  std::thread stopper;
  listener_.SetHook([&](const mealpb::BiteEvent& e) {
    if (e.phase() == v1::ACQUIRE_PHASE_DESCEND && !stopper.joinable()) {
      stopper = std::thread([&] { stopped = meal->Stop(); });
    }
  });
  EXPECT_THAT(meal->Bite(std::nullopt),
              StatusIs(absl::StatusCode::kAborted, ::testing::_));
  listener_.SetHook(nullptr);
  ASSERT_TRUE(stopper.joinable());
  stopper.join();
  ASSERT_TRUE(stopped.has_value());
  ASSERT_OK(stopped->status());
  EXPECT_TRUE((*stopped)->was_moving());
  const mealpb::MealState state = meal->state();
  EXPECT_TRUE(state.stopped());
  EXPECT_EQ(state.current().outcome(), "stopped");
  EXPECT_EQ(state.current().learned(), "not learned");
  EXPECT_THAT(state.message(), HasSubstr("Stopped by STOP during descend"));
  EXPECT_EQ(state.summary().attempts(), 0);
  // The selected event stays pending; nothing was learned.
  ASSERT_EQ(Events().size(), 1u);
  EXPECT_FALSE(Events()[0].completed());
  // The meal goes on.
  ASSERT_OK(meal->LookAtPlate());
  ASSERT_OK(meal->Bite(std::nullopt));
  EXPECT_EQ(meal->state().current().learned(), "learned");
}

// STOP pressed after a bite was asked for, while it is being chosen (the
// arm idle, so the robot's own Stop finds nothing to stop), ends the bite
// before the arm moves.
TEST_F(MealTest, StopWhileTheBiteIsChosenEndsItBeforeTheArmMoves) {
  auto meal = NewMeal();
  ASSERT_OK(meal->LookAtPlate());
  std::optional<absl::StatusOr<v1::StopResponse>> stopped;
  listener_.SetHook([&](const mealpb::BiteEvent& e) {
    if (e.step() == mealpb::STEP_CHOOSE && !stopped.has_value()) {
      stopped = meal->Stop();
    }
  });
  EXPECT_THAT(meal->Bite(std::nullopt),
              StatusIs(absl::StatusCode::kAborted,
                       HasSubstr("Stopped by STOP before the arm moved")));
  listener_.SetHook(nullptr);
  ASSERT_TRUE(stopped.has_value());
  ASSERT_OK(stopped->status());
  EXPECT_FALSE((*stopped)->was_moving());
  const mealpb::MealState state = meal->state();
  EXPECT_TRUE(state.stopped());
  EXPECT_EQ(state.current().outcome(), "stopped");
  EXPECT_EQ(state.current().learned(), "not learned");
  EXPECT_EQ(state.summary().attempts(), 0);
  for (const mealpb::BiteEvent& step : state.current().steps()) {
    EXPECT_NE(step.state(), mealpb::STEP_STATE_PROGRESS) << "the arm moved";
  }
  ASSERT_EQ(Events().size(), 1u);
  EXPECT_FALSE(Events()[0].completed());
  // The next bite is not cancelled by that STOP.
  ASSERT_OK(meal->LookAtPlate());
  ASSERT_OK(meal->Bite(std::nullopt));
  EXPECT_EQ(meal->state().current().learned(), "learned");
}

// A console queues a bite: a STOP pressed after it was asked for but before
// it started running ends it before the arm moves.
TEST_F(MealTest, StopWhileTheBiteWaitsToStartEndsItBeforeTheArmMoves) {
  auto meal = NewMeal();
  ASSERT_OK(meal->LookAtPlate());
  const uint64_t asked = meal->stops();
  absl::StatusOr<v1::StopResponse> stopped = meal->Stop();
  ASSERT_OK(stopped.status());
  EXPECT_FALSE(stopped->was_moving());
  EXPECT_THAT(meal->Bite(std::nullopt, asked),
              StatusIs(absl::StatusCode::kAborted,
                       HasSubstr("Stopped by STOP before the arm moved")));
  EXPECT_TRUE(meal->state().stopped());
  EXPECT_EQ(meal->state().summary().attempts(), 0);
  // Asked for after that STOP, the next bite runs.
  ASSERT_OK(meal->LookAtPlate());
  ASSERT_OK(meal->Bite(std::nullopt, meal->stops()));
  EXPECT_EQ(meal->state().current().learned(), "learned");
}

// STOP pressed as the arm is told to start (the robot still idle, so its
// Stop does not carry over) is sent again at the robot's first progress
// report: the bite ends stopped in its approach.
TEST_F(MealTest, StopAsTheArmStartsIsSentAgainAndStopsIt) {
  auto meal = NewMeal();
  ASSERT_OK(meal->LookAtPlate());
  std::optional<absl::StatusOr<v1::StopResponse>> stopped;
  listener_.SetHook([&](const mealpb::BiteEvent& e) {
    if (e.step() == mealpb::STEP_ACQUIRE &&
        e.state() == mealpb::STEP_STATE_STARTED && !stopped.has_value()) {
      stopped = meal->Stop();
    }
  });
  EXPECT_THAT(meal->Bite(std::nullopt),
              StatusIs(absl::StatusCode::kAborted, ::testing::_));
  listener_.SetHook(nullptr);
  ASSERT_TRUE(stopped.has_value());
  ASSERT_OK(stopped->status());
  EXPECT_FALSE((*stopped)->was_moving());
  const mealpb::MealState state = meal->state();
  EXPECT_EQ(state.current().outcome(), "stopped");
  EXPECT_THAT(state.message(), HasSubstr("Stopped by STOP during approach"));
  EXPECT_EQ(state.summary().attempts(), 0);
}

TEST_F(MealTest, ASecondBiteWhileOneRunsIsRefused) {
  auto meal = NewMeal();
  ASSERT_OK(meal->LookAtPlate());
  std::optional<absl::Status> second;
  std::optional<absl::Status> look;
  listener_.SetHook([&](const mealpb::BiteEvent& e) {
    if (e.step() == mealpb::STEP_ACQUIRE && !second.has_value()) {
      second = meal->Bite(std::nullopt);
      look = meal->LookAtPlate();
    }
  });
  ASSERT_OK(meal->Bite(std::nullopt));
  listener_.SetHook(nullptr);
  ASSERT_TRUE(second.has_value());
  EXPECT_THAT(*second, StatusIs(absl::StatusCode::kFailedPrecondition,
                                HasSubstr("already running")));
  EXPECT_THAT(*look,
              StatusIs(absl::StatusCode::kFailedPrecondition, ::testing::_));
  EXPECT_EQ(meal->state().bites_size(), 1);
  EXPECT_EQ(Events().size(), 1u);
}

// The failure of each service at each step.
struct StepFault {
  const char* name;
  const char* method;
  mealpb::Step step;
  bool at_look;        // fails LookAtPlate rather than Bite
  int pending_events;  // selected but not learned
  // Of the bite: "" when no bite began, "verdict" for the robot's.
  const char* outcome;
  const char* told;  // part of what the person reads
};

// Names the case in test output and in CTest's test names (the default
// prints the struct's bytes, pointers included, which change every build).
void PrintTo(const StepFault& fault, std::ostream* os) { *os << fault.name; }

class MealFaultTest : public MealTest,
                      public ::testing::WithParamInterface<StepFault> {};

TEST_P(MealFaultTest, TellsWhatFailedAndKeepsWhatItMust) {
  const StepFault& fault = GetParam();
  auto meal = NewMeal();
  services_->faults().Fail(fault.method,
                           absl::UnavailableError("the service is down"));
  absl::Status status = meal->LookAtPlate();
  if (!fault.at_look) {
    ASSERT_OK(status);
    status = meal->Bite(std::nullopt);
  }
  EXPECT_THAT(status,
              StatusIs(absl::StatusCode::kUnavailable, HasSubstr(fault.told)));
  const mealpb::MealState state = meal->state();
  EXPECT_EQ(state.phase(), "failed");
  EXPECT_THAT(state.error(), HasSubstr(fault.told));
  EXPECT_THAT(state.message(), HasSubstr("the service is down"));
  const std::vector<mealpb::BiteEvent> events = listener_.events();
  ASSERT_FALSE(events.empty());
  EXPECT_EQ(events.back().step(), fault.step);
  EXPECT_EQ(events.back().state(), mealpb::STEP_STATE_FAILED);
  if (fault.at_look) {
    EXPECT_EQ(state.bites_size(), 0);
  } else {
    if (std::string(fault.outcome) == "verdict") {
      EXPECT_THAT(state.current().outcome(),
                  ::testing::AnyOf("success", "failure"));
    } else {
      EXPECT_EQ(state.current().outcome(), fault.outcome);
    }
    EXPECT_EQ(state.current().learned(), "not learned");
    EXPECT_THAT(state.current().text(), HasSubstr(fault.told));
  }
  const std::vector<v1::Event> stored = Events();
  ASSERT_EQ(static_cast<int>(stored.size()), fault.pending_events);
  for (const v1::Event& e : stored) EXPECT_FALSE(e.completed());
  EXPECT_TRUE(journal_->ReadAll()->empty());

  // With the service back, the meal goes on.
  services_->faults().Clear();
  ASSERT_OK(meal->LookAtPlate());
  ASSERT_OK(meal->Bite(std::nullopt));
  EXPECT_EQ(meal->state().current().learned(), "learned");
}

INSTANTIATE_TEST_SUITE_P(
    EachServiceAtEachStep, MealFaultTest,
    ::testing::Values(
        StepFault{"Capture", "/bitewise.v1.RobotService/CaptureFrame",
                  mealpb::STEP_CAPTURE, true, 0, "",
                  "RobotService.CaptureFrame failed: UNAVAILABLE"},
        StepFault{"Detect", "/bitewise.v1.PerceptionService/DetectFood",
                  mealpb::STEP_DETECT, true, 0, "",
                  "PerceptionService.DetectFood failed"},
        StepFault{"Featurize", "/bitewise.v1.PerceptionService/Featurize",
                  mealpb::STEP_FEATURIZE, false, 0, "error",
                  "PerceptionService.Featurize failed"},
        StepFault{"FindUser", "/bitewise.v1.BanditService/GetUser",
                  mealpb::STEP_FEATURIZE, false, 0, "error",
                  "BanditService.GetUser failed"},
        StepFault{"Select", "/bitewise.v1.BanditService/Select",
                  mealpb::STEP_SELECT, false, 0, "error",
                  "BanditService.Select failed"},
        StepFault{"Acquire", "/bitewise.v1.RobotService/Acquire",
                  mealpb::STEP_ACQUIRE, false, 1, "error",
                  "RobotService.Acquire failed"},
        StepFault{"Classify", "/bitewise.v1.HapticService/Classify",
                  mealpb::STEP_CLASSIFY, false, 1, "verdict",
                  "HapticService.Classify failed"}),
    [](const ::testing::TestParamInfo<StepFault>& info) {
      return std::string(info.param.name);
    });

// A failed haptic class keeps the robot's verdict: the bite counts as an
// attempt, though nothing is learned from it.
TEST_F(MealTest, ClassifyFailureKeepsTheVerdictButLearnsNothing) {
  auto meal = NewMeal();
  ASSERT_OK(meal->LookAtPlate());
  services_->faults().Fail("/bitewise.v1.HapticService/Classify",
                           absl::UnavailableError("haptic down"));
  EXPECT_THAT(meal->Bite(std::nullopt),
              StatusIs(absl::StatusCode::kUnavailable, ::testing::_));
  const mealpb::Bite bite = meal->state().current();
  EXPECT_THAT(bite.outcome(), ::testing::AnyOf("success", "failure"));
  EXPECT_EQ(meal->state().summary().attempts(), 1);
  EXPECT_THAT(bite.text(), HasSubstr("nothing is learned"));
}

// Vision only: without a haptic class the bite is still learned.
TEST_F(MealTest, VisionOnlyLearnsWithoutTheHapticService) {
  options_.posthoc = PosthocMode::kNone;
  auto meal = NewMeal();
  ASSERT_OK(meal->LookAtPlate());
  services_->faults().Fail("/bitewise.v1.HapticService/Classify",
                           absl::UnavailableError("haptic down"));
  ASSERT_OK(meal->Bite(std::nullopt));
  EXPECT_EQ(meal->state().current().learned(), "learned");
  const std::vector<v1::Event> events = Events();
  ASSERT_EQ(events.size(), 1u);
  EXPECT_TRUE(events[0].completed());
  EXPECT_EQ(events[0].posthoc_size(), 0);
  absl::StatusOr<v1::User> user = clients_->bandit.GetUser(options_.user_id);
  ASSERT_OK(user.status());
  EXPECT_EQ(user->config().learner(), v1::LEARNER_CONTEXT_ONLY);
}

// An Update the BanditService cannot take goes to the journal, and is
// delivered once the service is back.
TEST_F(MealTest, AnUpdateThatCannotBeDeliveredIsJournaled) {
  auto meal = NewMeal();
  ASSERT_OK(meal->LookAtPlate());
  services_->faults().Fail("/bitewise.v1.BanditService/Update",
                           absl::UnavailableError("bandit down"));
  ASSERT_OK(meal->Bite(std::nullopt));
  const mealpb::Bite bite = meal->state().current();
  EXPECT_EQ(bite.learned(), "journaled");
  EXPECT_THAT(bite.text(), HasSubstr("saved to be learned later"));
  EXPECT_THAT(bite.error(), HasSubstr("BanditService.Update failed"));
  absl::StatusOr<std::vector<JournaledUpdate>> saved = journal_->ReadAll();
  ASSERT_OK(saved.status());
  ASSERT_EQ(saved->size(), 1u);
  EXPECT_EQ((*saved)[0].event_id, bite.event_id());
  EXPECT_FALSE(Events()[0].completed());

  // Still down: the journal keeps it.
  EXPECT_EQ(*meal->DeliverJournal(), 0);
  EXPECT_EQ(journal_->ReadAll()->size(), 1u);
  services_->faults().Clear();
  EXPECT_EQ(*meal->DeliverJournal(), 1);
  EXPECT_TRUE(journal_->ReadAll()->empty());
  EXPECT_TRUE(Events()[0].completed());
  EXPECT_EQ(Events()[0].loss(), bite.outcome() == "success" ? 0.0 : 1.0);
}

// An answer given before a crash is delivered by the next run.
TEST_F(MealTest, AnAnswerSurvivesTheProcess) {
  options_.confirm = ConfirmBy::kOperator;
  std::string event_id;
  {
    auto meal = NewMeal();
    ASSERT_OK(meal->LookAtPlate());
    ASSERT_OK(meal->Bite(std::nullopt));
    event_id = meal->state().current().event_id();
    ASSERT_OK(meal->Answer(event_id, true));
    // The meal object is dropped without finishing, as a killed process.
  }
  EXPECT_FALSE(Events()[0].completed());
  auto next = NewMeal();
  EXPECT_EQ(*next->DeliverJournal(), 1);
  ASSERT_TRUE(Events()[0].completed());
  EXPECT_EQ(Events()[0].loss(), 0.0);
}

// The last item eaten, the plate is empty and the meal ends.
TEST_F(MealTest, AnEmptyPlateEndsTheMeal) {
  FourServicesOptions options;
  options.foods = {"carrot"};
  options.seed = 11;
  auto small = FourServices::Start(options);
  ASSERT_OK(small.status());
  ServiceClients clients((*small)->channels(), CallDeadlines());
  Meal meal(&clients, journal_.get(), options_, &listener_);
  int bites = 0;
  while (bites < 12) {
    ASSERT_OK(meal.LookAtPlate());
    if (!meal.state().running()) break;
    ASSERT_OK(meal.Bite(std::nullopt));
    ++bites;
  }
  const mealpb::MealState state = meal.state();
  EXPECT_EQ(state.phase(), "ended");
  EXPECT_EQ(state.items_size(), 0);
  EXPECT_THAT(state.message(), HasSubstr("The plate is empty"));
  EXPECT_EQ(state.summary().attempts(), bites);
  EXPECT_EQ(state.summary().failures(), bites - 1);
  EXPECT_THAT(meal.Bite(std::nullopt),
              StatusIs(absl::StatusCode::kFailedPrecondition, ::testing::_));
}

}  // namespace
}  // namespace bitewise::meals
