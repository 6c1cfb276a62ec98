// The wrist camera path: RealSenseSource against a fake RealSense SDK
// library speaking the SDK's C interface (alignment requested, depth
// units applied, padded rows removed, every frame and error released);
// recordings written and replayed; the publisher's stale-frame refusal
// and dropped-frame count; and the CameraService read by the
// RobotService's CameraClient over gRPC, which never hands out a stale or
// repeated frame.
#include <dlfcn.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <tuple>
#include <vector>

#include "absl/strings/match.h"
#include "absl/time/clock.h"
#include "absl/time/time.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "services/camera/camera_service.h"
#include "services/camera/frame_publisher.h"
#include "services/camera/realsense_source.h"
#include "services/camera/recording.h"
#include "services/camera/sim_source.h"
#include "services/common/server.h"
#include "services/robot/camera_client.h"
#include "tests/common/test_certs.h"

namespace bitewise::camera {
namespace {

using ::testing::HasSubstr;

// The fake's steering functions, loaded once into this process. dlopen of
// the same path by the driver returns the same instance.
struct Fake {
  void* handle = dlopen(BITEWISE_FAKE_REALSENSE, RTLD_NOW | RTLD_LOCAL);
  template <typename Fn>
  Fn Get(const char* name) {
    return reinterpret_cast<Fn>(dlsym(handle, name));
  }
  void Reset() { Get<void (*)()>("FakeRealSense_Reset")(); }
  void NoDevice(bool v) { Get<void (*)(bool)>("FakeRealSense_SetNoDevice")(v); }
  void Stall(bool v) { Get<void (*)(bool)>("FakeRealSense_SetStalled")(v); }
  void Drop(int n) { Get<void (*)(int)>("FakeRealSense_DropFrames")(n); }
  void Units(float u) {
    Get<void (*)(float)>("FakeRealSense_SetDepthUnits")(u);
  }
  int WaitCalls() { return Get<int (*)()>("FakeRealSense_WaitCalls")(); }
  int StartCalls() { return Get<int (*)()>("FakeRealSense_StartCalls")(); }
  int LiveFrames() { return Get<int (*)()>("FakeRealSense_LiveFrames")(); }
  int LiveErrors() { return Get<int (*)()>("FakeRealSense_LiveErrors")(); }
  std::string Calls() {
    return Get<const char* (*)()>("FakeRealSense_Calls")();
  }
};

Fake& TheFake() {
  static Fake* fake = new Fake;
  return *fake;
}

RealSenseOptions FakeOptions() {
  RealSenseOptions options;
  options.library = BITEWISE_FAKE_REALSENSE;
  options.fps = 60;
  options.timeout_ms = 200;
  return options;
}

class RealSenseTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_NE(TheFake().handle, nullptr) << dlerror();
    TheFake().Reset();
  }
  void TearDown() override {
    // The driver released every frame and error it was given.
    EXPECT_EQ(TheFake().LiveFrames(), 0);
    EXPECT_EQ(TheFake().LiveErrors(), 0);
  }
};

TEST_F(RealSenseTest, FramesAreAlignedUnpaddedAndInMillimetres) {
  TheFake().Units(0.0001f);  // 100 um, a D415 setting
  auto source = RealSenseSource::Open(FakeOptions());
  ASSERT_TRUE(source.ok()) << source.status();
  absl::StatusOr<domain::RgbdFrame> frame = (*source)->Next();
  ASSERT_TRUE(frame.ok()) << frame.status();
  EXPECT_EQ(frame->intrinsics.width, 640);
  EXPECT_EQ(frame->intrinsics.height, 480);
  EXPECT_FLOAT_EQ(frame->intrinsics.fx, 612.3f);
  EXPECT_FLOAT_EQ(frame->intrinsics.cy, 238.9f);
  ASSERT_EQ(frame->rgb.size(), 640u * 480 * 3);
  for (int y : {0, 17, 479}) {
    for (int x : {0, 300, 639}) {
      const uint8_t* p = &frame->rgb[(static_cast<size_t>(y) * 640 + x) * 3];
      EXPECT_EQ(p[0], static_cast<uint8_t>(x));
      EXPECT_EQ(p[1], static_cast<uint8_t>(y));
      EXPECT_EQ(p[2], static_cast<uint8_t>(7 * frame->sequence));
    }
  }
  ASSERT_EQ(frame->depth_mm.size(), 640u * 480);
  EXPECT_EQ(frame->depth_mm[100], 400);
  EXPECT_EQ(frame->depth_mm[480 * 320 - 1], 380);
  EXPECT_EQ(frame->sequence, 1u);
  EXPECT_EQ((*source)->Next()->sequence, 2u);
  EXPECT_THAT(TheFake().Calls(), HasSubstr("rs2_process_frame"));
  EXPECT_THAT(TheFake().Calls(), ::testing::Not(HasSubstr("unaligned")));
  source->reset();
  EXPECT_THAT(TheFake().Calls(), HasSubstr("rs2_pipeline_stop"));
}

