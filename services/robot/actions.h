// The six skewering actions of the paper (docs/robot.md) (fork pitch, roll
// relative to the item's major axis, and maximum skewering force), the targets
// they are aimed at, and the geometry that turns a target seen by the camera
// into a fork pose in the task frame. Pure data and arithmetic: no I/O.
#ifndef BITEWISE_SERVICES_ROBOT_ACTIONS_H_
#define BITEWISE_SERVICES_ROBOT_ACTIONS_H_

#include <string>
#include <string_view>
#include <vector>

#include "Eigen/Core"
#include "absl/status/statusor.h"

namespace bitewise::robot {

struct ActionSpec {
  // The RobotService's number for the action (AcquireRequest.action,
  // ListActions); only the wire uses it.
  int index = 0;
  std::string name;
  double pitch_rad = 0.0;
  double roll_rad = 0.0;
  double max_force_n = 0.0;
};

// VS0, VS90, TV0, TV90, TA0, TA90, in the paper's order.
const std::vector<ActionSpec>& SkeweringActions();

// The action named `name`; INVALID_ARGUMENT naming the valid actions when
// no action has that name.
absl::StatusOr<ActionSpec> FindAction(std::string_view name);
// Actions are found by name; a number is the wire's (ActionFromWire).
absl::StatusOr<ActionSpec> FindAction(int) = delete;

// The action with the RobotService's wire number `index`; INVALID_ARGUMENT
// naming the valid range when `index` is not an action.
absl::StatusOr<ActionSpec> ActionFromWire(int index);

// A rigid transform X_AB: p_A = R_AB * p_B + p_AB.
struct RigidTransform {
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  Eigen::Vector3d operator*(const Eigen::Vector3d& v) const {
    return R * v + p;
  }
};

// The wrist camera looking straight down from `height_m` above the task
// origin: camera x right, y down, z forward (the convention of
// services/sim/scene.h), so R = diag(1, -1, -1).
RigidTransform CameraLookingDown(double height_m);

// A food item as PerceptionService reports it: the centre of its visible
// top surface in the camera frame C, and the angle of its major axis in the
// image (from image +x towards image +y).
struct AcquireTarget {
  Eigen::Vector3d p_CameraItem_m = Eigen::Vector3d::Zero();
  double major_axis_angle_rad = 0.0;
};

// The target in the task frame: its top-surface centre and the yaw of its
// major axis about T's z.
struct TaskTarget {
  Eigen::Vector3d p_TaskItem_m = Eigen::Vector3d::Zero();
  double major_axis_yaw_rad = 0.0;
};

TaskTarget ToTaskFrame(const AcquireTarget& target,
                       const RigidTransform& X_TaskCamera);

// Where the fork may go: a vertical cylinder about the task origin.
struct Workspace {
  double radius_m = 0.15;
  double min_z_m = -0.01;
  double max_z_m = 0.10;
};

// INVALID_ARGUMENT naming the coordinates and the limit they break when the
// target is not finite or lies outside `workspace`.
absl::Status CheckInWorkspace(const TaskTarget& target,
                              const Workspace& workspace);

// The fork yaw for `action` on an item whose major axis has `yaw_rad`.
double ForkYaw(const ActionSpec& action, double major_axis_yaw_rad);

}  // namespace bitewise::robot

#endif  // BITEWISE_SERVICES_ROBOT_ACTIONS_H_
