#include "services/robot/actions.h"

#include <cmath>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "services/domain/skewering_actions.h"

namespace bitewise::robot {

const std::vector<ActionSpec>& SkeweringActions() {
  static const auto* const kActions = [] {
    auto* actions = new std::vector<ActionSpec>;
    for (int i = 0; i < domain::kNumActions; ++i) {
      const domain::SkeweringAction& a = domain::kSkeweringActions[i];
      actions->push_back({i, a.name, a.pitch_rad, a.roll_rad, a.max_force_n});
    }
    return actions;
  }();
  return *kActions;
}

namespace {

std::string ActionNames() {
  return absl::StrJoin(
      SkeweringActions(), ", ",
      [](std::string* out, const ActionSpec& a) { out->append(a.name); });
}

}  // namespace

absl::StatusOr<ActionSpec> FindAction(std::string_view name) {
  for (const ActionSpec& action : SkeweringActions()) {
    if (action.name == name) return action;
  }
  return absl::InvalidArgumentError(
      absl::StrCat("no skewering action is named \"", std::string(name),
                   "\": the actions are ", ActionNames()));
}

absl::StatusOr<ActionSpec> ActionFromWire(int index) {
  const auto& actions = SkeweringActions();
  if (index < 0 || index >= static_cast<int>(actions.size())) {
    return absl::InvalidArgumentError(
        absl::StrCat("action ", index, " is out of range: actions are 0..",
                     actions.size() - 1, " (", ActionNames(), ")"));
  }
  return actions[index];
}

RigidTransform CameraLookingDown(double height_m) {
  RigidTransform X;
  X.R = Eigen::Vector3d(1.0, -1.0, -1.0).asDiagonal();
  X.p = Eigen::Vector3d(0.0, 0.0, height_m);
  return X;
}

TaskTarget ToTaskFrame(const AcquireTarget& target,
                       const RigidTransform& X_TaskCamera) {
  TaskTarget out;
  out.p_TaskItem_m = X_TaskCamera * target.p_CameraItem_m;
  // The axis is a direction in the camera's x-y plane; rotate it like one.
  const Eigen::Vector3d axis_C(std::cos(target.major_axis_angle_rad),
                               std::sin(target.major_axis_angle_rad), 0.0);
  const Eigen::Vector3d axis_T = X_TaskCamera.R * axis_C;
  out.major_axis_yaw_rad = std::atan2(axis_T.y(), axis_T.x());
  return out;
}

absl::Status CheckInWorkspace(const TaskTarget& target,
                              const Workspace& workspace) {
  const Eigen::Vector3d& p = target.p_TaskItem_m;
  if (!p.allFinite() || !std::isfinite(target.major_axis_yaw_rad)) {
    return absl::InvalidArgumentError(
        "target center_camera_m and major_axis_angle_rad must be finite");
  }
  const double r = std::hypot(p.x(), p.y());
  if (r > workspace.radius_m) {
    return absl::InvalidArgumentError(absl::StrFormat(
        "target is outside the workspace: %.3f m from the plate centre "
        "(task frame x %.3f, y %.3f), limit %.3f m",
        r, p.x(), p.y(), workspace.radius_m));
  }
  if (p.z() < workspace.min_z_m || p.z() > workspace.max_z_m) {
    return absl::InvalidArgumentError(absl::StrFormat(
        "target is outside the workspace: %.3f m above the plate, allowed "
        "%.3f..%.3f m",
        p.z(), workspace.min_z_m, workspace.max_z_m));
  }
  return absl::OkStatus();
}

double ForkYaw(const ActionSpec& action, double major_axis_yaw_rad) {
  return std::remainder(major_axis_yaw_rad + action.roll_rad, 2.0 * M_PI);
}

}  // namespace bitewise::robot
