// RobotBackend: everything behind the Robot for one deployment, chosen by
// configuration: the simulated world (a kinematic arm, a plate of food and
// the simulated Net F/T box on loopback, read by the real NetFtRdtClient)
// or the hardware (the JACO2 through its SDK and a real Net F/T box).
// Also the camera (the simulated camera, or on hardware a FrameProvider such
// as CameraClient for the wrist camera's publisher) and the readiness
// signal that the service's health status follows: live only while F/T
// data streams.
//
// Thread-safe.
#ifndef BITEWISE_SERVICES_ROBOT_BACKEND_H_
#define BITEWISE_SERVICES_ROBOT_BACKEND_H_

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "absl/synchronization/mutex.h"
#include "services/domain/rgbd_frame.h"
#include "services/robot/jaco2/jaco2_arm.h"
#include "services/robot/netft/netft_rdt_client.h"
#include "services/robot/robot.h"
#include "services/robot/sim/sim_arm.h"
#include "services/robot/sim/sim_netft_box.h"
#include "services/robot/sim/sim_world.h"
#include "services/sim/scene.h"

namespace bitewise::robot {

enum class BackendKind { kSim, kJaco2 };

// Where the hardware backend's frames come from (CameraClient in
// production). Implementations are thread-safe and never return a frame
// too old to act on.
class FrameProvider {
 public:
  virtual ~FrameProvider() = default;
  virtual absl::StatusOr<domain::RgbdFrame> Capture() = 0;
  virtual std::string name() const = 0;
};

struct SimBackendOptions {
  // Seeds the plate, the world's outcomes and items' force profiles, the
  // box's noise and faults, each from its own stream (SimStreamSeeds).
  uint64_t seed = 1;
  // Food names from sim::FoodCatalog(), one item each; empty means the paper's
  // eight unseen foods.
  std::vector<std::string> foods;
  bool allow_touching = false;
  sim::SimNetFtBoxOptions box;  // host/port of the simulated box
  sim::SimWorldOptions world;   // seed is overwritten with `seed`
  sim::SimArmOptions arm;
};

// The simulated world's random streams from its one seed. The plate is
// drawn from the seed itself (as the simulated camera of bitewise-camera
// --source=sim draws it); outcomes and the box's noise from streams mixed
// from it (random::MixSeed), so that no outcome can be read off an item's
// drawn size or the sensor's bias.
struct SimStreamSeeds {
  uint64_t plate = 0;
  uint64_t world = 0;  // outcomes and items' force profiles
  uint64_t box = 0;    // the simulated box's noise and faults
};
SimStreamSeeds StreamSeeds(uint64_t seed);

struct HardwareBackendOptions {
  jaco2::Jaco2Options arm;
  // Success when the static load after extraction reaches this (N); 0 or
  // less leaves the decision to the operator.
  double static_load_threshold_n = 0.02;
  // The wrist camera; not owned, must outlive the backend. Null: no
  // camera (CaptureFrame is FAILED_PRECONDITION saying so).
  FrameProvider* camera = nullptr;
};

struct RobotBackendOptions {
  BackendKind kind = BackendKind::kSim;
  SimBackendOptions sim;
  HardwareBackendOptions hardware;
  // The F/T client. For kSim, host and port are the simulated box's.
  netft::NetFtRdtClientOptions ft;
  AcquisitionConfig acquisition;
  // How long to wait at start for the F/T data: kSim, for the first data
  // and the counter's verdict; kJaco2, for a sensor fit to move the arm
  // (NetFtRdtClient::CheckLive OK) before the JACO2 is sent home.
  double ft_start_timeout_s = 10.0;
};

// The simulated Net F/T box's options for these backend options: its
// seed's stream and the client's counts per unit.
sim::SimNetFtBoxOptions SimBoxOptions(const RobotBackendOptions& options);

class RobotBackend {
 public:
  // Errors: INVALID_ARGUMENT for unknown foods or bad rates; the errors of
  // Jaco2Arm::Open, NetFtRdtClient::Connect and SimNetFtBox::Start;
  // UNAVAILABLE if the simulated box sends nothing in ft_start_timeout_s,
  // or if the real sensor is not fit to move the arm by then (nothing has
  // moved: the JACO2 is sent home only after).
  // Create is MakeSimBackend or MakeHardwareBackend by options.kind.
  static absl::StatusOr<std::unique_ptr<RobotBackend>> Create(
      const RobotBackendOptions& options);
  // The simulated world (plate, arm, Net F/T box on loopback) from
  // options.sim, options.ft and options.acquisition; ready once the box
  // streams and its counter has a verdict.
  static absl::StatusOr<std::unique_ptr<RobotBackend>> MakeSimBackend(
      const RobotBackendOptions& options);
  // The JACO2 (options.hardware.arm), the Net F/T box at options.ft and the
  // camera of options.hardware.
  static absl::StatusOr<std::unique_ptr<RobotBackend>> MakeHardwareBackend(
      const RobotBackendOptions& options);
  ~RobotBackend();

