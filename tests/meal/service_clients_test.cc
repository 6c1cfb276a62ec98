// The meal library's clients of the four services
// (clients/meal/service_clients.h): the channels a client's flags describe,
// with TLS only on the links named, and every call's failure naming the
// service and the call, against no server and against the real services.
#include "clients/meal/service_clients.h"

#include <memory>
#include <string>
#include <vector>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "tests/common/status_matchers.h"
#include "tests/meal/four_services.h"

namespace bitewise::meals {
namespace {

using ::bitewise::testing::FourServices;
using ::bitewise::testing::FourServicesOptions;
using ::bitewise::testing::IsOk;
using ::bitewise::testing::SharedFourServicesTest;
using ::bitewise::testing::StatusIs;
using ::testing::AllOf;
using ::testing::HasSubstr;
using ::testing::StartsWith;

ServiceLinks DistinctLinks() {
  ServiceLinks links;
  links.bandit = "127.0.0.1:1";
  links.perception = "127.0.0.1:2";
  links.haptic = "127.0.0.1:3";
  links.robot = "127.0.0.1:4";
  return links;
}

TEST(OpenServiceChannelsTest, PlaintextLinksOpenWithoutAServer) {
  absl::StatusOr<ServiceChannels> channels =
      OpenServiceChannels(DistinctLinks());
  ASSERT_THAT(channels, IsOk());
  EXPECT_NE(channels->bandit, nullptr);
  EXPECT_NE(channels->perception, nullptr);
  EXPECT_NE(channels->haptic, nullptr);
  EXPECT_NE(channels->robot, nullptr);
}

TEST(OpenServiceChannelsTest, AnUnknownTlsLinkIsRefusedNamingIt) {
  ServiceLinks links = DistinctLinks();
  links.tls_for = "bandit,camera";
  EXPECT_THAT(OpenServiceChannels(links),
              StatusIs(absl::StatusCode::kInvalidArgument,
                       AllOf(HasSubstr("unknown link \"camera\""),
                             HasSubstr("bandit, perception, haptic, robot"))));
  links.tls_for = "";
  EXPECT_THAT(OpenServiceChannels(links),
              StatusIs(absl::StatusCode::kInvalidArgument,
                       HasSubstr("unknown link \"\"")));
}

// TLS flags that would be dropped silently are refused: links named for
// TLS without a CA, a BanditService certificate name on a plaintext link.
TEST(OpenServiceChannelsTest, TlsFlagsThatWouldDoNothingAreRefused) {
  ServiceLinks links = DistinctLinks();
  links.tls_for = "bandit,perception";
  EXPECT_THAT(OpenServiceChannels(links),
              StatusIs(absl::StatusCode::kInvalidArgument,
                       HasSubstr("no CA file is given: every link would be "
                                 "plaintext")));
  links.tls_for = "all";
  links.bandit_tls_name = "bandit.facility";
  EXPECT_THAT(OpenServiceChannels(links),
              StatusIs(absl::StatusCode::kInvalidArgument,
                       HasSubstr("the bandit link is plaintext")));
  links.tls.tls_ca_file = "/nonexistent/ca.pem";
  links.tls_for = "robot";
  EXPECT_THAT(OpenServiceChannels(links),
              StatusIs(absl::StatusCode::kInvalidArgument,
                       HasSubstr("the bandit link is plaintext")));
}

// TLS whose CA file cannot be read fails exactly the links that use TLS,
// and the error names the first such link's address.
TEST(OpenServiceChannelsTest, TlsGoesOnlyToTheLinksNamed) {
  ServiceLinks links = DistinctLinks();
  links.tls.tls_ca_file = "/nonexistent/bitewise-ca.pem";
  struct Case {
    std::string tls_for;
    std::string failing_address;
  };
  const std::vector<Case> cases = {
      {"all", links.bandit},
      {"robot", links.robot},
      {"haptic,robot", links.haptic},
      {"robot,perception", links.perception},
  };
  for (const Case& c : cases) {
    links.tls_for = c.tls_for;
    absl::StatusOr<ServiceChannels> channels = OpenServiceChannels(links);
    ASSERT_FALSE(channels.ok()) << c.tls_for;
    EXPECT_THAT(std::string(channels.status().message()),
                AllOf(StartsWith(c.failing_address + ": "),
                      HasSubstr("/nonexistent/bitewise-ca.pem")))
        << c.tls_for;
  }
}

TEST(OpenServiceChannelsTest, ChannelOptionErrorsNameTheAddress) {
  ServiceLinks links = DistinctLinks();
  links.max_attempts = 6;
  EXPECT_THAT(OpenServiceChannels(links),
              StatusIs(absl::StatusCode::kInvalidArgument,
                       AllOf(StartsWith("127.0.0.1:1: "),
                             HasSubstr("max_attempts must be 1-5"))));
  links.max_attempts = 5;
  links.max_message_bytes = 0;
  EXPECT_THAT(OpenServiceChannels(links),
              StatusIs(absl::StatusCode::kInvalidArgument,
                       AllOf(StartsWith("127.0.0.1:1: "),
                             HasSubstr("max_message_bytes"))));
}

// Each call's failure, and the name it must carry.
struct NamedCall {
  std::string name;
  absl::Status status;
};

TEST(ServiceClientsTest, EveryCallToAnAbsentServiceIsUnavailableNamingIt) {
  absl::StatusOr<ServiceChannels> channels =
      OpenServiceChannels(DistinctLinks());
  ASSERT_THAT(channels, IsOk());
  CallDeadlines deadlines;
  deadlines.unary = absl::Seconds(5);
  deadlines.acquire = absl::Seconds(5);
  ServiceClients clients(*channels, deadlines);
  int progress_reports = 0;
  const std::vector<NamedCall> calls = {
      {"RobotService.CaptureFrame", clients.robot.CaptureFrame().status()},
      {"RobotService.GetStatus", clients.robot.GetStatus().status()},
      {"RobotService.Stop", clients.robot.Stop().status()},
      {"RobotService.Acquire",
       clients.robot
           .Acquire(v1::AcquireRequest(),
                    [&](const v1::AcquireProgress&) { ++progress_reports; })
           .status()},
      {"PerceptionService.DetectFood",
       clients.perception.DetectFood(v1::Frame()).status()},
      {"PerceptionService.Featurize",
       clients.perception.Featurize(v1::Frame(), v1::BoundingBox()).status()},
      {"HapticService.Classify", clients.haptic.Classify({}).status()},
      {"BanditService.GetUser", clients.bandit.GetUser("ann").status()},
      {"BanditService.CreateUser",
       clients.bandit.CreateUser(v1::CreateUserRequest()).status()},
      {"BanditService.ListUsers",
       clients.bandit.ListUsers(v1::ListUsersRequest()).status()},
      {"BanditService.Select",
       clients.bandit.Select(v1::SelectRequest()).status()},
      {"BanditService.Update",
       clients.bandit.Update(v1::UpdateRequest()).status()},
      {"BanditService.GetModel", clients.bandit.GetModel("ann").status()},
      {"BanditService.Estimate",
       clients.bandit.Estimate(v1::EstimateRequest()).status()},
      {"BanditService.ListEvents",
       clients.bandit.ListEvents(v1::ListEventsRequest()).status()},
  };
  for (const NamedCall& call : calls) {
    EXPECT_EQ(call.status.code(), absl::StatusCode::kUnavailable)
        << call.name << ": " << call.status;
    EXPECT_THAT(std::string(call.status.message()),
                StartsWith(call.name + " failed: UNAVAILABLE: "))
        << call.status;
  }
  EXPECT_EQ(progress_reports, 0);
}

// The real services: answers come through, and their errors are named.
class ServiceClientsWithServicesTest
    : public SharedFourServicesTest<ServiceClientsWithServicesTest> {
 public:
  static FourServicesOptions Options() {
    FourServicesOptions options;
    options.foods = {"carrot"};
    return options;
  }

 protected:
};

TEST_F(ServiceClientsWithServicesTest, AnswersComeThroughAndErrorsAreNamed) {
  ASSERT_NE(services_, nullptr);
  ServiceClients clients(services_->channels(), CallDeadlines());
  absl::StatusOr<v1::Frame> frame = clients.robot.CaptureFrame();
  ASSERT_THAT(frame, IsOk());
  EXPECT_EQ(frame->width(), 640u);
  EXPECT_EQ(frame->height(), 480u);
  absl::StatusOr<v1::DetectFoodResponse> found =
      clients.perception.DetectFood(*frame);
  ASSERT_THAT(found, IsOk());
  // The plate holds one carrot.
  EXPECT_EQ(found->items_size(), 1);

  EXPECT_THAT(clients.bandit.GetUser("nobody-at-all"),
              StatusIs(absl::StatusCode::kNotFound,
                       AllOf(StartsWith("BanditService.GetUser failed: "
                                        "NOT_FOUND: "),
                             HasSubstr("nobody-at-all"))));
  // A bad action is refused before the arm moves: no progress, and the
  // robot's own reason after the call's name.
  v1::AcquireRequest request;
  request.set_action(99);
  int progress_reports = 0;
  EXPECT_THAT(
      clients.robot.Acquire(
          request, [&](const v1::AcquireProgress&) { ++progress_reports; }),
      StatusIs(absl::StatusCode::kInvalidArgument,
               StartsWith("RobotService.Acquire failed: INVALID_ARGUMENT: ")));
  EXPECT_EQ(progress_reports, 0);
}

TEST_F(ServiceClientsWithServicesTest, ACallPastItsDeadlineIsNamed) {
  ASSERT_NE(services_, nullptr);
  CallDeadlines deadlines;
  deadlines.unary = -absl::Seconds(1);  // already past when sent
  ServiceClients clients(services_->channels(), deadlines);
  EXPECT_THAT(clients.robot.GetStatus(),
              StatusIs(absl::StatusCode::kDeadlineExceeded,
                       StartsWith("RobotService.GetStatus failed: "
                                  "DEADLINE_EXCEEDED: ")));
  EXPECT_THAT(clients.bandit.ListUsers(v1::ListUsersRequest()),
              StatusIs(absl::StatusCode::kDeadlineExceeded,
                       StartsWith("BanditService.ListUsers failed: ")));
}

}  // namespace
}  // namespace bitewise::meals
