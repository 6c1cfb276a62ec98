// Jaco2Arm: the Kinova JACO2 behind the Arm interface. The vendor SDK is a
// shared library loaded at run time with dlopen, so bitewise builds and runs
// (in simulation) on machines without it. The USB and Ethernet variants of
// the SDK export the same functions, the Ethernet ones with an "Ethernet_"
// prefix on every name. Set points are streamed as Cartesian velocity
// trajectory points at the control rate, which is how the JACO2 is driven
// at 100 Hz (position points would queue up in its trajectory FIFO).
//
// Frames: the task frame (arm.h) is the arm base frame shifted by
// p_BaseTask_m, axes parallel. The fork is assumed mounted so that the
// end effector's Euler angles are (pi + pitch, 0, yaw); calibrate this on
// the real arm.
//
// Thread-safe: SDK calls are serialised.
#ifndef BITEWISE_SERVICES_ROBOT_JACO2_JACO2_ARM_H_
#define BITEWISE_SERVICES_ROBOT_JACO2_JACO2_ARM_H_

#include <memory>
#include <string>

#include "Eigen/Core"
#include "absl/base/thread_annotations.h"
#include "absl/status/statusor.h"
#include "absl/synchronization/mutex.h"
#include "services/robot/arm.h"
#include "services/robot/jaco2/kinova_types.h"

namespace bitewise::jaco2 {

enum class Jaco2Transport { kUsb, kEthernet };

struct Jaco2Options {
  // Path or bare file name (searched like any dlopen name). Empty picks the
  // vendor's name for the transport: Kinova.API.USBCommandLayerUbuntu.so or
  // Kinova.API.EthCommandLayerUbuntu.so.
  std::string sdk_library;
  Jaco2Transport transport = Jaco2Transport::kUsb;
  // Where the task frame's origin (the plate centre) is in the base frame.
  Eigen::Vector3d p_BaseTask_m = Eigen::Vector3d(0.0, -0.45, -0.05);
  // Position error feedback added to the feed-forward velocity, 1/s.
  double position_gain_per_s = 5.0;
  // Commanded speeds are clipped to these.
  double max_speed_mps = 0.2;
  double max_rate_radps = 1.5;
};

// Force and torque at the end effector estimated by the arm from its joint
// torques (GetCartesianForce); coarse, for diagnostics next to the Forque.
struct ArmWrench {
  Eigen::Vector3d force_n = Eigen::Vector3d::Zero();
  Eigen::Vector3d torque_nm = Eigen::Vector3d::Zero();
};

class Jaco2Arm final : public robot::Arm {
 public:
  // Loads the SDK, resolves every function it needs, then InitAPI,
  // StartControlAPI and SetCartesianControl. Errors: FAILED_PRECONDITION
  // naming the library when it cannot be loaded or lacks a function (with
  // the prefixed name, so a USB/Ethernet mix-up is obvious); UNAVAILABLE
  // naming the call and its SDK error code when the arm does not answer.
  static absl::StatusOr<std::unique_ptr<Jaco2Arm>> Open(
      const Jaco2Options& options);

  // Erases trajectories, CloseAPI, dlclose.
  ~Jaco2Arm() override;

  std::string name() const override;
  absl::Status MoveHome() override;
  absl::StatusOr<robot::ForkPose> MeasuredPose() override;
  absl::Status Command(const robot::ForkPose& setpoint,
                       const robot::ForkVelocity& velocity) override;
  absl::Status Halt() override;

  absl::StatusOr<ArmWrench> EstimatedWrench();

  // The symbol prefix of the loaded variant: "" or "Ethernet_".
  const std::string& prefix() const { return prefix_; }

 private:
  struct Api {
    kinova::VoidFn init_api = nullptr;
    kinova::VoidFn close_api = nullptr;
    kinova::VoidFn start_control_api = nullptr;
    kinova::VoidFn move_home = nullptr;
    kinova::VoidFn set_cartesian_control = nullptr;
    kinova::GetCartesianFn get_cartesian_position = nullptr;
    kinova::GetCartesianFn get_cartesian_force = nullptr;
    kinova::SendBasicTrajectoryFn send_basic_trajectory = nullptr;
    kinova::VoidFn erase_all_trajectories = nullptr;
  };

  Jaco2Arm(const Jaco2Options& options, void* handle, std::string library,
           std::string prefix, const Api& api);
  absl::Status Check(const char* function, int code) const;
  absl::StatusOr<robot::ForkPose> MeasuredPoseLocked()
      ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_);
  absl::Status SendVelocityLocked(const kinova::CartesianInfo& velocity)
      ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_);

  const Jaco2Options options_;
  void* const handle_;
  const std::string library_;
  const std::string prefix_;
  const Api api_;
  mutable absl::Mutex mu_;
};

}  // namespace bitewise::jaco2

#endif  // BITEWISE_SERVICES_ROBOT_JACO2_JACO2_ARM_H_
