// The console's meal host (clients/console/meal_host.h) called directly:
// a browser's subscription queue, and the host's requests with and
// without a meal against the four real services.
#include "clients/console/meal_host.h"

#include <memory>
#include <optional>
#include <regex>
#include <string>
#include <thread>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
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
using ::testing::HasSubstr;
using ::testing::StartsWith;

TEST(SubscriptionTest, FramesComeInOrderAndNextWaitsAtMostItsTimeout) {
  Subscription subscription;
  subscription.Push("a");
  subscription.Push("b");
  EXPECT_EQ(subscription.Next(absl::Seconds(1)), "a");
  EXPECT_EQ(subscription.Next(absl::Seconds(1)), "b");
  const absl::Time start = absl::Now();
  EXPECT_EQ(subscription.Next(absl::Milliseconds(50)), std::nullopt);
  EXPECT_GE(absl::Now() - start, absl::Milliseconds(45));
  EXPECT_FALSE(subscription.closed());

  // A frame pushed from another thread wakes a waiting Next.
  std::thread pusher([&] {
    absl::SleepFor(absl::Milliseconds(50));
    subscription.Push("c");
  });
  EXPECT_EQ(subscription.Next(absl::Seconds(10)), "c");
  pusher.join();
}

TEST(SubscriptionTest, AClosedSubscriptionHandsOutNothingMore) {
  Subscription subscription;
  subscription.Push("queued");
  subscription.Close();
  EXPECT_TRUE(subscription.closed());
  const absl::Time start = absl::Now();
  EXPECT_EQ(subscription.Next(absl::Seconds(10)), std::nullopt);
  EXPECT_LT(absl::Now() - start, absl::Seconds(5));  // at once
  subscription.Push("late");
  EXPECT_EQ(subscription.Next(absl::ZeroDuration()), std::nullopt);
}

TEST(SubscriptionTest, ABrowserTooFarBehindIsDropped) {
  Subscription subscription;
  for (int i = 0; i < 512; ++i) subscription.Push(absl::StrCat(i));
  EXPECT_FALSE(subscription.closed());
  EXPECT_EQ(subscription.Next(absl::ZeroDuration()), "0");
  subscription.Push("512");  // 512 queued again: still kept
  EXPECT_FALSE(subscription.closed());
  subscription.Push("513");  // one too many
  EXPECT_TRUE(subscription.closed());
  EXPECT_EQ(subscription.Next(absl::ZeroDuration()), std::nullopt);
}

class MealHostTest : public SharedFourServicesTest<MealHostTest> {
 public:
  static FourServicesOptions Options() {
    FourServicesOptions options;
    options.foods = {"carrot", "banana", "grape"};
    return options;
  }

 protected:
  void SetUp() override {
    ASSERT_NE(services_, nullptr);
    clients_ = std::make_unique<meals::ServiceClients>(services_->channels(),
                                                       meals::CallDeadlines());
    MealHostOptions options;
    options.journal_path = absl::StrCat(
        services_->dir(), "/host-",
        ::testing::UnitTest::GetInstance()->current_test_info()->name(),
        ".journal");
    host_ = std::make_unique<MealHost>(clients_.get(), options);
  }

  void TearDown() override { host_.reset(); }

  // Waits until the meal is in `phase` with `bites` bites.
  mealpb::MealState WaitForPhase(const std::string& phase, int bites = 0) {
    const absl::Time deadline = absl::Now() + absl::Seconds(60);
    mealpb::MealState state = host_->State();
    while ((state.phase() != phase || state.bites_size() != bites) &&
           absl::Now() < deadline) {
      absl::SleepFor(absl::Milliseconds(20));
      state = host_->State();
    }
    EXPECT_EQ(state.phase(), phase);
    EXPECT_EQ(state.bites_size(), bites);
    return state;
  }

  std::unique_ptr<meals::ServiceClients> clients_;
  std::unique_ptr<MealHost> host_;
};