TEST_F(RealSenseTest, NoDeviceIsFailedPreconditionNamingTheCall) {
  TheFake().NoDevice(true);
  auto source = RealSenseSource::Open(FakeOptions());
  EXPECT_EQ(source.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(source.status().message(),
              HasSubstr("rs2_pipeline_start_with_config: No device connected"));
}

TEST_F(RealSenseTest, MissingOrWrongLibraryIsNamed) {
  RealSenseOptions options = FakeOptions();
  options.library = "/nonexistent/librealsense2.so";
  auto missing = RealSenseSource::Open(options);
  EXPECT_EQ(missing.status().code(), absl::StatusCode::kNotFound);
  EXPECT_THAT(missing.status().message(),
              HasSubstr("/nonexistent/librealsense2.so"));
  options.library = "libm.so.6";  // loads, but is not the SDK
  auto wrong = RealSenseSource::Open(options);
  EXPECT_EQ(wrong.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(wrong.status().message(), HasSubstr("rs2_create_context"));
}

TEST_F(RealSenseTest, AStalledCameraIsUnavailableAndThePublisherGoesStale) {
  auto source = RealSenseSource::Open(FakeOptions());
  ASSERT_TRUE(source.ok()) << source.status();
  FramePublisher publisher(*std::move(source));
  while (!publisher.Newest(0).ok()) absl::SleepFor(absl::Milliseconds(5));
  ASSERT_TRUE(publisher.Newest(0.5).ok());
  TheFake().Stall(true);
  absl::SleepFor(absl::Milliseconds(700));
  absl::StatusOr<PublishedFrame> stale = publisher.Newest(0.5);
  EXPECT_EQ(stale.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(stale.status().message(), HasSubstr("s old (limit 0.50 s)"));
  EXPECT_THAT(stale.status().message(), HasSubstr("Frame didn't arrive"));
  TheFake().Stall(false);
  absl::SleepFor(absl::Milliseconds(300));
  EXPECT_TRUE(publisher.Newest(0.5).ok());
}

// A USB cable that drops out: the SDK fails its reconnect and leaves the
// pipeline stopped, failing every later wait at once. The publisher must
// neither spin on that nor give up: the camera plugged back in is found.
TEST_F(RealSenseTest, ACameraUnpluggedIsFoundAgainWithoutSpinning) {
  auto opened = RealSenseSource::Open(FakeOptions());
  ASSERT_TRUE(opened.ok()) << opened.status();
  RealSenseSource* source = opened->get();
  FramePublisher publisher(*std::move(opened));
  while (publisher.Counters().frames_captured < 3) {
    absl::SleepFor(absl::Milliseconds(5));
  }
  TheFake().NoDevice(true);
  absl::SleepFor(absl::Milliseconds(300));  // the timeout passes
  const int waits_before = TheFake().WaitCalls();
  const int starts_before = TheFake().StartCalls();
  absl::SleepFor(absl::Seconds(1));
  // Ten tries a second at most: each a restart that fails (no wait), and
  // at least a few of them (it keeps trying).
  EXPECT_LE(TheFake().StartCalls() - starts_before, 12);
  EXPECT_GE(TheFake().StartCalls() - starts_before, 3);
  EXPECT_LE(TheFake().WaitCalls() - waits_before, 1);
  absl::StatusOr<PublishedFrame> gone = publisher.Newest(0.5);
  EXPECT_EQ(gone.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(gone.status().message(),
              HasSubstr("restarting the streams after \"RealSense "
                        "rs2_pipeline_wait_for_frames: Device disconnected"));
  EXPECT_THAT(gone.status().message(),
              HasSubstr("rs2_pipeline_start_with_config: No device connected"));
  const uint64_t last_sequence =
      publisher.Newest(0).ok() ? publisher.Newest(0)->frame.sequence : 0;
  ASSERT_GT(last_sequence, 0u);

  TheFake().NoDevice(false);  // plugged back in
  absl::StatusOr<PublishedFrame> back;
  for (int i = 0; i < 200 && !(back = publisher.Newest(0.5)).ok(); ++i) {
    absl::SleepFor(absl::Milliseconds(20));
  }
  ASSERT_TRUE(back.ok()) << back.status();
  // The device counts from 1 again; the published sequence keeps rising.
  EXPECT_GT(back->frame.sequence, last_sequence);
  EXPECT_GE(source->restarts(), 1);
}

TEST_F(RealSenseTest, ThePublisherCountsFramesTheCameraDropped) {
  auto source = RealSenseSource::Open(FakeOptions());
  ASSERT_TRUE(source.ok()) << source.status();
  FramePublisher publisher(*std::move(source));
  while (publisher.Counters().frames_captured < 2) {
    absl::SleepFor(absl::Milliseconds(5));
  }
  TheFake().Drop(5);
  const uint64_t seen = publisher.Counters().frames_captured;
  while (publisher.Counters().frames_captured < seen + 2) {
    absl::SleepFor(absl::Milliseconds(5));
  }
  EXPECT_EQ(publisher.Counters().frames_dropped, 5u);
}

std::string TempDir(const std::string& name) {
  const std::string dir = ::testing::TempDir() + "/" + name;
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

TEST(RecordingTest, ReplaysWhatWasRecordedThenEnds) {
  SimSourceOptions sim;
  sim.rate_hz = 1000;
  auto inner = SimSource::Create(sim);
  ASSERT_TRUE(inner.ok());
  const std::string dir = TempDir("recording");
  RecordingSource recorder(*std::move(inner), dir, 30.0);
  std::vector<domain::RgbdFrame> recorded;
  for (int i = 0; i < 3; ++i) recorded.push_back(*recorder.Next());
  ReplayOptions options;
  options.rate_hz = 200;
  auto replay = ReplaySource::Open(dir, options);
  ASSERT_TRUE(replay.ok()) << replay.status();
  for (int i = 0; i < 3; ++i) {
    absl::StatusOr<domain::RgbdFrame> frame = (*replay)->Next();
    ASSERT_TRUE(frame.ok()) << frame.status();
    EXPECT_EQ(frame->rgb, recorded[i].rgb);
    EXPECT_EQ(frame->depth_mm, recorded[i].depth_mm);
    EXPECT_EQ(frame->intrinsics.fx, recorded[i].intrinsics.fx);
    EXPECT_EQ(frame->sequence, static_cast<uint64_t>(i));
  }
  EXPECT_EQ((*replay)->Next().status().code(), absl::StatusCode::kOutOfRange);
  options.loop = true;
  auto looping = ReplaySource::Open(dir, options);
  for (int i = 0; i < 4; ++i) ASSERT_TRUE((*looping)->Next().ok());
  EXPECT_EQ((*looping)->Next()->rgb, recorded[1].rgb);
}

TEST(RecordingTest, BrokenRecordingsAreNamed) {
  const std::string dir = TempDir("broken");
  EXPECT_EQ(ReplaySource::Open(dir, {}).status().code(),
            absl::StatusCode::kNotFound);
  std::ofstream(dir + "/camera.txt") << "version 1\nwidth 640\nheight x\n";
  auto bad = ReplaySource::Open(dir, {});
  EXPECT_EQ(bad.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(bad.status().message(), HasSubstr("line 3"));
  ASSERT_TRUE(WriteRecordingHeader(dir, domain::CameraIntrinsics(), 30).ok());
  EXPECT_EQ(ReplaySource::Open(dir, {}).status().code(),
            absl::StatusCode::kFailedPrecondition);
  std::ofstream(dir + "/000000.rgb.png") << "not a png";
  auto replay = ReplaySource::Open(dir, {});
  ASSERT_TRUE(replay.ok());
  absl::StatusOr<domain::RgbdFrame> frame = (*replay)->Next();
  EXPECT_EQ(frame.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(frame.status().message(), HasSubstr("000000.rgb.png"));
}

// A second session into the same directory would replay the first's tail
// after it: refused, and recording is a side line of feeding, so the
// camera goes on serving frames when it cannot record (here, or after a
// full disk), the recording whole up to the frame before.
TEST(RecordingTest, ARecordingThatCannotGoOnStopsAndFramesFlow) {
  SimSourceOptions sim;
  sim.rate_hz = 1000;
  const std::string dir = TempDir("twice");
  {
    RecordingSource first(*SimSource::Create(sim), dir, 30.0);
    for (int i = 0; i < 3; ++i) ASSERT_TRUE(first.Next().ok());
    EXPECT_TRUE(first.recording_error().ok());
  }
  const absl::Status again = RecordingSource::CheckNewRecording(dir);
  EXPECT_EQ(again.code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(again.message(), HasSubstr("already holds a recording"));
  RecordingSource second(*SimSource::Create(sim), dir, 30.0);
  ASSERT_TRUE(second.Next().ok());  // a frame, not recorded
  EXPECT_EQ(second.recording_error().code(),
            absl::StatusCode::kFailedPrecondition);
  EXPECT_EQ(second.frames_written(), 0);
  auto replay = ReplaySource::Open(dir, {});
  ASSERT_TRUE(replay.ok());
  for (int i = 0; i < 3; ++i) ASSERT_TRUE((*replay)->Next().ok());
  EXPECT_EQ((*replay)->Next().status().code(), absl::StatusCode::kOutOfRange);

  // The directory gone and a file in its place (as good as a full disk).
  const std::string lost = TempDir("lost");
  RecordingSource recorder(*SimSource::Create(sim), lost, 30.0);
  ASSERT_TRUE(recorder.Next().ok());
  std::filesystem::remove_all(lost);
  std::ofstream(lost) << "not a directory";
  for (int i = 0; i < 3; ++i) {
    absl::StatusOr<domain::RgbdFrame> frame = recorder.Next();
    EXPECT_TRUE(frame.ok()) << frame.status();
  }
  EXPECT_EQ(recorder.frames_written(), 1);
  EXPECT_THAT(recorder.recording_error().message(), HasSubstr("cannot write"));
  std::filesystem::remove(lost);
}

// A frame cut short by a power loss is named and skipped, not read again
// forever: the replay goes on, and ends.
TEST(RecordingTest, ADamagedFrameIsSkippedAndTheReplayGoesOn) {
  SimSourceOptions sim;
  sim.rate_hz = 1000;
  const std::string dir = TempDir("damaged");
  {
    RecordingSource recorder(*SimSource::Create(sim), dir, 30.0);
    for (int i = 0; i < 3; ++i) ASSERT_TRUE(recorder.Next().ok());
  }
  std::filesystem::resize_file(dir + "/000001.depth.png", 40);
  ReplayOptions options;
  options.rate_hz = 500;
  auto replay = ReplaySource::Open(dir, options);
  ASSERT_TRUE(replay.ok());
  EXPECT_EQ((*replay)->Next()->sequence, 0u);
  absl::StatusOr<domain::RgbdFrame> damaged = (*replay)->Next();
  EXPECT_EQ(damaged.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(damaged.status().message(), HasSubstr("000001.depth.png"));
  EXPECT_EQ((*replay)->Next()->sequence, 2u);
  EXPECT_EQ((*replay)->Next().status().code(), absl::StatusCode::kOutOfRange);
}

// A recording's header is held to the rule every frame is: whole sides up
// to 8192 pixels, focal lengths of 1 to 10^6, the principal point near the
// image.
TEST(RecordingTest, AHeaderPerceptionWouldRefuseIsRefused) {
  const std::string dir = TempDir("header");
  std::ofstream(dir + "/000000.rgb.png") << "exists";
  const auto open_with = [&](const std::string& width, const std::string& fx,
                             const std::string& cx) {
    std::ofstream(dir + "/camera.txt", std::ios::trunc)
        << "version 1\nwidth " << width << "\nheight 480\nfx " << fx
        << "\nfy 600\ncx " << cx << "\ncy 240\nrate_hz 30\n";
    return ReplaySource::Open(dir, {}).status();
  };
  EXPECT_TRUE(open_with("640", "600", "320").ok());
  for (const auto& [width, fx, cx, message] : std::vector<
           std::tuple<std::string, std::string, std::string, std::string>>{
           {"1e10", "600", "320", "width 1e+10 is not a whole number"},
           {"640.5", "600", "320", "width 640.5 is not a whole number"},
           {"640", "1e-200", "320", "fx and fy must be focal lengths"},
           {"640", "600", "5000", "cx and cy must be finite and within"}}) {
    const absl::Status status = open_with(width, fx, cx);
    EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument) << message;
    EXPECT_THAT(status.message(), HasSubstr(message));
  }
}

// The CameraService with a publisher, and the RobotService's client.
class CameraLinkTest : public ::testing::Test {
 protected:
  void Start(std::unique_ptr<FrameSource> source, double max_age_s = 0.5,
             const ServerOptions& server_options = ServerOptions(),
             const ChannelOptions& channel = ChannelOptions()) {
    publisher_ = std::make_unique<FramePublisher>(std::move(source));
    service_ = std::make_unique<CameraServiceImpl>(&env_, publisher_.get());
    auto server = ServiceServer::Start(server_options, &env_, {service_.get()},
                                       {"bitewise.v1.CameraService"});
    ASSERT_TRUE(server.ok()) << server.status();
    server_ = *std::move(server);
    client_ = Client(channel, max_age_s);
  }
  std::unique_ptr<robot::CameraClient> Client(const ChannelOptions& channel,
                                              double max_age_s = 2.0) {
    robot::CameraClientOptions options;
    options.address = server_->address();
    options.max_frame_age_s = max_age_s;
    options.channel = channel;
    options.channel.max_message_bytes = 64 << 20;
    auto client = robot::CameraClient::Create(options);
    EXPECT_TRUE(client.ok()) << client.status();
    return client.ok() ? *std::move(client) : nullptr;
  }
  void TearDown() override {
    if (server_) server_->Shutdown();
  }
  RpcEnvironment env_;
  std::unique_ptr<FramePublisher> publisher_;
  std::unique_ptr<CameraServiceImpl> service_;
  std::unique_ptr<ServiceServer> server_;
  std::unique_ptr<robot::CameraClient> client_;
};

// Captures until the camera has a frame the client has not returned yet
// (the first frame takes a moment; a loaded machine renders slowly).
absl::StatusOr<domain::RgbdFrame> CaptureNew(robot::CameraClient& client) {
  absl::StatusOr<domain::RgbdFrame> frame = client.Capture();
  for (int i = 0; i < 250 && !frame.ok() &&
                  (absl::IsUnavailable(frame.status()) ||
                   absl::StrContains(frame.status().message(), "again"));
       ++i) {
    absl::SleepFor(absl::Milliseconds(20));
    frame = client.Capture();
  }
  return frame;
}

// The camera computer is on the lab's (wireless) network: its frames, a
// person's plate, go only to a client certificate with the robot role
// (deploy/config/robot-computer.env; bitewise-robot --camera_tls_cert).
TEST_F(CameraLinkTest, OnlyTheRobotsCertificateGetsFramesOverMutualTls) {
  SimSourceOptions sim;
  sim.rate_hz = 20;
  auto source = SimSource::Create(sim);
  ASSERT_TRUE(source.ok());
  ASSERT_TRUE(testing::Certs().error.empty()) << testing::Certs().error;
  ServerOptions server_options = testing::TlsServerOptions(/*mutual=*/true);
  server_options.authz_file = testing::WriteRoles("bitewise-client robot\n");
  ChannelOptions robot = testing::TlsChannelOptions(/*with_client_cert=*/true);
  robot.tls_server_name_override = "localhost";
  Start(*std::move(source), 2.0, server_options, robot);
  absl::StatusOr<domain::RgbdFrame> frame = CaptureNew(*client_);
  ASSERT_TRUE(frame.ok()) << frame.status();

  // Only the CA (the deployment before this session): no frame.
  ChannelOptions anyone = testing::TlsChannelOptions(false);
  anyone.tls_server_name_override = "localhost";
  std::unique_ptr<robot::CameraClient> stranger = Client(anyone);
  ASSERT_NE(stranger, nullptr);
  EXPECT_FALSE(stranger->Capture().ok());

  // A lab certificate without the robot role: refused by role.
  testing::WriteRoles("bitewise-client researcher\n");
  ASSERT_TRUE(server_->ReloadAuthorization().ok());
  std::unique_ptr<robot::CameraClient> researcher = Client(robot);
  ASSERT_NE(researcher, nullptr);
  absl::StatusOr<domain::RgbdFrame> refused = researcher->Capture();
  EXPECT_EQ(refused.status().code(), absl::StatusCode::kPermissionDenied)
      << refused.status();
}

TEST_F(CameraLinkTest, TheRobotGetsTheNewestFrameIntact) {
  SimSourceOptions sim;
  sim.rate_hz = 20;
  auto source = SimSource::Create(sim);
  ASSERT_TRUE(source.ok());
  Start(*std::move(source), /*max_age_s=*/2.0);
  absl::StatusOr<domain::RgbdFrame> frame = CaptureNew(*client_);
  ASSERT_TRUE(frame.ok()) << frame.status();
  const absl::StatusOr<PublishedFrame> newest = publisher_->Newest(0);
  ASSERT_TRUE(newest.ok());
  // The same picture, byte for byte, or one captured just after it.
  EXPECT_LE(newest->frame.sequence, frame->sequence + 1);
  EXPECT_EQ(frame->rgb.size(), 640u * 480 * 3);
  EXPECT_EQ(frame->depth_mm.size(), 640u * 480);
  absl::StatusOr<domain::RgbdFrame> next = CaptureNew(*client_);
  ASSERT_TRUE(next.ok()) << next.status();
  EXPECT_GT(next->sequence, frame->sequence);
}

TEST_F(CameraLinkTest, AStoppedCameraIsRefusedNamingTheAge) {
  // A two-frame recording that is not looped: the camera "stops".
  SimSourceOptions sim;
  sim.rate_hz = 1000;
  const std::string dir = TempDir("stops");
  {
    RecordingSource recorder(*SimSource::Create(sim), dir, 50.0);
    ASSERT_TRUE(recorder.Next().ok());
    ASSERT_TRUE(recorder.Next().ok());
  }
  auto replay = ReplaySource::Open(dir, {});
  ASSERT_TRUE(replay.ok());
  Start(*std::move(replay), /*max_age_s=*/0.3);
  absl::SleepFor(absl::Milliseconds(600));
  absl::StatusOr<domain::RgbdFrame> frame = client_->Capture();
  EXPECT_EQ(frame.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(frame.status().message(), HasSubstr("s old (limit 0.30 s)"));
  EXPECT_THAT(frame.status().message(), HasSubstr(server_->address()));
  EXPECT_THAT(frame.status().message(), HasSubstr("ended after 2 frames"));
}

TEST_F(CameraLinkTest, TheSameFrameIsNeverUsedForTwoBites) {
  SimSourceOptions sim;
  sim.rate_hz = 0.25;  // one frame now, the next in 4 s
  auto source = SimSource::Create(sim);
  ASSERT_TRUE(source.ok());
  Start(*std::move(source), /*max_age_s=*/10.0);
  absl::StatusOr<domain::RgbdFrame> first = CaptureNew(*client_);
  ASSERT_TRUE(first.ok()) << first.status();
  absl::StatusOr<domain::RgbdFrame> again = client_->Capture();
  EXPECT_EQ(again.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(again.status().message(), HasSubstr("again"));
}

// A publisher that says its frame's age is not a number (or negative): the
// age says nothing, so the frame is never used for a bite.
TEST(CameraClientTest, AFrameWhoseAgeIsNotANumberIsNotUsed) {
  class BadAge final : public v1::CameraService::Service {
   public:
    double age_s = 0.0;
    grpc::Status GetFrame(grpc::ServerContext*, const v1::GetFrameRequest*,
                          v1::CameraFrame* reply) override {
      reply->set_age_s(age_s);
      return grpc::Status::OK;
    }
  };
  RpcEnvironment env;
  BadAge service;
  auto server = ServiceServer::Start(ServerOptions(), &env, {&service},
                                     {"bitewise.v1.CameraService"});
  ASSERT_TRUE(server.ok()) << server.status();
  robot::CameraClientOptions options;
  options.address = (*server)->address();
  auto client = robot::CameraClient::Create(options);
  ASSERT_TRUE(client.ok());
  for (double age : {std::nan(""), -1.0}) {
    service.age_s = age;
    absl::StatusOr<domain::RgbdFrame> frame = (*client)->Capture();
    EXPECT_EQ(frame.status().code(), absl::StatusCode::kInternal) << age;
    EXPECT_THAT(frame.status().message(), HasSubstr("whose age_s is"));
  }
  (*server)->Shutdown();
}

TEST_F(CameraLinkTest, NoCameraAtTheAddressIsUnavailable) {
  robot::CameraClientOptions options;
  options.address = "127.0.0.1:1";
  options.timeout_s = 1.0;
  auto client = robot::CameraClient::Create(options);
  ASSERT_TRUE(client.ok());
  absl::StatusOr<domain::RgbdFrame> frame = (*client)->Capture();
  EXPECT_EQ(frame.status().code(), absl::StatusCode::kUnavailable);
  EXPECT_THAT(frame.status().message(), HasSubstr("camera at 127.0.0.1:1"));
}

}  // namespace
}  // namespace bitewise::camera
