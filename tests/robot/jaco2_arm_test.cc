// Jaco2Arm against a fake Kinova SDK built by these tests (the hardware
// boundary): the USB and Ethernet variants are told apart by the symbol
// prefix alone, every mapped call reaches the SDK in the right order with
// the right data, and a missing or broken SDK gives a clear error.
#include "services/robot/jaco2/jaco2_arm.h"

#include <dlfcn.h>

#include <cmath>
#include <limits>
#include <memory>
#include <string>

#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "services/camera/camera_service.h"
#include "services/camera/frame_publisher.h"
#include "services/camera/sim_source.h"
#include "services/common/server.h"
#include "services/common/status_macros.h"
#include "services/domain/steady_time.h"
#include "services/robot/backend.h"
#include "services/robot/camera_client.h"
#include "services/robot/sim/sim_netft_box.h"

namespace bitewise::jaco2 {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;
using ::testing::StartsWith;

// The fake SDK's test hooks, resolved in the already loaded library.
class FakeSdk {
 public:
  explicit FakeSdk(const std::string& path) {
    // RTLD_NOLOAD: only a handle on the copy Jaco2Arm loaded; shares state.
    handle_ = dlopen(path.c_str(), RTLD_NOW | RTLD_NOLOAD);
    if (handle_ == nullptr) handle_ = dlopen(path.c_str(), RTLD_NOW);
    calls_ = reinterpret_cast<void (*)(char*, int)>(
        dlsym(handle_, "FakeKinova_Calls"));
    reset_ = reinterpret_cast<void (*)(const char*)>(
        dlsym(handle_, "FakeKinova_Reset"));
    last_point_ = reinterpret_cast<int (*)(kinova::TrajectoryPoint*)>(
        dlsym(handle_, "FakeKinova_LastPoint"));
    move_ = reinterpret_cast<void (*)(float, float, float, float)>(
        dlsym(handle_, "FakeKinova_Move"));
  }
  ~FakeSdk() {
    if (handle_ != nullptr) dlclose(handle_);
  }
  bool ok() const { return calls_ && reset_ && last_point_ && move_; }
  void Move(float dx, float dy, float dz, float dthetax) {
    move_(dx, dy, dz, dthetax);
  }
  std::string Calls() {
    char buffer[8192];
    calls_(buffer, sizeof(buffer));
    return buffer;
  }
  void Reset(const char* failing = "") { reset_(failing); }
  int LastPoint(kinova::TrajectoryPoint* point) { return last_point_(point); }

