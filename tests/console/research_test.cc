// The researcher view's answers (clients/console/research.h): tallies per
// meal and the events as CSV from given events, and all of a person's
// events and the per-action estimates from a real BanditService.
#include "clients/console/research.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "tests/common/status_matchers.h"
#include "tests/meal/four_services.h"

namespace bitewise::console {
namespace {

using ::bitewise::testing::FourServices;
using ::bitewise::testing::FourServicesOptions;
using ::bitewise::testing::IsOk;
using ::bitewise::testing::SharedFourServicesTest;
using ::bitewise::testing::StatusIs;
using ::testing::AllOf;
using ::testing::ElementsAre;
using ::testing::HasSubstr;

v1::Event MakeEvent(const std::string& id, const std::string& meal,
                    bool completed, double loss, int64_t selected_seconds) {
  v1::Event event;
  event.set_event_id(id);
  event.set_user_id("rita");
  event.set_meal_id(meal);
  event.set_completed(completed);
  if (completed) event.set_loss(loss);
  event.mutable_selected_at()->set_seconds(selected_seconds);
  return event;
}

TEST(MealsOfTest, MealsAreTalliedInTheOrderOfTheirFirstEvent) {
  const std::vector<v1::Event> events = {
      MakeEvent("1", "lunch", true, 0.5, 1700000000),  // a failure
      MakeEvent("2", "breakfast", true, 0.0, 1700000100),
      MakeEvent("3", "lunch", true, 0.49999, 1700000200),
      MakeEvent("4", "lunch", false, 0.0, 1700000300),
      MakeEvent("5", "breakfast", true, 1.0, 1700000400),
      MakeEvent("6", "lunch", true, 1.0, 1700000500),
  };
  const consolepb::MealsReply reply = MealsOf("rita", events);
  EXPECT_EQ(reply.user_id(), "rita");
  ASSERT_EQ(reply.meals_size(), 2);
  const consolepb::MealTally& lunch = reply.meals(0);
  EXPECT_EQ(lunch.meal_id(), "lunch");
  EXPECT_EQ(lunch.attempts(), 3);
  EXPECT_EQ(lunch.failures(), 2);
  EXPECT_EQ(lunch.pending(), 1);
  EXPECT_EQ(lunch.first_selected_at(), "2023-11-14T22:13:20Z");
  const consolepb::MealTally& breakfast = reply.meals(1);
  EXPECT_EQ(breakfast.meal_id(), "breakfast");
  EXPECT_EQ(breakfast.attempts(), 2);
  EXPECT_EQ(breakfast.failures(), 1);
  EXPECT_EQ(breakfast.pending(), 0);
  EXPECT_EQ(breakfast.first_selected_at(), "2023-11-14T22:15:00Z");

  EXPECT_EQ(MealsOf("nobody", {}).meals_size(), 0);
}

TEST(EventsCsvTest, OneRowPerEventWithCellsQuotedWhereTheyMustBe) {
  v1::Event done = MakeEvent("7", "lunch", true, 1.0, 1700000000);
  done.set_item_label("pea, \"sweet\"");
  done.set_action(3);
  done.set_propensity(0.1);
  done.add_posthoc(0.5);
  done.add_posthoc(-2.0);
  done.set_model_version(4);
  done.mutable_updated_at()->set_seconds(1700000001);
  done.mutable_updated_at()->set_nanos(500000000);
  done.add_context(1.0 / 3);
  done.add_context(2.0);
  v1::Event pending = MakeEvent("8", "tea\nbreak", false, 0.0, 1700000002);
  pending.set_item_label("kiwi");
  pending.set_propensity(1.0);

  const std::string header =
      "event_id,user_id,meal_id,item_label,action,propensity,completed,loss,"
      "posthoc,model_version,selected_at,updated_at";
  const std::string done_row =
      "7,rita,lunch,\"pea, \"\"sweet\"\"\",3,0.10000000000000001,true,1,"
      "0.5;-2,4,2023-11-14T22:13:20Z,2023-11-14T22:13:21.500Z";
  const std::string pending_row =
      "8,rita,\"tea\nbreak\",kiwi,0,1,false,0,,0,2023-11-14T22:13:22Z,";
  EXPECT_EQ(EventsCsv({done, pending}, false),
            header + "\r\n" + done_row + "\r\n" + pending_row + "\r\n");
  EXPECT_EQ(EventsCsv({done, pending}, true),
            header + ",context\r\n" + done_row + ",0.33333333333333331;2\r\n" +
                pending_row + ",\r\n");
  EXPECT_EQ(EventsCsv({}, false), header + "\r\n");
  // Vectors withheld from this identity: the column says so, not blank
  // cells that read as pending bites (WithholdContexts clears both).
  v1::Event hidden = done;
  hidden.clear_posthoc();
  hidden.clear_context();
  const std::string hidden_row =
      "7,rita,lunch,\"pea, \"\"sweet\"\"\",3,0.10000000000000001,true,1,"
      ",4,2023-11-14T22:13:20Z,2023-11-14T22:13:21.500Z";
  EXPECT_EQ(EventsCsv({hidden}, true, /*withheld=*/true),
            "event_id,user_id,meal_id,item_label,action,propensity,completed,"
            "loss,posthoc_withheld,model_version,selected_at,updated_at\r\n" +
                hidden_row + "\r\n");

  // Text a spreadsheet would run as a formula is shown, not run.
  v1::Event formula = MakeEvent("9", "=HYPERLINK(\"http://x/\",\"open\")",
                                false, 0.0, 1700000003);
  formula.set_item_label("-1+2");
  formula.set_propensity(1.0);
  EXPECT_EQ(EventsCsv({formula}, false),
            header +
                "\r\n9,rita,\"'=HYPERLINK(\"\"http://x/"
                "\"\",\"\"open\"\")\",\"'-1+2\","
                "0,1,false,0,,0,2023-11-14T22:13:23Z,\r\n");
}

// A person's events in a real BanditService (of the four services).
class ResearchTest : public SharedFourServicesTest<ResearchTest> {
 public:
  static FourServicesOptions Options() {
    FourServicesOptions options;
    options.foods = {"carrot"};
    return options;
  }

