// In-process tests of the RobotService: the simulated backend (real UDP
// Net F/T stream on loopback) behind a real gRPC server, called through a
// stub. Acquire end to end with streaming, Stop over the wire, errors, the
// camera, and health that follows the F/T stream.
#include "services/robot/robot_service.h"

#include <chrono>
#include <functional>
#include <future>
#include <memory>
#include <vector>

#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "services/common/channel.h"
#include "services/common/readiness_monitor.h"
#include "services/common/server.h"
#include "tests/robot/wait_for.h"

namespace bitewise::robot {
namespace {

using ::bitewise::testing::WaitFor;
using ::testing::HasSubstr;

constexpr char kService[] = "bitewise.v1.RobotService";

class RobotServiceTest : public ::testing::Test {
 protected:
  void SetUp() override {
    RobotBackendOptions options;
    options.sim.seed = 2;
    options.sim.foods = {"strawberry", "carrot", "banana"};
    options.ft.silence_timeout_s = 0.3;
    options.acquisition.watchdog_timeout_s = 0.5;
    auto backend = RobotBackend::Create(options);
    ASSERT_TRUE(backend.ok()) << backend.status();
    backend_ = std::move(backend).value();
    service_ = std::make_unique<RobotServiceImpl>(&env_, backend_.get());
    auto server = ServiceServer::Start(ServerOptions(), &env_, {service_.get()},
                                       {kService});
    ASSERT_TRUE(server.ok()) << server.status();
    server_ = std::move(server).value();
    readiness_ = std::make_unique<::bitewise::ReadinessMonitor>(
        [this] { return backend_->FtLive(); },
        [this](bool serving) { server_->SetServing(serving); });
    auto channel = MakeChannel(server_->address(), ChannelOptions());
    ASSERT_TRUE(channel.ok());
    channel_ = *channel;
    ASSERT_TRUE(WaitForServing(channel_, kService, absl::Seconds(30)).ok());
    stub_ = v1::RobotService::NewStub(channel_);
  }

  void TearDown() override {
    readiness_.reset();
    if (server_) server_->Shutdown();
  }

  std::unique_ptr<grpc::ClientContext> Ctx() {
    auto context = std::make_unique<grpc::ClientContext>();
    context->set_deadline(std::chrono::system_clock::now() +
                          std::chrono::seconds(60));
    return context;
  }

  v1::AcquireRequest RequestFor(size_t item, int action) {
    const sim::PlateScene scene = backend_->world()->scene();
    const AcquireTarget target =
        *backend_->world()->TargetOf(scene.items.at(item).id);
    v1::AcquireRequest request;
    request.set_action(action);
    v1::Point3* c = request.mutable_target()->mutable_center_camera_m();
    c->set_x(target.p_CameraItem_m.x());
    c->set_y(target.p_CameraItem_m.y());
    c->set_z(target.p_CameraItem_m.z());
    request.mutable_target()->set_major_axis_angle_rad(
        target.major_axis_angle_rad);
    return request;
  }

  // Reads the whole stream.
  grpc::Status Acquire(const v1::AcquireRequest& request,
                       std::vector<v1::AcquireProgress>* messages,
                       const std::function<void()>& on_first = nullptr) {
    auto context = Ctx();
    auto reader = stub_->Acquire(context.get(), request);
    v1::AcquireProgress progress;
    while (reader->Read(&progress)) {
      if (messages->empty() && on_first) on_first();
      messages->push_back(progress);
    }
    return reader->Finish();
  }