  Robot& robot() { return *robot_; }
  bool simulated() const { return world_ != nullptr; }
  // -1 on hardware.
  int items_left() const;
  // Simulation only (nullptr on hardware): for tests and tools.
  sim::SimWorld* world() { return world_.get(); }
  sim::SimNetFtBox* box() { return box_.get(); }
  sim::SimArm* sim_arm() { return sim_arm_.get(); }
  netft::NetFtRdtClient* ft() { return ft_.get(); }

  // One RGB-D frame of the plate: rendered in simulation (the simulated
  // camera is fixed above the plate); on hardware the wrist camera's, taken
  // at the arm's viewing pose: an arm a bite left elsewhere is first moved
  // back (Robot::MoveToView, its errors) and the frame is one taken 0.3 s
  // after it arrived. The camera's errors (e.g. FAILED_PRECONDITION for a
  // stale frame); FAILED_PRECONDITION when no camera was configured.
  absl::StatusOr<domain::RgbdFrame> CaptureFrame();

  // True while the F/T stream is live.
  bool FtLive() const;
  // What the health status follows: OK while the F/T stream is live and
  // the arm answers (Robot::ArmReadiness), else why not, naming the sensor
  // or the arm.
  absl::Status Readiness();

 private:
  RobotBackend() = default;
  absl::StatusOr<domain::RgbdFrame> CaptureAtView();
  static constexpr double kViewSettleS = 0.3;
  static constexpr double kFreshFrameWaitS = 3.0;

  // Until the simulated box streams and its counter has a verdict;
  // UNAVAILABLE after `timeout_s`.
  absl::Status WaitForSimulatedStream(double timeout_s);
  // OK once ft_->CheckLive() is; else UNAVAILABLE after timeout_s, saying
  // "refusing to <action>" and the sensor's problem.
  absl::Status WaitForFitSensor(double timeout_s, absl::string_view action);
  // Homes `arm` and builds the Robot over it and the F/T client.
  absl::Status StartRobot(Arm* arm, SuccessJudge* judge,
                          const AcquisitionConfig& acquisition);

  // Destroyed in reverse: the robot first, the arm last, the box (whose
  // thread reads the world and the arm) before the world.
  std::unique_ptr<sim::SimArm> sim_arm_;
  std::unique_ptr<jaco2::Jaco2Arm> jaco2_arm_;
  std::unique_ptr<sim::SimWorld> world_;
  std::unique_ptr<sim::SimNetFtBox> box_;
  std::unique_ptr<netft::NetFtRdtClient> ft_;
  std::unique_ptr<SuccessJudge> hardware_judge_;
  std::unique_ptr<Robot> robot_;
  FrameProvider* camera_ = nullptr;
  uint64_t render_seed_ = 0;
  std::atomic<uint64_t> frames_{0};
};

}  // namespace bitewise::robot

#endif  // BITEWISE_SERVICES_ROBOT_BACKEND_H_
