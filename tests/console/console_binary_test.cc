// The bitewise-console binary killed mid-meal (SIGKILL) after the operator
// answered: the answer, not yet sent, is in the journal, and the restarted
// console delivers it before anything else; the restarted console shows
// the robot idle and the person's model as the store has it. The four
// services run in this process; the console is the real binary.
#include <httplib.h>
#include <signal.h>

#include <string>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "tests/common/child_process.h"
#include "tests/meal/four_services.h"

namespace bitewise {
namespace {

using ::bitewise::testing::ChildProcess;
using ::bitewise::testing::FourServices;
using ::testing::HasSubstr;

const httplib::Headers kPost = {{"X-Bitewise-Request", "1"}};

class ConsoleBinaryTest : public ::testing::Test {
 protected:
  void SetUp() override {
    testing::FourServicesOptions options;
    options.foods = {"strawberry", "carrot", "banana"};
    auto started = FourServices::Start(options);
    ASSERT_TRUE(started.ok()) << started.status();
    services_ = *std::move(started);
    clients_ = std::make_unique<meals::ServiceClients>(services_->channels(),
                                                       meals::CallDeadlines());
  }

  // Starts the console binary; its port is picked afresh each time.
  void StartConsole(int run) {
    absl::StatusOr<int> port = testing::PickFreePort();
    ASSERT_TRUE(port.ok());
    port_ = *port;
    ASSERT_TRUE(
        console_
            .Start(
                {BITEWISE_CONSOLE_BINARY,
                 absl::StrCat("--listen=127.0.0.1:", port_),
                 absl::StrCat("--bandit=", services_->bandit_address()),
                 absl::StrCat("--perception=", services_->perception_address()),
                 absl::StrCat("--haptic=", services_->haptic_address()),
                 absl::StrCat("--robot=", services_->robot_address()),
                 "--confirm=operator",
                 absl::StrCat("--journal=", services_->dir(),
                              "/console.journal")},
                absl::StrCat(services_->dir(), "/console", run, ".log"))
            .ok());
    ASSERT_TRUE(
        console_.WaitForLog("bitewise-console: open", absl::Seconds(30)).ok())
        << console_.log();
  }

  httplib::Client Client() {
    httplib::Client client("127.0.0.1", port_);
    client.set_read_timeout(30, 0);
    return client;
  }

  // Polls GET /api/meal until its body has `text`.
  std::string WaitForMeal(const std::string& text) {
    const absl::Time deadline = absl::Now() + absl::Seconds(60);
    std::string body;
    while (absl::Now() < deadline) {
      auto reply = Client().Get("/api/meal");
      if (reply && reply->status == 200) {
        body = reply->body;
        if (absl::StrContains(body, text)) return body;
      }
      absl::SleepFor(absl::Milliseconds(50));
    }
    ADD_FAILURE() << "never saw " << text << " in " << body;
    return body;
  }

  std::vector<v1::Event> Events(const std::string& user) {
    v1::ListEventsRequest request;
    request.set_user_id(user);
    auto events = clients_->bandit.ListEvents(request);
    EXPECT_TRUE(events.ok()) << events.status();
    if (!events.ok()) return {};
    return {events->events().begin(), events->events().end()};
  }

  std::unique_ptr<FourServices> services_;
  std::unique_ptr<meals::ServiceClients> clients_;
  ChildProcess console_;
  int port_ = 0;
};

TEST_F(ConsoleBinaryTest, KilledMidMealLosesNoAnswer) {
  StartConsole(1);
  auto started = Client().Post("/api/meals", kPost,
                               R"({"user_id":"pat","meal_id":"supper"})",
                               "application/json");
  ASSERT_TRUE(started);
  ASSERT_EQ(started->status, 201) << started->body;
  WaitForMeal("\"phase\":\"choosing\"");
  auto bite = Client().Post("/api/meal/bite", kPost, R"({"item_index":-1})",
                            "application/json");
  ASSERT_TRUE(bite);
  ASSERT_EQ(bite->status, 202) << bite->body;
  WaitForMeal("\"learned\":\"awaiting answer\"");
  std::vector<v1::Event> events = Events("pat");
  ASSERT_EQ(events.size(), 1u);
  auto answered =
      Client().Post("/api/meal/answer", kPost,
                    absl::StrCat(R"({"event_id":")", events[0].event_id(),
                                 R"(","success":false})"),
                    "application/json");
  ASSERT_TRUE(answered);
  ASSERT_EQ(answered->status, 200) << answered->body;
  // Acknowledged, not yet learned: the answer may still change.
  EXPECT_FALSE(Events("pat")[0].completed());

  console_.Kill();  // SIGKILL
  EXPECT_FALSE(Events("pat")[0].completed());

  StartConsole(2);
  EXPECT_THAT(console_.log(), HasSubstr("journal: delivered 1 update(s)"));
  events = Events("pat");
  ASSERT_EQ(events.size(), 1u);
  EXPECT_TRUE(events[0].completed());
  EXPECT_EQ(events[0].loss(), 1.0);
  // The restarted console: no meal, the robot idle, the model as stored.
  auto meal = Client().Get("/api/meal");
  ASSERT_TRUE(meal);
  EXPECT_THAT(meal->body, HasSubstr("\"phase\":\"idle\""));
  EXPECT_THAT(meal->body, HasSubstr("\"running\":false"));
  auto robot = Client().Get("/api/robot");
  ASSERT_TRUE(robot);
  EXPECT_THAT(robot->body, HasSubstr("\"busy_with\":\"\""));
  auto model = Client().Get("/api/people/pat/model");
  ASSERT_TRUE(model);
  EXPECT_THAT(model->body, HasSubstr("\"model_version\":\"1\""));
  console_.SignalAndWait(SIGTERM, absl::Seconds(10)).IgnoreError();
}

}  // namespace
}  // namespace bitewise
