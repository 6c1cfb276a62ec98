// The real bitewise-camera binary as a child process: on the RealSense
// path (the fake SDK library) it serves the camera's frames to the
// RobotService's client and records them when asked; a missing SDK stops
// the start naming the library, and so does a frame size over
// --max_message_bytes; SIGTERM drains.
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "absl/time/time.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "services/camera/recording.h"
#include "services/common/channel.h"
#include "services/robot/camera_client.h"
#include "tests/common/child_process.h"

namespace bitewise::camera {
namespace {

using ::bitewise::testing::ChildProcess;
using ::bitewise::testing::DescribeWaitStatus;
using ::testing::HasSubstr;

constexpr char kService[] = "bitewise.v1.CameraService";

std::string LogPath() {
  return absl::StrCat(
      ::testing::TempDir(), "/camera_binary_test.",
      ::testing::UnitTest::GetInstance()->current_test_info()->name(), ".log");
}

void Spawn(ChildProcess& child, const std::vector<std::string>& args) {
  std::vector<std::string> argv = {BITEWISE_CAMERA_BINARY};
  argv.insert(argv.end(), args.begin(), args.end());
  const std::string log = LogPath();
  unlink(log.c_str());
  const absl::Status started = child.Start(argv, log);
  ASSERT_TRUE(started.ok()) << started;
}

// Starts the binary on the RealSense path (the fake SDK) on a free port with
// `flags`, waits until it serves, and connects the RobotService's client,
// whose channel accepts `max_message_bytes`.
void ServeRealSense(ChildProcess& child, const std::vector<std::string>& flags,
                    int max_message_bytes,
                    std::unique_ptr<robot::CameraClient>* client) {
  const absl::StatusOr<int> port = bitewise::testing::PickFreePort();
  ASSERT_TRUE(port.ok());
  std::vector<std::string> args = {
      "--source=realsense",
      absl::StrCat("--realsense_library=", BITEWISE_FAKE_REALSENSE),
      absl::StrCat("--listen=127.0.0.1:", *port)};
  args.insert(args.end(), flags.begin(), flags.end());
  ASSERT_NO_FATAL_FAILURE(Spawn(child, args));
  const std::string address = absl::StrCat("127.0.0.1:", *port);
  auto channel = MakeChannel(address, {});
  ASSERT_TRUE(channel.ok());
  const absl::Status serving =
      WaitForServing(*channel, kService, absl::Seconds(30));
  ASSERT_TRUE(serving.ok()) << serving << "; log:\n" << child.log();
  robot::CameraClientOptions options;
  options.address = address;
  options.channel.max_message_bytes = max_message_bytes;
  auto created = robot::CameraClient::Create(options);
  ASSERT_TRUE(created.ok()) << created.status();
  *client = *std::move(created);
}

TEST(CameraBinaryTest, ServesAndRecordsTheRealSensePath) {
  const std::string dir = ::testing::TempDir() + "/camera_binary_recording";
  std::filesystem::remove_all(dir);
  ChildProcess child;
  std::unique_ptr<robot::CameraClient> client;
  ASSERT_NO_FATAL_FAILURE(ServeRealSense(
      child, {"--fps=30", absl::StrCat("--record=", dir)}, 4 << 20, &client));
  absl::StatusOr<domain::RgbdFrame> frame = client->Capture();
  ASSERT_TRUE(frame.ok()) << frame.status() << "; log:\n" << child.log();
  EXPECT_FLOAT_EQ(frame->intrinsics.fx, 612.3f);  // the fake SDK's
  EXPECT_EQ(frame->depth_mm[10], 400);

  const absl::StatusOr<int> status =
      child.SignalAndWait(SIGTERM, absl::Seconds(30));
  ASSERT_TRUE(status.ok()) << status.status();
  ASSERT_TRUE(WIFEXITED(*status)) << DescribeWaitStatus(*status);
  EXPECT_EQ(WEXITSTATUS(*status), 0) << child.log();
  // What it recorded replays.
  auto replay = ReplaySource::Open(dir, {});
  ASSERT_TRUE(replay.ok()) << replay.status();
  absl::StatusOr<domain::RgbdFrame> first = (*replay)->Next();
  ASSERT_TRUE(first.ok()) << first.status();
  EXPECT_FLOAT_EQ(first->intrinsics.fx, 612.3f);
}

TEST(CameraBinaryTest, MissingSdkStopsTheStartNamingIt) {
  ChildProcess child;
  ASSERT_NO_FATAL_FAILURE(
      Spawn(child, {"--source=realsense",
                    "--realsense_library=/nonexistent/librealsense2.so.2.54",
                    "--listen=127.0.0.1:0"}));
  const absl::StatusOr<int> status = child.Wait(absl::Seconds(30));
  ASSERT_TRUE(status.ok()) << status.status();
  ASSERT_TRUE(WIFEXITED(*status)) << DescribeWaitStatus(*status);
  EXPECT_NE(WEXITSTATUS(*status), 0);
  EXPECT_THAT(child.log(), HasSubstr("/nonexistent/librealsense2.so.2.54"));
}

// 1280x720 frames are 4.6 MB, over the default 4 MiB message: the start
// stops, naming the size and every binary whose limit must be raised.
TEST(CameraBinaryTest, AFrameOverTheMessageLimitStopsTheStart) {
  ChildProcess child;
  ASSERT_NO_FATAL_FAILURE(Spawn(
      child, {"--source=realsense",
              absl::StrCat("--realsense_library=", BITEWISE_FAKE_REALSENSE),
              "--width=1280", "--height=720", "--listen=127.0.0.1:0"}));
  const absl::StatusOr<int> status = child.Wait(absl::Seconds(30));
  ASSERT_TRUE(status.ok()) << status.status();
  ASSERT_TRUE(WIFEXITED(*status)) << DescribeWaitStatus(*status);
  EXPECT_EQ(WEXITSTATUS(*status), 1);
  EXPECT_THAT(child.log(),
              HasSubstr("--width=1280 --height=720: a frame is about 4609024 "
                        "bytes, over --max_message_bytes (4194304); give "
                        "--max_message_bytes of at least 4609024 here, to "
                        "bitewise-robot"));
}

// A replay's frames are its recording's size: one over the limit stops the
// start too (it served, and every GetFrame failed).
TEST(CameraBinaryTest, AReplayOverTheMessageLimitStopsTheStart) {
  const std::string dir = ::testing::TempDir() + "/replay_1280x720";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  domain::CameraIntrinsics k;
  k.width = 1280;
  k.height = 720;
  k.cx = 640;
  k.cy = 360;
  ASSERT_TRUE(WriteRecordingHeader(dir, k, 15).ok());
  std::ofstream(dir + "/000000.rgb.png") << "the size is in camera.txt";
  ChildProcess child;
  ASSERT_NO_FATAL_FAILURE(Spawn(
      child,
      {"--source=replay", "--replay_dir=" + dir, "--listen=127.0.0.1:0"}));
  const absl::StatusOr<int> status = child.Wait(absl::Seconds(30));
  ASSERT_TRUE(status.ok()) << status.status();
  ASSERT_TRUE(WIFEXITED(*status)) << DescribeWaitStatus(*status);
  EXPECT_EQ(WEXITSTATUS(*status), 1);
  EXPECT_THAT(child.log(),
              HasSubstr("the recording's 1280x720 frames (replay:" + dir +
                        "): a frame is about 4609024 bytes, over "
                        "--max_message_bytes (4194304)"));
}

// With the limit raised as that message says, the frame is served whole.
TEST(CameraBinaryTest, ServesA1280x720FrameUnderARaisedLimit) {
  ChildProcess child;
  std::unique_ptr<robot::CameraClient> client;
  ASSERT_NO_FATAL_FAILURE(ServeRealSense(
      child, {"--width=1280", "--height=720", "--max_message_bytes=4609024"},
      64 << 20 /* as bitewise-robot's */, &client));
  absl::StatusOr<domain::RgbdFrame> frame = client->Capture();
  ASSERT_TRUE(frame.ok()) << frame.status() << "; log:\n" << child.log();
  EXPECT_EQ(frame->intrinsics.width, 1280);
  EXPECT_EQ(frame->intrinsics.height, 720);
}

}  // namespace
}  // namespace bitewise::camera