 protected:
  void SetUp() override {
    ASSERT_NE(services_, nullptr);
    clients_ = std::make_unique<meals::ServiceClients>(services_->channels(),
                                                       meals::CallDeadlines());
  }

  // A user with 3-dimensional contexts and these bites: (meal, context,
  // loss or pending).
  struct Bite {
    std::string meal;
    std::vector<double> context;
    double loss;  // < 0: pending
  };
  std::vector<std::string> Feed(const std::string& user_id,
                                const std::vector<Bite>& bites,
                                v1::Learner learner = v1::LEARNER_UNSPECIFIED) {
    v1::CreateUserRequest create;
    create.set_user_id(user_id);
    create.mutable_config()->set_learner(learner);
    create.mutable_config()->set_context_dim(3);
    create.mutable_config()->set_posthoc_dim(2);
    create.mutable_config()->set_lambda_c(1.0);
    EXPECT_THAT(clients_->bandit.CreateUser(create), IsOk());
    std::vector<std::string> ids;
    for (const Bite& bite : bites) {
      v1::SelectRequest select;
      select.set_user_id(user_id);
      select.set_meal_id(bite.meal);
      select.set_item_label("carrot");
      for (double v : bite.context) select.add_context(v);
      absl::StatusOr<v1::SelectResponse> selected =
          clients_->bandit.Select(select);
      EXPECT_THAT(selected, IsOk());
      if (!selected.ok()) return ids;
      ids.push_back(selected->event_id());
      if (bite.loss < 0) continue;
      v1::UpdateRequest update;
      update.set_event_id(selected->event_id());
      update.set_loss(bite.loss);
      update.add_posthoc(0.25);
      update.add_posthoc(-0.5);
      EXPECT_THAT(clients_->bandit.Update(update), IsOk());
    }
    return ids;
  }