  RpcEnvironment env_;
  std::unique_ptr<RobotBackend> backend_;
  std::unique_ptr<RobotServiceImpl> service_;
  std::unique_ptr<ServiceServer> server_;
  std::unique_ptr<::bitewise::ReadinessMonitor> readiness_;
  std::shared_ptr<grpc::Channel> channel_;
  std::unique_ptr<v1::RobotService::Stub> stub_;
};

TEST_F(RobotServiceTest, ListActionsIsSpecsTable) {
  v1::ListActionsResponse response;
  ASSERT_TRUE(stub_->ListActions(Ctx().get(), {}, &response).ok());
  ASSERT_EQ(response.actions_size(), 6);
  EXPECT_EQ(response.actions(3).name(), "TV90");
  EXPECT_DOUBLE_EQ(response.actions(3).pitch_rad(), -0.5);
  EXPECT_DOUBLE_EQ(response.actions(3).roll_rad(), M_PI / 2);
  EXPECT_DOUBLE_EQ(response.actions(4).max_force_n(), 10.0);
}

TEST_F(RobotServiceTest, GetStatusReportsTheSimulatedStream) {
  v1::RobotStatus status;
  ASSERT_TRUE(stub_->GetStatus(Ctx().get(), {}, &status).ok());
  EXPECT_TRUE(status.simulated());
  EXPECT_TRUE(status.arm_ready());
  EXPECT_TRUE(status.ft_streaming());
  EXPECT_EQ(status.ft_state(), "streaming");
  EXPECT_THAT(status.ft_sensor(), HasSubstr("Net F/T sensor at 127.0.0.1:"));
  EXPECT_GT(status.ft_samples(), 0u);
  EXPECT_EQ(status.items_left(), 3);
  EXPECT_EQ(status.busy_with(), "");
}

TEST_F(RobotServiceTest, AcquireStreamsPhasesThenTheResult) {
  std::vector<v1::AcquireProgress> messages;
  grpc::Status status = Acquire(RequestFor(0, 0), &messages);
  ASSERT_TRUE(status.ok()) << status.error_message();
  ASSERT_GE(messages.size(), 5u);
  std::vector<v1::AcquirePhase> phases;
  for (const auto& m : messages) {
    if (phases.empty() || phases.back() != m.phase()) {
      phases.push_back(m.phase());
    }
    EXPECT_EQ(m.has_result(), &m == &messages.back());
  }
  EXPECT_EQ(phases, (std::vector<v1::AcquirePhase>{
                        v1::ACQUIRE_PHASE_APPROACH, v1::ACQUIRE_PHASE_ORIENT,
                        v1::ACQUIRE_PHASE_DESCEND, v1::ACQUIRE_PHASE_EXTRACT,
                        v1::ACQUIRE_PHASE_DONE}));
  const v1::AcquireResult& result = messages.back().result();
  EXPECT_EQ(result.true_food_type(), "strawberry");
  EXPECT_EQ(result.action().name(), "VS0");
  EXPECT_GT(result.trace_size(), 1000);
  EXPECT_GT(result.peak_force_n(), 1.0);
  EXPECT_GT(result.contact_time_s(), 0.0);
  v1::RobotStatus robot;
  ASSERT_TRUE(stub_->GetStatus(Ctx().get(), {}, &robot).ok());
  EXPECT_EQ(robot.items_left(), result.success() ? 2 : 3);
}

TEST_F(RobotServiceTest, BadRequestsAreInvalidArgument) {
  std::vector<v1::AcquireProgress> messages;
  grpc::Status status = Acquire(RequestFor(0, 6), &messages);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(status.error_message(), HasSubstr("action 6 is out of range"));
  v1::AcquireRequest no_target;
  status = Acquire(no_target, &messages);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(status.error_message(), HasSubstr("target.center_camera_m"));
  v1::AcquireRequest far = RequestFor(0, 0);
  far.mutable_target()->mutable_center_camera_m()->set_y(-0.3);
  status = Acquire(far, &messages);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(status.error_message(), HasSubstr("outside the workspace"));
  EXPECT_TRUE(messages.empty());
  EXPECT_EQ(backend_->items_left(), 3);
}

TEST_F(RobotServiceTest, StopOverTheWireAbortsTheAcquire) {
  std::vector<v1::AcquireProgress> messages;
  std::future<grpc::Status> running = std::async(
      std::launch::async, [&] { return Acquire(RequestFor(1, 1), &messages); });
  ASSERT_TRUE(WaitFor([&] { return backend_->sim_arm()->commands() > 5; }));
  // A second Acquire meanwhile is refused.
  std::vector<v1::AcquireProgress> second;
  grpc::Status refused = Acquire(RequestFor(0, 0), &second);
  EXPECT_EQ(refused.error_code(), grpc::StatusCode::FAILED_PRECONDITION);
  v1::StopResponse stop;
  ASSERT_TRUE(stub_->Stop(Ctx().get(), {}, &stop).ok());
  EXPECT_TRUE(stop.was_moving());
  const int commands = backend_->sim_arm()->commands();
  grpc::Status status = running.get();
  EXPECT_EQ(status.error_code(), grpc::StatusCode::ABORTED);
  EXPECT_THAT(status.error_message(), HasSubstr("Stop request"));
  EXPECT_EQ(backend_->sim_arm()->commands(), commands);
}

TEST_F(RobotServiceTest, TareSendsTheBiasCommand) {
  v1::TareResponse response;
  ASSERT_TRUE(stub_->Tare(Ctx().get(), {}, &response).ok());
  EXPECT_TRUE(
      WaitFor([&] { return backend_->box()->counters().bias_commands == 1; }));
}

TEST_F(RobotServiceTest, CaptureFrameRendersThePlate) {
  v1::Frame frame;
  grpc::Status status = stub_->CaptureFrame(Ctx().get(), {}, &frame);
  ASSERT_TRUE(status.ok()) << status.error_message();
  EXPECT_EQ(frame.width(), 640u);
  EXPECT_EQ(frame.height(), 480u);
  EXPECT_EQ(frame.rgb_encoding(), v1::IMAGE_ENCODING_RGB8);
  EXPECT_EQ(frame.rgb().size(), 640u * 480u * 3u);
  ASSERT_EQ(frame.depth_mm().size(), 640u * 480u * 2u);
  // The plate centre is 35 cm below the camera.
  const size_t centre = 2 * (240 * 640 + 320);
  const int depth_mm =
      static_cast<uint8_t>(frame.depth_mm()[centre]) |
      (static_cast<uint8_t>(frame.depth_mm()[centre + 1]) << 8);
  EXPECT_GT(depth_mm, 300);
  EXPECT_LE(depth_mm, 360);
  EXPECT_NEAR(frame.intrinsics().fx(), 615.0, 50.0);
}

TEST_F(RobotServiceTest, HealthFollowsTheForceTorqueStream) {
  sim::SimNetFtFaults faults;
  faults.silent = true;
  backend_->box()->SetFaults(faults);
  EXPECT_TRUE(WaitFor([&] {
    auto health = CheckHealth(channel_, kService, absl::Seconds(10));
    return health.ok() && *health == ServingStatus::kNotServing;
  }));
  backend_->box()->SetFaults(sim::SimNetFtFaults());
  EXPECT_TRUE(WaitForServing(channel_, kService, absl::Seconds(30)).ok());
}

}  // namespace
}  // namespace bitewise::robot
