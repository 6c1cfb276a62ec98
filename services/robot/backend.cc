#include "services/robot/backend.h"

#include <cstdio>
#include <random>
#include <utility>

#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "absl/time/time.h"
#include "services/common/status_macros.h"
#include "services/domain/random.h"
#include "services/domain/steady_time.h"

namespace bitewise::robot {

SimStreamSeeds StreamSeeds(uint64_t seed) {
  return {seed, random::MixSeed(seed, 1), random::MixSeed(seed, 2)};
}

sim::SimNetFtBoxOptions SimBoxOptions(const RobotBackendOptions& options) {
  sim::SimNetFtBoxOptions box = options.sim.box;
  box.seed = StreamSeeds(options.sim.seed).box;
  box.counts_per_force = options.ft.counts_per_force;
  box.counts_per_torque = options.ft.counts_per_torque;
  return box;
}

absl::StatusOr<std::unique_ptr<RobotBackend>> RobotBackend::Create(
    const RobotBackendOptions& options) {
  return options.kind == BackendKind::kSim ? MakeSimBackend(options)
                                           : MakeHardwareBackend(options);
}

absl::StatusOr<std::unique_ptr<RobotBackend>> RobotBackend::MakeSimBackend(
    const RobotBackendOptions& options) {
  std::unique_ptr<RobotBackend> backend(new RobotBackend());
  const SimBackendOptions& sim_options = options.sim;
  std::vector<const sim::FoodType*> foods;
  if (sim_options.foods.empty()) {
    foods = sim::UnseenFoods();
  } else {
    for (const std::string& name : sim_options.foods) {
      const sim::FoodType* food = sim::FindFood(name);
      if (food == nullptr) {
        return absl::InvalidArgumentError(absl::StrCat(
            "unknown food \"", name, "\" for the simulated plate"));
      }
      foods.push_back(food);
    }
  }
  AcquisitionConfig acquisition = options.acquisition;
  const SimStreamSeeds seeds = StreamSeeds(sim_options.seed);
  std::mt19937_64 plate_rng(seeds.plate);
  const sim::PlateScene scene =
      sim::RandomPlate(foods, sim_options.allow_touching, plate_rng);
  sim::SimArmOptions arm_options = sim_options.arm;
  arm_options.control_period_s = acquisition.control_period_s;
  backend->sim_arm_ = std::make_unique<sim::SimArm>(arm_options);
  sim::SimWorldOptions world_options = sim_options.world;
  world_options.seed = seeds.world;
  backend->world_ = std::make_unique<sim::SimWorld>(
      scene, backend->sim_arm_.get(), world_options);
  netft::NetFtRdtClientOptions ft_options = options.ft;
  const sim::SimNetFtBoxOptions box_options = SimBoxOptions(options);
  ASSIGN_OR_RETURN(backend->box_,
                   sim::SimNetFtBox::Start(box_options, backend->world_.get()));
  ft_options.host = box_options.host;
  ft_options.port = backend->box_->port();
  acquisition.X_TaskCamera = backend->world_->X_TaskCamera();
  backend->render_seed_ = sim_options.seed;
  ASSIGN_OR_RETURN(backend->ft_, netft::NetFtRdtClient::Connect(ft_options));
  RETURN_IF_ERROR(backend->WaitForSimulatedStream(options.ft_start_timeout_s));
  RETURN_IF_ERROR(backend->StartRobot(backend->sim_arm_.get(),
                                      backend->world_.get(), acquisition));
  return backend;
}

absl::StatusOr<std::unique_ptr<RobotBackend>> RobotBackend::MakeHardwareBackend(
    const RobotBackendOptions& options) {
  std::unique_ptr<RobotBackend> backend(new RobotBackend());
  ASSIGN_OR_RETURN(backend->jaco2_arm_,
                   jaco2::Jaco2Arm::Open(options.hardware.arm));
  if (options.hardware.static_load_threshold_n > 0.0) {
    backend->hardware_judge_ = std::make_unique<StaticLoadJudge>(
        options.hardware.static_load_threshold_n);
  } else {
    backend->hardware_judge_ = std::make_unique<OperatorJudge>();
  }
  backend->camera_ = options.hardware.camera;
  ASSIGN_OR_RETURN(backend->ft_, netft::NetFtRdtClient::Connect(options.ft));
  // Homing is the SDK's own motion, which no force limit or watchdog of
  // ours watches: it starts only once the sensor is fit to move an arm (as
  // an Acquire would require), or the start stops naming what is wrong.
  RETURN_IF_ERROR(backend->WaitForFitSensor(options.ft_start_timeout_s,
                                            "move the JACO2 home"));
  RETURN_IF_ERROR(backend->StartRobot(backend->jaco2_arm_.get(),
                                      backend->hardware_judge_.get(),
                                      options.acquisition));
  return backend;
}

absl::Status RobotBackend::WaitForSimulatedStream(double timeout_s) {
  // Loopback: data must flow at once, or something is badly wrong.
  const double deadline_s = SteadyNowS() + timeout_s;
  while (ft_->Health().state != netft::StreamState::kStreaming) {
    if (SteadyNowS() > deadline_s) {
      return absl::UnavailableError(absl::StrCat(
          ft_->name(), " (simulated) sent no data in ", timeout_s, " s"));
    }
    absl::SleepFor(absl::Milliseconds(5));
  }
  // And until the counter has a verdict (ok or fault: a box whose counter
  // disagrees with the configured rate must still come up, refusing to
  // move, so that the fault is visible).
  while (ft_->Health().counter.state == netft::CounterClockState::kVerifying) {
    if (SteadyNowS() > deadline_s) {
      return absl::UnavailableError(absl::StrCat(
          ft_->name(), " (simulated): ", ft_->Health().counter.problem,
          " after ", timeout_s, " s"));
    }
    absl::SleepFor(absl::Milliseconds(5));
  }
  return absl::OkStatus();
}

absl::Status RobotBackend::WaitForFitSensor(double timeout_s,
                                            absl::string_view action) {
  const double deadline_s = SteadyNowS() + timeout_s;
  absl::Status live = ft_->CheckLive();
  while (!live.ok()) {
    if (SteadyNowS() > deadline_s) {
      return absl::UnavailableError(
          absl::StrCat("refusing to ", action, ": ", live.message(),
                       " (waited ", timeout_s, " s for the F/T sensor)"));
    }
    absl::SleepFor(absl::Milliseconds(5));
    live = ft_->CheckLive();
  }
  return absl::OkStatus();
}

absl::Status RobotBackend::StartRobot(Arm* arm, SuccessJudge* judge,
                                      const AcquisitionConfig& acquisition) {
  RETURN_IF_ERROR(arm->MoveHome());
  robot_ = std::make_unique<Robot>(arm, ft_.get(), judge, acquisition);
  // Home is where the camera's view is calibrated (X_TaskCamera: on
  // hardware, --camera_height_m above the plate, looking down).
  ASSIGN_OR_RETURN(const ForkPose view, robot_->RecordViewPose());
  std::fprintf(stderr,
               "bitewise-robot: viewing pose: fork tip at (%.3f, %.3f, %.3f) m "
               "in the task frame, pitch %.3f rad, yaw %.3f rad\n",
               view.p_TaskTip_m.x(), view.p_TaskTip_m.y(), view.p_TaskTip_m.z(),
               view.pitch_rad, view.yaw_rad);
  return absl::OkStatus();
}

RobotBackend::~RobotBackend() = default;

int RobotBackend::items_left() const {
  return world_ ? world_->items_left() : -1;
}

absl::StatusOr<domain::RgbdFrame> RobotBackend::CaptureFrame() {
  if (!world_) {
    if (camera_ == nullptr) {
      return absl::FailedPreconditionError(
          "no camera configured for the hardware backend: start "
          "bitewise-camera on the camera computer and give its address with "
          "--camera_address");
    }
    return CaptureAtView();
  }
  // Each frame its own noise, reproducibly.
  const uint64_t sequence = frames_++;
  return sim::ToRgbdFrame(
      sim::RenderPlate(world_->scene(), sim::D415Intrinsics(),
                       render_seed_ * 1000003ULL + sequence),
      sequence, SteadyNowS());
}

absl::StatusOr<domain::RgbdFrame> RobotBackend::CaptureAtView() {
  // The camera rides on the wrist: its view is known only at the viewing
  // pose, where the last bite did not leave the arm.
  ASSIGN_OR_RETURN(const bool moved, robot_->MoveToView());
  if (!moved) {
    ASSIGN_OR_RETURN(domain::RgbdFrame frame, camera_->Capture());
    RETURN_IF_ERROR(robot_->CheckAtView());
    return frame;
  }
  // A frame taken once the arm has settled there, not on the way.
  const double settled_s = SteadyNowS() + kViewSettleS;
  const double deadline_s = settled_s + kFreshFrameWaitS;
  absl::Status last = absl::OkStatus();
  while (SteadyNowS() <= deadline_s) {
    absl::SleepFor(absl::Milliseconds(30));
    absl::StatusOr<domain::RgbdFrame> frame = camera_->Capture();
    if (frame.ok() && frame->capture_s >= settled_s) {
      RETURN_IF_ERROR(robot_->CheckAtView());
      return frame;
    }
    // An earlier frame, or the same one again: wait for the next.
    if (!frame.ok() && !absl::IsFailedPrecondition(frame.status())) {
      return frame.status();
    }
    if (!frame.ok()) last = frame.status();
  }
  return absl::UnavailableError(absl::StrCat(
      camera_->name(),
      ": no frame taken after the arm settled at its viewing "
      "pose within ",
      kFreshFrameWaitS, " s",
      last.ok() ? "" : absl::StrCat(" (last: ", last.message(), ")")));
}

bool RobotBackend::FtLive() const { return ft_ && ft_->CheckLive().ok(); }

absl::Status RobotBackend::Readiness() {
  if (!ft_) return absl::FailedPreconditionError("no F/T sensor");
  RETURN_IF_ERROR(ft_->CheckLive());
  return robot_ ? robot_->ArmReadiness()
                : absl::FailedPreconditionError("the robot has not started");
}

}  // namespace bitewise::robot