TEST_F(MealHostTest, WithoutAMealEachRequestSaysSo) {
  EXPECT_EQ(host_->State().phase(), "idle");
  EXPECT_THAT(host_->Look(), StatusIs(absl::StatusCode::kFailedPrecondition,
                                      "no meal is running"));
  EXPECT_THAT(host_->Bite(std::nullopt),
              StatusIs(absl::StatusCode::kFailedPrecondition,
                       StartsWith("no meal is running")));
  EXPECT_THAT(host_->EndMeal(), StatusIs(absl::StatusCode::kFailedPrecondition,
                                         "no meal is running"));
  EXPECT_THAT(
      host_->Answer("1", true),
      StatusIs(absl::StatusCode::kFailedPrecondition, "no meal is running"));
  EXPECT_THAT(host_->PlateJpeg(),
              StatusIs(absl::StatusCode::kNotFound,
                       HasSubstr("has not looked at a plate yet")));
  EXPECT_THAT(host_->DeliverJournal(), IsOk());
  EXPECT_EQ(*host_->DeliverJournal(), 0);
  // STOP needs no meal.
  absl::StatusOr<v1::StopResponse> stopped = host_->Stop();
  ASSERT_THAT(stopped, IsOk());
  EXPECT_FALSE(stopped->was_moving());
}

TEST_F(MealHostTest, BadIdsAreRefusedAndStartNothing) {
  EXPECT_THAT(
      host_->StartMeal("a b", "lunch"),
      StatusIs(absl::StatusCode::kInvalidArgument, HasSubstr("user_id")));
  EXPECT_THAT(
      host_->StartMeal("ann", "lunch time"),
      StatusIs(absl::StatusCode::kInvalidArgument, HasSubstr("meal_id")));
  EXPECT_EQ(host_->State().phase(), "idle");
  EXPECT_EQ(host_->PlateJpeg().status().code(), absl::StatusCode::kNotFound);
}

// A look may move the arm back to its viewing pose (on the JACO2), so a
// bite that failed (a STOP, a collision, a sensor fault, a service down) is
// not followed by one by itself: the person asks ("Look at the plate
// again"). Before, every bite was.
TEST_F(MealHostTest, AFailedBiteIsNotFollowedByALookOfItsOwn) {
  ASSERT_THAT(host_->StartMeal("ines", "tea"), IsOk());
  const mealpb::MealState plate = WaitForPhase("choosing");
  services_->faults().Fail("/bitewise.v1.RobotService/Acquire",
                           absl::UnavailableError("the arm was halted"));
  ASSERT_THAT(host_->Bite(std::nullopt), IsOk());
  mealpb::MealState failed = WaitForPhase("failed", 1);
  services_->faults().Clear();
  absl::SleepFor(absl::Milliseconds(500));  // time for a look, were one due
  failed = host_->State();
  EXPECT_EQ(failed.phase(), "failed");
  EXPECT_EQ(failed.plate_version(), plate.plate_version());
  EXPECT_FALSE(failed.plate_fresh());
  EXPECT_THAT(host_->Bite(std::nullopt),
              StatusIs(absl::StatusCode::kFailedPrecondition,
                       HasSubstr("not been looked at since the last bite")));
  ASSERT_THAT(host_->Look(), IsOk());
  const mealpb::MealState again = WaitForPhase("choosing", 1);
  EXPECT_TRUE(again.plate_fresh());
  EXPECT_GT(again.plate_version(), plate.plate_version());
  ASSERT_THAT(host_->EndMeal(), IsOk());
  WaitForPhase("ended", 1);
}