  std::unique_ptr<meals::ServiceClients> clients_;
};

TEST_F(ResearchTest, AllEventsAreListedWithContextsOnlyWhenAsked) {
  const std::vector<std::string> ids =
      Feed("ada", {{"breakfast", {0.1, 0.2, 0.3}, 1.0},
                   {"lunch", {0.4, 0.5, 0.6}, 0.0},
                   {"lunch", {0.7, 0.8, 0.9}, -1}});
  ASSERT_EQ(ids.size(), 3u);
  bool withheld = true;
  absl::StatusOr<std::vector<v1::Event>> all =
      AllEvents(clients_->bandit, "ada", "", false, &withheld);
  ASSERT_THAT(all, IsOk());
  EXPECT_FALSE(withheld);
  ASSERT_EQ(all->size(), 3u);
  for (size_t i = 0; i < 3; ++i) {
    EXPECT_EQ((*all)[i].event_id(), ids[i]);
    EXPECT_EQ((*all)[i].context_size(), 0);
  }
  EXPECT_TRUE((*all)[1].completed());
  EXPECT_FALSE((*all)[2].completed());

  absl::StatusOr<std::vector<v1::Event>> lunch =
      AllEvents(clients_->bandit, "ada", "lunch", true, nullptr);
  ASSERT_THAT(lunch, IsOk());
  ASSERT_EQ(lunch->size(), 2u);
  EXPECT_THAT((*lunch)[0].context(), ElementsAre(0.4, 0.5, 0.6));
  EXPECT_THAT((*lunch)[1].context(), ElementsAre(0.7, 0.8, 0.9));

  EXPECT_THAT(AllEvents(clients_->bandit, "a da", "", false, nullptr),
              StatusIs(absl::StatusCode::kInvalidArgument, HasSubstr("a da")));
  EXPECT_THAT(AllEvents(clients_->bandit, "nobody", "", false, nullptr),
              StatusIs(absl::StatusCode::kNotFound,
                       HasSubstr("BanditService.ListEvents failed")));

  absl::StatusOr<v1::ListUsersResponse> users = AllUsers(clients_->bandit);
  ASSERT_THAT(users, IsOk());
  bool listed = false;
  for (const v1::User& user : users->users()) listed |= user.user_id() == "ada";
  EXPECT_TRUE(listed);
}

// A bite's estimates are the person's learner's own, as a Select at the
// bite's context computes them: theta_a . c for post hoc LinUCB; for
// poLinUCB theta_a . c plus beta_a . p_hat(c), which theta alone misses.
// Asking records nothing.
TEST_F(ResearchTest, EstimatesAreTheLearnersOwnAtTheBitesContext) {
  const std::vector<Bite> bites = {{"lunch", {1.0, 0.0, 0.5}, 1.0},
                                   {"lunch", {0.0, 1.0, -0.5}, 0.0},
                                   {"lunch", {0.3, -0.2, 0.9}, 1.0},
                                   {"lunch", {0.25, 0.5, -1.5}, -1}};
  const std::vector<double> context = {0.25, 0.5, -1.5};
  const std::vector<std::string> pia_ids =
      Feed("pia", bites, v1::LEARNER_POLINUCB);
  ASSERT_EQ(pia_ids.size(), 4u);
  absl::StatusOr<consolepb::EstimatesReply> pia =
      EstimatesFor(clients_->bandit, "pia", pia_ids[3]);
  ASSERT_THAT(pia, IsOk());
  EXPECT_EQ(pia->learner(), "LEARNER_POLINUCB");
  absl::StatusOr<v1::Model> pia_model = clients_->bandit.GetModel("pia");
  ASSERT_THAT(pia_model, IsOk());
  EXPECT_EQ(pia_model->model_version(), 3);  // nothing recorded by asking
  v1::SelectRequest select;
  select.set_user_id("pia");
  select.mutable_context()->Add(context.begin(), context.end());
  absl::StatusOr<v1::SelectResponse> selected = clients_->bandit.Select(select);
  ASSERT_THAT(selected, IsOk());
  ASSERT_EQ(pia->estimates_size(), selected->estimates_size());
  double largest_gap = 0.0;
  for (int a = 0; a < pia->estimates_size(); ++a) {
    EXPECT_EQ(pia->estimates(a).predicted_loss(),
              selected->estimates(a).predicted_loss())
        << a;
    EXPECT_EQ(pia->estimates(a).width(), selected->estimates(a).width()) << a;
    EXPECT_EQ(pia->estimates(a).lcb(), selected->estimates(a).lcb()) << a;
    double dot = 0.0;
    for (int i = 0; i < 3; ++i) {
      dot += pia_model->actions(a).theta(i) * context[i];
    }
    largest_gap = std::max(largest_gap,
                           std::abs(pia->estimates(a).predicted_loss() - dot));
  }
  EXPECT_GT(largest_gap, 1e-6);  // theta . c alone is not poLinUCB's

  const std::vector<std::string> ids = Feed("bea", bites);
  ASSERT_EQ(ids.size(), 4u);
  absl::StatusOr<v1::Model> model = clients_->bandit.GetModel("bea");
  ASSERT_THAT(model, IsOk());
  absl::StatusOr<v1::User> user = clients_->bandit.GetUser("bea");
  ASSERT_THAT(user, IsOk());

  absl::StatusOr<consolepb::EstimatesReply> reply =
      EstimatesFor(clients_->bandit, "bea", ids[3]);
  ASSERT_THAT(reply, IsOk());
  EXPECT_EQ(reply->event_id(), ids[3]);
  EXPECT_EQ(reply->user_id(), "bea");
  EXPECT_EQ(reply->learner(), "LEARNER_POSTHOC");
  EXPECT_EQ(reply->model_version(), 3);
  ASSERT_EQ(reply->estimates_size(), model->actions_size());
  ASSERT_EQ(reply->estimates_size(), 6);
  int64_t counted = 0;
  bool some_learned = false;
  for (int a = 0; a < reply->estimates_size(); ++a) {
    const v1::ActionModel& action = model->actions(a);
    ASSERT_EQ(action.theta_size(), 3);
    double dot = 0.0;
    for (int i = 0; i < 3; ++i) dot += action.theta(i) * context[i];
    EXPECT_NEAR(reply->estimates(a).predicted_loss(), dot, 1e-12) << a;
    EXPECT_GT(reply->estimates(a).width(), 0.0) << a;
    EXPECT_NEAR(reply->estimates(a).lcb(),
                dot - user->config().alpha() * reply->estimates(a).width(),
                1e-12)
        << a;
    EXPECT_EQ(reply->estimates(a).action(), action.action());
    EXPECT_EQ(reply->estimates(a).action_name(), action.action_name());
    EXPECT_EQ(reply->estimates(a).count(), action.count());
    counted += action.count();
    some_learned |= reply->estimates(a).predicted_loss() != 0.0;
  }
  EXPECT_EQ(counted, 3);
  EXPECT_TRUE(some_learned);
  user = clients_->bandit.GetUser("bea");
  ASSERT_THAT(user, IsOk());
  EXPECT_EQ(user->model_version(), 3);
  EXPECT_EQ(user->pending_events(), 1);  // the fourth bite, as it was

  for (const char* bad : {"x", "0", "-3", ""}) {
    EXPECT_THAT(EstimatesFor(clients_->bandit, "bea", bad),
                StatusIs(absl::StatusCode::kInvalidArgument,
                         HasSubstr(absl::StrCat("got \"", bad, "\""))));
  }
  const std::string other = Feed("cy", {{"tea", {1, 2, 3}, 0.0}})[0];
  EXPECT_THAT(EstimatesFor(clients_->bandit, "bea", other),
              StatusIs(absl::StatusCode::kNotFound,
                       HasSubstr(absl::StrCat("event ", other,
                                              " is not one of bea's"))));
  EXPECT_THAT(EstimatesFor(clients_->bandit, "nobody", ids[0]),
              StatusIs(absl::StatusCode::kNotFound, HasSubstr("nobody")));
}

}  // namespace
}  // namespace bitewise::console