 private:
  void* handle_ = nullptr;
  void (*calls_)(char*, int) = nullptr;
  void (*reset_)(const char*) = nullptr;
  int (*last_point_)(kinova::TrajectoryPoint*) = nullptr;
  void (*move_)(float, float, float, float) = nullptr;
};

Jaco2Options UsbOptions() {
  Jaco2Options options;
  options.sdk_library = BITEWISE_FAKE_KINOVA_USB;
  options.transport = Jaco2Transport::kUsb;
  options.p_BaseTask_m = Eigen::Vector3d(0.0, -0.45, -0.05);
  return options;
}

TEST(Jaco2ArmTest, UsbVariantMapsEveryCall) {
  FakeSdk sdk(BITEWISE_FAKE_KINOVA_USB);
  ASSERT_TRUE(sdk.ok());
  sdk.Reset();
  {
    auto arm = Jaco2Arm::Open(UsbOptions());
    ASSERT_TRUE(arm.ok()) << arm.status();
    EXPECT_EQ((*arm)->prefix(), "");
    EXPECT_EQ((*arm)->name(), "JACO2 (USB)");
    EXPECT_EQ(sdk.Calls(), "InitAPI;StartControlAPI;SetCartesianControl;");
    ASSERT_TRUE((*arm)->MoveHome().ok());

    // Home is (0, -0.45, 0.10) in the base frame: 0.15 m above the plate.
    absl::StatusOr<robot::ForkPose> pose = (*arm)->MeasuredPose();
    ASSERT_TRUE(pose.ok()) << pose.status();
    EXPECT_NEAR(pose->p_TaskTip_m.x(), 0.0, 1e-6);
    EXPECT_NEAR(pose->p_TaskTip_m.y(), 0.0, 1e-6);
    EXPECT_NEAR(pose->p_TaskTip_m.z(), 0.15, 1e-6);
    EXPECT_NEAR(pose->pitch_rad, 0.0, 1e-6);

    // One 100 Hz command: straight down at 5 cm/s, feed-forward only.
    robot::ForkPose setpoint = *pose;
    setpoint.p_TaskTip_m.z() -= 0.0005;
    robot::ForkVelocity velocity;
    velocity.v_TaskTip_mps = Eigen::Vector3d(0.0, 0.0, -0.05);
    ASSERT_TRUE((*arm)->Command(setpoint, velocity).ok());
    kinova::TrajectoryPoint point{};
    EXPECT_EQ(sdk.LastPoint(&point), 1);
    EXPECT_EQ(point.Position.Type, kinova::kCartesianVelocity);
    // -0.05 feed-forward plus 5/s x -0.0005 m of position error.
    EXPECT_NEAR(point.Position.CartesianPosition.Z, -0.0525, 1e-6);
    EXPECT_NEAR(point.Position.CartesianPosition.X, 0.0, 1e-6);

    // Halt: erase the FIFO, then command zero velocity.
    ASSERT_TRUE((*arm)->Halt().ok());
    EXPECT_EQ(sdk.LastPoint(&point), 2);
    EXPECT_EQ(point.Position.CartesianPosition.Z, 0.0f);

    absl::StatusOr<ArmWrench> wrench = (*arm)->EstimatedWrench();
    ASSERT_TRUE(wrench.ok());
    EXPECT_NEAR(wrench->force_n.z(), 3.5, 1e-6);
    EXPECT_NEAR(wrench->torque_nm.z(), -0.5, 1e-6);
  }
  EXPECT_EQ(sdk.Calls(),
            "InitAPI;StartControlAPI;SetCartesianControl;MoveHome;"
            "GetCartesianPosition;GetCartesianPosition;SendBasicTrajectory;"
            "EraseAllTrajectories;SendBasicTrajectory;GetCartesianForce;"
            "EraseAllTrajectories;CloseAPI;");
}

TEST(Jaco2ArmTest, EthernetVariantUsesThePrefixedNames) {
  FakeSdk sdk(BITEWISE_FAKE_KINOVA_ETHERNET);
  ASSERT_TRUE(sdk.ok());
  sdk.Reset();
  Jaco2Options options = UsbOptions();
  options.sdk_library = BITEWISE_FAKE_KINOVA_ETHERNET;
  options.transport = Jaco2Transport::kEthernet;
  auto arm = Jaco2Arm::Open(options);
  ASSERT_TRUE(arm.ok()) << arm.status();
  EXPECT_EQ((*arm)->prefix(), "Ethernet_");
  EXPECT_EQ((*arm)->name(), "JACO2 (Ethernet)");
  ASSERT_TRUE((*arm)->MoveHome().ok());
  EXPECT_EQ(sdk.Calls(),
            "InitAPI;StartControlAPI;SetCartesianControl;MoveHome;");
}

TEST(Jaco2ArmTest, WrongVariantNamesTheMissingFunction) {
  // The USB library has no Ethernet_ functions.
  Jaco2Options options = UsbOptions();
  options.transport = Jaco2Transport::kEthernet;
  absl::Status status = Jaco2Arm::Open(options).status();
  EXPECT_EQ(status.code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(status.message(), HasSubstr("has no function Ethernet_InitAPI"));
  EXPECT_THAT(status.message(), HasSubstr("USB variant"));
}

TEST(Jaco2ArmTest, MissingSdkIsAClearError) {
  Jaco2Options options;
  options.sdk_library = "/nonexistent/Kinova.API.USBCommandLayerUbuntu.so";
  absl::Status status = Jaco2Arm::Open(options).status();
  EXPECT_EQ(status.code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(std::string(status.message()),
              StartsWith("cannot load the Kinova JACO2 SDK "
                         "\"/nonexistent/Kinova.API.USBCommandLayerUbuntu.so"));
  EXPECT_THAT(status.message(), HasSubstr("--jaco2_sdk"));
  // The default name when none is given.
  Jaco2Options defaults;
  defaults.transport = Jaco2Transport::kEthernet;
  status = Jaco2Arm::Open(defaults).status();
  EXPECT_THAT(status.message(),
              HasSubstr("\"Kinova.API.EthCommandLayerUbuntu.so\""));
}

TEST(Jaco2ArmTest, SdkErrorCodesNameTheCall) {
  FakeSdk sdk(BITEWISE_FAKE_KINOVA_USB);
  ASSERT_TRUE(sdk.ok());
  sdk.Reset("StartControlAPI");
  absl::Status status = Jaco2Arm::Open(UsbOptions()).status();
  EXPECT_EQ(status.code(), absl::StatusCode::kUnavailable);
  EXPECT_THAT(status.message(),
              HasSubstr("StartControlAPI failed with error 1015"));
  // The API was opened, so it is closed again.
  EXPECT_THAT(sdk.Calls(), HasSubstr("CloseAPI;"));
  sdk.Reset();
}

// Halt's zero velocity is what brakes the arm: it is sent even when the
// erase before it fails, and the error names the failed call.
TEST(Jaco2ArmTest, HaltSendsZeroVelocityEvenWhenTheEraseFails) {
  FakeSdk sdk(BITEWISE_FAKE_KINOVA_USB);
  ASSERT_TRUE(sdk.ok());
  sdk.Reset("EraseAllTrajectories");
  auto arm = Jaco2Arm::Open(UsbOptions());
  ASSERT_TRUE(arm.ok()) << arm.status();
  const absl::Status halted = (*arm)->Halt();
  EXPECT_FALSE(halted.ok());
  EXPECT_THAT(halted.message(), HasSubstr("EraseAllTrajectories"));
  kinova::TrajectoryPoint point{};
  EXPECT_EQ(sdk.LastPoint(&point), 1);
  EXPECT_EQ(point.Position.Type, kinova::kCartesianVelocity);
  EXPECT_EQ(point.Position.CartesianPosition.X, 0.0f);
  EXPECT_EQ(point.Position.CartesianPosition.Z, 0.0f);
}

// A NaN passes every clip (NaN > max is false); it never reaches the arm.
TEST(Jaco2ArmTest, ANonFiniteCommandSendsNothing) {
  FakeSdk sdk(BITEWISE_FAKE_KINOVA_USB);
  ASSERT_TRUE(sdk.ok());
  sdk.Reset();
  auto arm = Jaco2Arm::Open(UsbOptions());
  ASSERT_TRUE(arm.ok()) << arm.status();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  absl::StatusOr<robot::ForkPose> pose = (*arm)->MeasuredPose();
  ASSERT_TRUE(pose.ok());
  robot::ForkPose setpoint = *pose;
  setpoint.p_TaskTip_m.x() = nan;
  EXPECT_EQ((*arm)->Command(setpoint, robot::ForkVelocity()).code(),
            absl::StatusCode::kInvalidArgument);
  robot::ForkVelocity velocity;
  velocity.yaw_rate_radps = nan;
  EXPECT_EQ((*arm)->Command(*pose, velocity).code(),
            absl::StatusCode::kInvalidArgument);
  kinova::TrajectoryPoint point{};
  EXPECT_EQ(sdk.LastPoint(&point), 0);
}

robot::RobotBackendOptions HardwareOptions() {
  robot::RobotBackendOptions options;
  options.kind = robot::BackendKind::kJaco2;
  options.hardware.arm = UsbOptions();
  options.ft.host = "127.0.0.1";
  options.ft_start_timeout_s = 0.5;
  return options;
}

// A hardware backend on the fake SDK with a simulated F/T box that streams
// sane readings (so the arm is sent home); `camera` may be null.
struct FitHardware {
  std::unique_ptr<sim::SimNetFtBox> box;
  std::unique_ptr<robot::RobotBackend> backend;  // goes before the box
};
absl::StatusOr<FitHardware> StartFitHardware(
    robot::FrameProvider* camera = nullptr) {
  FitHardware out;
  ASSIGN_OR_RETURN(out.box,
                   sim::SimNetFtBox::Start(sim::SimNetFtBoxOptions(), nullptr));
  robot::RobotBackendOptions options = HardwareOptions();
  options.ft.port = out.box->port();
  options.ft_start_timeout_s = 10.0;
  options.hardware.camera = camera;
  ASSIGN_OR_RETURN(out.backend, robot::RobotBackend::Create(options));
  return out;
}

// Homing is the SDK's own motion, watched by no force limit of ours: with a
// sensor that sends nothing, the start stops naming it, and the arm has not
// been sent home.
TEST(Jaco2BackendTest, TheArmIsNotSentHomeWhileTheSensorIsSilent) {
  FakeSdk sdk(BITEWISE_FAKE_KINOVA_USB);
  ASSERT_TRUE(sdk.ok());
  sdk.Reset();
  robot::RobotBackendOptions options = HardwareOptions();
  options.ft.port = 9;  // discard: nothing answers
  auto backend = robot::RobotBackend::Create(options);
  ASSERT_FALSE(backend.ok());
  EXPECT_EQ(backend.status().code(), absl::StatusCode::kUnavailable);
  EXPECT_THAT(backend.status().message(),
              HasSubstr("refusing to move the JACO2 home: "));
  EXPECT_THAT(backend.status().message(), HasSubstr("127.0.0.1:9"));
  EXPECT_THAT(sdk.Calls(), Not(HasSubstr("MoveHome")));
}

// With a sensor that streams sane readings, the arm is sent home.
TEST(Jaco2BackendTest, TheArmIsSentHomeOnceTheSensorIsFit) {
  FakeSdk sdk(BITEWISE_FAKE_KINOVA_USB);
  ASSERT_TRUE(sdk.ok());
  sdk.Reset();
  absl::StatusOr<FitHardware> hardware = StartFitHardware();
  ASSERT_TRUE(hardware.ok()) << hardware.status();
  EXPECT_THAT(sdk.Calls(), HasSubstr("MoveHome"));
}

// Health follows the arm as well as the sensor: an arm that stops
// answering (off its USB link) turned no health NOT_SERVING while every
// Acquire failed. Asked at most once a second.
TEST(Jaco2BackendTest, ReadinessFollowsTheArm) {
  FakeSdk sdk(BITEWISE_FAKE_KINOVA_USB);
  ASSERT_TRUE(sdk.ok());
  sdk.Reset();
  absl::StatusOr<FitHardware> hardware = StartFitHardware();
  ASSERT_TRUE(hardware.ok()) << hardware.status();
  robot::RobotBackend* backend = hardware->backend.get();
  EXPECT_TRUE(backend->Readiness().ok()) << backend->Readiness();
  sdk.Reset("GetCartesianPosition");
  absl::SleepFor(absl::Seconds(1.1));
  const absl::Status gone = backend->Readiness();
  EXPECT_FALSE(gone.ok());
  EXPECT_THAT(std::string(gone.message()),
              HasSubstr("does not answer: Kinova JACO2 SDK "));
  EXPECT_THAT(std::string(gone.message()), HasSubstr("GetCartesianPosition"));
  // Metrics read the counters without asking the arm.
  const std::string before = sdk.Calls();
  (void)backend->robot().Status(/*ask_arm=*/false);
  EXPECT_EQ(sdk.Calls(), before);
  sdk.Reset();
  absl::SleepFor(absl::Seconds(1.1));
  EXPECT_TRUE(backend->Readiness().ok()) << backend->Readiness();
}

// The wrist camera's view is known only at the viewing pose (home): a frame
// asked for where a bite left the arm is taken after the arm is back and
// has settled there (it used to be taken from wherever the arm was, and
// aimed at as if from home). Through the real link: the camera publisher's
// gRPC service with its simulated source, the RobotService's client.
TEST(Jaco2BackendTest, AFrameIsTakenAtTheViewingPose) {
  FakeSdk sdk(BITEWISE_FAKE_KINOVA_USB);
  ASSERT_TRUE(sdk.ok());
  sdk.Reset();
  camera::SimSourceOptions sim;
  sim.rate_hz = 30;
  auto source = camera::SimSource::Create(sim);
  ASSERT_TRUE(source.ok()) << source.status();
  RpcEnvironment env;
  camera::FramePublisher publisher(*std::move(source));
  camera::CameraServiceImpl service(&env, &publisher);
  auto server = ServiceServer::Start(ServerOptions(), &env, {&service},
                                     {"bitewise.v1.CameraService"});
  ASSERT_TRUE(server.ok()) << server.status();
  robot::CameraClientOptions camera_options;
  camera_options.address = (*server)->address();
  camera_options.channel.max_message_bytes = 64 << 20;
  auto camera = robot::CameraClient::Create(camera_options);
  ASSERT_TRUE(camera.ok()) << camera.status();

  absl::StatusOr<FitHardware> hardware = StartFitHardware(camera->get());
  ASSERT_TRUE(hardware.ok()) << hardware.status();
  robot::RobotBackend* backend = hardware->backend.get();
  // Where a bite ends: 6 cm lower and 4 cm aside, tilted.
  sdk.Move(0.04f, 0.0f, -0.06f, 0.3f);

  const double asked_s = SteadyNowS();
  absl::StatusOr<domain::RgbdFrame> frame = backend->CaptureFrame();
  ASSERT_TRUE(frame.ok()) << frame.status();
  // Taken after the way back and the settling time, not before.
  EXPECT_GT(frame->capture_s, asked_s + 0.3);
  const std::string calls = sdk.Calls();
  EXPECT_THAT(calls, HasSubstr("SendBasicTrajectory"));
  // Home again (the viewing pose recorded at start), within 1 cm.
  absl::StatusOr<bool> there = backend->robot().MoveToView();
  ASSERT_TRUE(there.ok()) << there.status();
  EXPECT_FALSE(*there);
  (*server)->Shutdown();
}

}  // namespace
}  // namespace bitewise::jaco2
