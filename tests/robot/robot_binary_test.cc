// End-to-end test of the real bitewise-robot binary in its default
// simulated backend: it starts, reports SERVING once the simulated Net F/T
// stream is live, runs an Acquire over gRPC with streamed progress, rejects
// bad input with the documented codes and drains on SIGTERM. It also writes
// the streamed messages as grpcurl-style JSON (trace shortened) to
// $TEST_TMPDIR-like temp dir, which is where docs/robot.md's example output
// comes from.
#include <grpcpp/client_context.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <memory>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "bitewise/v1/robot.grpc.pb.h"
#include "gmock/gmock.h"
#include "google/protobuf/util/json_util.h"
#include "gtest/gtest.h"
#include "services/common/channel.h"
#include "services/sim/scene.h"
#include "tests/common/child_process.h"

namespace bitewise {
namespace {

using ::testing::HasSubstr;

constexpr char kService[] = "bitewise.v1.RobotService";
constexpr uint64_t kSeed = 1;

std::unique_ptr<grpc::ClientContext> Ctx() {
  auto context = std::make_unique<grpc::ClientContext>();
  context->set_deadline(std::chrono::system_clock::now() +
                        std::chrono::seconds(60));
  return context;
}

std::string Json(const google::protobuf::Message& message) {
  std::string out;
  google::protobuf::util::JsonPrintOptions options;
  options.add_whitespace = true;
  EXPECT_TRUE(
      google::protobuf::util::MessageToJsonString(message, &out, options).ok());
  return out;
}

// A frozen-readings threshold below zero would turn the check into
// nonsense: the binary refuses to start, naming the flag.
TEST(RobotBinaryTest, RefusesANegativeFrozenReadingsThreshold) {
  testing::ChildProcess child;
  const std::string log = ::testing::TempDir() + "/robot_bad_flag.log";
  ASSERT_TRUE(child
                  .Start({BITEWISE_ROBOT_BINARY, "--listen=127.0.0.1:0",
                          "--ft_frozen_after_s=-0.5"},
                         log)
                  .ok());
  absl::StatusOr<int> exit = child.Wait(absl::Seconds(30));
  ASSERT_TRUE(exit.ok()) << exit.status();
  EXPECT_NE(*exit, 0);
  EXPECT_THAT(child.log(),
              HasSubstr("--ft_frozen_after_s must be 0 (off) or above 0 and "
                        "at most 2 s on --backend=sim, got -0.5"));
}

// Flags that would let the JACO2 move longer on a silent or frozen sensor,
// or toward a non-finite place, stop the start naming the flag (before any
// SDK or sensor is opened).
TEST(RobotBinaryTest, RefusesSettingsThatWouldLetTheArmMoveBlind) {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"--watchdog_s=0.5",
       "--watchdog_s must be 0 (the default) or above 0 and at most 0.25 s on "
       "--backend=jaco2, got 0.5"},
      {"--ft_silence_timeout_s=nan",
       "--ft_silence_timeout_s must be 0 (the default) or above 0 and at most "
       "0.25 s on --backend=jaco2, got nan"},
      {"--ft_frozen_after_s=0",
       "--ft_frozen_after_s must be above 0 and at most 0.25 s on "
       "--backend=jaco2, got 0"},
      {"--task_origin_in_base_m=0,nan,0",
       "--task_origin_in_base_m: nan m is not a finite number within 1 m"},
      {"--camera_height_m=-1",
       "--camera_height_m must be above 0 and at most 2 m, got -1"},
  };
  for (const auto& [flag, message] : cases) {
    testing::ChildProcess child;
    const std::string log = ::testing::TempDir() + "/robot_blind_flag.log";
    unlink(log.c_str());
    ASSERT_TRUE(child
                    .Start({BITEWISE_ROBOT_BINARY, "--listen=127.0.0.1:0",
                            "--backend=jaco2", flag},
                           log)
                    .ok());
    absl::StatusOr<int> exit = child.Wait(absl::Seconds(30));
    ASSERT_TRUE(exit.ok()) << exit.status();
    EXPECT_NE(*exit, 0) << flag;
    EXPECT_THAT(child.log(), HasSubstr(message)) << flag;
  }
}