TEST_F(MealHostTest, AMealRunsOnTheHostAndEverySubscriberSeesIt) {
  std::shared_ptr<Subscription> early = host_->Subscribe();
  std::optional<std::string> first = early->Next(absl::Seconds(1));
  ASSERT_TRUE(first.has_value());
  EXPECT_THAT(*first, AllOf(StartsWith("event: state\ndata: {"),
                            HasSubstr("\"phase\":\"idle\"")));

  absl::StatusOr<mealpb::MealState> started = host_->StartMeal("hana", "");
  ASSERT_THAT(started, IsOk());
  EXPECT_EQ(started->user_id(), "hana");
  EXPECT_TRUE(std::regex_match(started->meal_id(),
                               std::regex("meal-[0-9]{8}-[0-9]{6}")))
      << started->meal_id();
  const mealpb::MealState plate = WaitForPhase("choosing");
  ASSERT_GT(plate.items_size(), 0);

  // One meal at a time, named.
  EXPECT_THAT(host_->StartMeal("ivo", "supper"),
              StatusIs(absl::StatusCode::kFailedPrecondition,
                       HasSubstr(absl::StrCat("meal ", started->meal_id(),
                                              " for hana is running"))));
  EXPECT_THAT(host_->Bite(plate.items_size()),
              StatusIs(absl::StatusCode::kInvalidArgument,
                       HasSubstr(absl::StrCat("item_index ", plate.items_size(),
                                              " is not on the plate"))));
  EXPECT_THAT(host_->Bite(-1), StatusIs(absl::StatusCode::kInvalidArgument,
                                        HasSubstr("not on the plate")));
  absl::StatusOr<std::pair<int, std::string>> jpeg = host_->PlateJpeg();
  ASSERT_THAT(jpeg, IsOk());
  EXPECT_EQ(jpeg->first, plate.plate_version());
  EXPECT_EQ(jpeg->second.substr(0, 2), "\xff\xd8");

  // A subscriber that comes now is sent the current state first.
  std::shared_ptr<Subscription> late = host_->Subscribe();
  std::optional<std::string> now = late->Next(absl::Seconds(1));
  ASSERT_TRUE(now.has_value());
  EXPECT_THAT(*now, HasSubstr("\"phase\":\"choosing\""));

  ASSERT_THAT(host_->Bite(std::nullopt, plate.plate_version()), IsOk());
  const mealpb::MealState after = WaitForPhase("choosing", 1);
  ASSERT_EQ(after.bites_size(), 1);
  // A choice made on the look before (its numbers may name other items
  // now) is refused, naming both looks; nothing starts.
  EXPECT_THAT(
      host_->Bite(0, plate.plate_version()),
      StatusIs(absl::StatusCode::kFailedPrecondition,
               HasSubstr(absl::StrCat("the plate was looked at again since "
                                      "this choice (look ",
                                      plate.plate_version(), ", now ",
                                      after.plate_version(), ")"))));
  EXPECT_EQ(host_->State().bites_size(), 1);
  // The robot judged the bite: there is nothing to answer.
  EXPECT_THAT(host_->Answer(after.bites(0).event_id(), true),
              StatusIs(absl::StatusCode::kFailedPrecondition,
                       HasSubstr("no question is open")));
  ASSERT_THAT(host_->EndMeal(), IsOk());
  WaitForPhase("ended", 1);

  // Both saw the bite's progress and its end.
  for (const std::shared_ptr<Subscription>& subscription : {early, late}) {
    // Read until the meal's end arrives: it is sent after the state says
    // "ended", so a busy machine may deliver it late.
    std::string seen;
    const absl::Time deadline = absl::Now() + absl::Seconds(30);
    while (seen.find("\"phase\":\"ended\"") == std::string::npos &&
           absl::Now() < deadline) {
      if (std::optional<std::string> frame =
              subscription->Next(absl::Milliseconds(200))) {
        seen += *frame;
      }
    }
    EXPECT_THAT(seen, HasSubstr("event: progress"));
    EXPECT_THAT(seen, HasSubstr(absl::StrCat("\"event_id\":\"",
                                             after.bites(0).event_id(), "\"")));
    EXPECT_THAT(seen, HasSubstr("\"phase\":\"ended\""));
  }
  host_->CloseSubscriptions();
  EXPECT_TRUE(early->closed());
  EXPECT_TRUE(late->closed());

  // Now another meal may start.
  ASSERT_THAT(host_->StartMeal("ivo", "supper"), IsOk());
  WaitForPhase("choosing");
}

}  // namespace
}  // namespace bitewise::console
