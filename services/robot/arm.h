// The Arm interface: what the acquisition loop needs from a robot arm that
// carries the fork, whether it is the Kinova JACO2 (Jaco2Arm) or the
// simulated kinematic arm (sim::SimArm). Poses are of the fork tip in the
// task frame T: origin at the plate centre on the plate surface, x to the
// right of the camera image, y towards its top, z up (right-handed).
//
// Implementations are thread-safe: Halt() in particular is called from
// whatever thread handles a Stop request while the control loop runs.
#ifndef BITEWISE_SERVICES_ROBOT_ARM_H_
#define BITEWISE_SERVICES_ROBOT_ARM_H_

#include <string>

#include "Eigen/Core"
#include "absl/status/status.h"
#include "absl/status/statusor.h"

namespace bitewise::robot {

// The fork tip's pose: position, the yaw of the tines' plane about T's z
// axis, and the pitch of the handle from vertical (the action's pitch).
struct ForkPose {
  Eigen::Vector3d p_TaskTip_m = Eigen::Vector3d::Zero();
  double yaw_rad = 0.0;
  double pitch_rad = 0.0;
};

// The rate of change of a ForkPose.
struct ForkVelocity {
  Eigen::Vector3d v_TaskTip_mps = Eigen::Vector3d::Zero();
  double yaw_rate_radps = 0.0;
  double pitch_rate_radps = 0.0;
};

class Arm {
 public:
  virtual ~Arm() = default;

  // Names the arm in errors and status ("simulated arm", "JACO2 (USB)").
  virtual std::string name() const = 0;

  // Moves to the arm's home pose and waits until it is there.
  virtual absl::Status MoveHome() = 0;

  virtual absl::StatusOr<ForkPose> MeasuredPose() = 0;

  // One control period's command: the set point to reach by the end of the
  // period and the velocity that gets there. Called at the control rate
  // (100 Hz); arms that track velocities use `velocity`, position-driven
  // arms use `setpoint`.
  virtual absl::Status Command(const ForkPose& setpoint,
                               const ForkVelocity& velocity) = 0;

  // Stops all motion at once and holds the current pose. Safe to call at
  // any time, from any thread, repeatedly.
  virtual absl::Status Halt() = 0;
};

}  // namespace bitewise::robot

#endif  // BITEWISE_SERVICES_ROBOT_ARM_H_