TEST(RobotBinaryTest, SimulatedRobotEndToEnd) {
  testing::ChildProcess child;
  const std::string log = ::testing::TempDir() + "/robot_binary_test.log";
  std::string address;
  for (int attempt = 0; attempt < 5 && address.empty(); ++attempt) {
    absl::StatusOr<int> port = testing::PickFreePort();
    ASSERT_TRUE(port.ok()) << port.status();
    ASSERT_TRUE(child
                    .Start({BITEWISE_ROBOT_BINARY,
                            absl::StrCat("--listen=127.0.0.1:", *port),
                            absl::StrCat("--seed=", kSeed), "--watchdog_s=0.5",
                            "--ft_silence_timeout_s=0.3"},
                           log)
                    .ok());
    absl::Status up = child.WaitForLog(
        absl::StrCat("serving on 127.0.0.1:", *port, " "), absl::Seconds(60));
    if (up.ok()) {
      address = absl::StrCat("127.0.0.1:", *port);
    } else {
      ASSERT_THAT(std::string(up.message()),
                  HasSubstr("cannot start the server"));
    }
  }
  ASSERT_FALSE(address.empty());
  auto channel = MakeChannel(address, ChannelOptions());
  ASSERT_TRUE(channel.ok());
  ASSERT_TRUE(WaitForServing(*channel, kService, absl::Seconds(30)).ok())
      << child.log();
  auto stub = v1::RobotService::NewStub(*channel);

  v1::RobotStatus status;
  ASSERT_TRUE(stub->GetStatus(Ctx().get(), {}, &status).ok());
  EXPECT_TRUE(status.simulated());
  EXPECT_TRUE(status.ft_streaming());
  EXPECT_EQ(status.items_left(), 8);

  // The binary's plate is a function of the seed alone: the same plate here
  // gives a perfect detection of the first item.
  std::mt19937_64 rng(kSeed);
  const sim::PlateScene scene =
      sim::RandomPlate(sim::UnseenFoods(), /*allow_touching=*/false, rng);
  const sim::SceneItem& item = scene.items.at(0);
  v1::AcquireRequest request;
  request.set_action(1);
  v1::Point3* c = request.mutable_target()->mutable_center_camera_m();
  c->set_x(item.x_m);
  c->set_y(item.y_m);
  c->set_z(scene.camera_height_m - item.height_m);
  request.mutable_target()->set_major_axis_angle_rad(item.yaw_rad);

  auto context = Ctx();
  auto reader = stub->Acquire(context.get(), request);
  std::vector<v1::AcquireProgress> messages;
  v1::AcquireProgress progress;
  while (reader->Read(&progress)) messages.push_back(progress);
  grpc::Status finished = reader->Finish();
  ASSERT_TRUE(finished.ok()) << finished.error_message() << child.log();
  ASSERT_FALSE(messages.empty());
  const v1::AcquireResult& result = messages.back().result();
  EXPECT_EQ(result.true_food_type(), item.food->name);
  EXPECT_GT(result.trace_size(), 1000);
  EXPECT_GT(result.peak_force_n(), 1.0);

  // The example for docs/robot.md: the request, then every message, the
  // trace cut to three samples.
  std::ofstream example(::testing::TempDir() + "/robot_acquire_example.json");
  example << Json(request) << "\n";
  for (v1::AcquireProgress m : messages) {
    if (m.has_result()) {
      m.mutable_result()->mutable_trace()->DeleteSubrange(
          3, m.result().trace_size() - 3);
    }
    example << Json(m) << "\n";
  }

  request.set_action(9);
  auto bad_context = Ctx();
  auto bad = stub->Acquire(bad_context.get(), request);
  while (bad->Read(&progress)) {
  }
  grpc::Status rejected = bad->Finish();
  EXPECT_EQ(rejected.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(rejected.error_message(), HasSubstr("action 9 is out of range"));

  absl::StatusOr<int> exit = child.SignalAndWait(SIGTERM, absl::Seconds(30));
  ASSERT_TRUE(exit.ok()) << exit.status();
  EXPECT_TRUE(WIFEXITED(*exit) && WEXITSTATUS(*exit) == 0)
      << testing::DescribeWaitStatus(*exit) << child.log();
}

}  // namespace
}  // namespace bitewise
