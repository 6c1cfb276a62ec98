#include "services/robot/jaco2/jaco2_arm.h"

#include <dlfcn.h>

#include <algorithm>
#include <cmath>
#include <utility>

#include "absl/strings/str_cat.h"
#include "services/common/status_macros.h"

namespace bitewise::jaco2 {
namespace {

std::string DefaultLibrary(Jaco2Transport transport) {
  return transport == Jaco2Transport::kEthernet
             ? "Kinova.API.EthCommandLayerUbuntu.so"
             : "Kinova.API.USBCommandLayerUbuntu.so";
}

template <typename Fn>
absl::Status Resolve(void* handle, const std::string& library,
                     const std::string& prefix, const char* name, Fn* out) {
  const std::string symbol = prefix + name;
  dlerror();
  void* address = dlsym(handle, symbol.c_str());
  if (address == nullptr) {
    return absl::FailedPreconditionError(absl::StrCat(
        "Kinova JACO2 SDK \"", library, "\" has no function ", symbol,
        prefix.empty() ? " (is it the Ethernet variant?)"
                       : " (is it the USB variant?)"));
  }
  *out = reinterpret_cast<Fn>(address);
  return absl::OkStatus();
}

double Clip(double value, double limit) {
  return std::clamp(value, -limit, limit);
}

}  // namespace

absl::StatusOr<std::unique_ptr<Jaco2Arm>> Jaco2Arm::Open(
    const Jaco2Options& options) {
  const std::string library = options.sdk_library.empty()
                                  ? DefaultLibrary(options.transport)
                                  : options.sdk_library;
  const std::string prefix =
      options.transport == Jaco2Transport::kEthernet ? "Ethernet_" : "";
  dlerror();
  void* handle = dlopen(library.c_str(), RTLD_NOW | RTLD_LOCAL);
  if (handle == nullptr) {
    const char* error = dlerror();
    return absl::FailedPreconditionError(
        absl::StrCat("cannot load the Kinova JACO2 SDK \"", library,
                     "\": ", error != nullptr ? error : "unknown error",
                     ". Install the Kinova SDK or point --jaco2_sdk at it."));
  }
  Api api;
  absl::Status resolved = [&]() -> absl::Status {
    RETURN_IF_ERROR(Resolve(handle, library, prefix, "InitAPI", &api.init_api));
    RETURN_IF_ERROR(
        Resolve(handle, library, prefix, "CloseAPI", &api.close_api));
    RETURN_IF_ERROR(Resolve(handle, library, prefix, "StartControlAPI",
                            &api.start_control_api));
    RETURN_IF_ERROR(
        Resolve(handle, library, prefix, "MoveHome", &api.move_home));
    RETURN_IF_ERROR(Resolve(handle, library, prefix, "SetCartesianControl",
                            &api.set_cartesian_control));
    RETURN_IF_ERROR(Resolve(handle, library, prefix, "GetCartesianPosition",
                            &api.get_cartesian_position));
    RETURN_IF_ERROR(Resolve(handle, library, prefix, "GetCartesianForce",
                            &api.get_cartesian_force));
    RETURN_IF_ERROR(Resolve(handle, library, prefix, "SendBasicTrajectory",
                            &api.send_basic_trajectory));
    RETURN_IF_ERROR(Resolve(handle, library, prefix, "EraseAllTrajectories",
                            &api.erase_all_trajectories));
    return absl::OkStatus();
  }();
  if (!resolved.ok()) {
    dlclose(handle);
    return resolved;
  }
  std::unique_ptr<Jaco2Arm> arm(
      new Jaco2Arm(options, handle, library, prefix, api));
  RETURN_IF_ERROR(arm->Check("InitAPI", api.init_api()));
  RETURN_IF_ERROR(arm->Check("StartControlAPI", api.start_control_api()));
  RETURN_IF_ERROR(
      arm->Check("SetCartesianControl", api.set_cartesian_control()));
  return arm;
}

Jaco2Arm::Jaco2Arm(const Jaco2Options& options, void* handle,
                   std::string library, std::string prefix, const Api& api)
    : options_(options),
      handle_(handle),
      library_(std::move(library)),
      prefix_(std::move(prefix)),
      api_(api) {}

Jaco2Arm::~Jaco2Arm() {
  {
    absl::MutexLock lock(&mu_);
    api_.erase_all_trajectories();
    api_.close_api();
  }
  dlclose(handle_);
}

std::string Jaco2Arm::name() const {
  return prefix_.empty() ? "JACO2 (USB)" : "JACO2 (Ethernet)";
}

absl::Status Jaco2Arm::Check(const char* function, int code) const {
  if (code == kinova::kNoErrorKinova) return absl::OkStatus();
  return absl::UnavailableError(absl::StrCat(
      "Kinova JACO2 SDK ", prefix_, function, " failed with error ", code));
}

absl::Status Jaco2Arm::MoveHome() {
  absl::MutexLock lock(&mu_);
  return Check("MoveHome", api_.move_home());
}

absl::StatusOr<robot::ForkPose> Jaco2Arm::MeasuredPose() {
  absl::MutexLock lock(&mu_);
  return MeasuredPoseLocked();
}

absl::StatusOr<robot::ForkPose> Jaco2Arm::MeasuredPoseLocked() {
  kinova::CartesianPosition position{};
  RETURN_IF_ERROR(
      Check("GetCartesianPosition", api_.get_cartesian_position(&position)));
  const kinova::CartesianInfo& c = position.Coordinates;
  robot::ForkPose pose;
  pose.p_TaskTip_m = Eigen::Vector3d(c.X, c.Y, c.Z) - options_.p_BaseTask_m;
  pose.pitch_rad = std::remainder(c.ThetaX - M_PI, 2.0 * M_PI);
  pose.yaw_rad = c.ThetaZ;
  return pose;
}

absl::Status Jaco2Arm::SendVelocityLocked(
    const kinova::CartesianInfo& velocity) {
  kinova::TrajectoryPoint point{};
  point.Position.Type = kinova::kCartesianVelocity;
  point.Position.HandMode = kinova::kHandNoMovement;
  point.Position.CartesianPosition = velocity;
  return Check("SendBasicTrajectory", api_.send_basic_trajectory(point));
}

absl::Status Jaco2Arm::Command(const robot::ForkPose& setpoint,
                               const robot::ForkVelocity& velocity) {
  // A NaN passes every clip below (NaN > max is false) and would reach the
  // arm as a velocity; nothing is sent.
  if (!setpoint.p_TaskTip_m.allFinite() || !std::isfinite(setpoint.yaw_rad) ||
      !std::isfinite(setpoint.pitch_rad) ||
      !velocity.v_TaskTip_mps.allFinite() ||
      !std::isfinite(velocity.yaw_rate_radps) ||
      !std::isfinite(velocity.pitch_rate_radps)) {
    return absl::InvalidArgumentError(
        "JACO2: set point or velocity not finite; nothing sent");
  }
  absl::MutexLock lock(&mu_);
  ASSIGN_OR_RETURN(const robot::ForkPose measured, MeasuredPoseLocked());
  const double k = options_.position_gain_per_s;
  const Eigen::Vector3d v = velocity.v_TaskTip_mps +
                            k * (setpoint.p_TaskTip_m - measured.p_TaskTip_m);
  const double speed = v.norm();
  const Eigen::Vector3d v_clipped =
      speed > options_.max_speed_mps ? v * (options_.max_speed_mps / speed) : v;
  kinova::CartesianInfo command{};
  command.X = static_cast<float>(v_clipped.x());
  command.Y = static_cast<float>(v_clipped.y());
  command.Z = static_cast<float>(v_clipped.z());
  command.ThetaX = static_cast<float>(
      Clip(velocity.pitch_rate_radps +
               k * std::remainder(setpoint.pitch_rad - measured.pitch_rad,
                                  2.0 * M_PI),
           options_.max_rate_radps));
  command.ThetaY = 0.0f;
  command.ThetaZ = static_cast<float>(Clip(
      velocity.yaw_rate_radps +
          k * std::remainder(setpoint.yaw_rad - measured.yaw_rad, 2.0 * M_PI),
      options_.max_rate_radps));
  return SendVelocityLocked(command);
}

absl::Status Jaco2Arm::Halt() {
  absl::MutexLock lock(&mu_);
  // Drop anything queued, then command zero velocity so the arm brakes now.
  // The zero velocity is sent even when the erase fails: it is what stops
  // the arm.
  absl::Status erased =
      Check("EraseAllTrajectories", api_.erase_all_trajectories());
  absl::Status zeroed = SendVelocityLocked(kinova::CartesianInfo{});
  if (erased.ok()) return zeroed;
  if (zeroed.ok()) return erased;
  return absl::Status(erased.code(),
                      absl::StrCat(erased.message(), "; ", zeroed.message()));
}

absl::StatusOr<ArmWrench> Jaco2Arm::EstimatedWrench() {
  absl::MutexLock lock(&mu_);
  kinova::CartesianPosition force{};
  RETURN_IF_ERROR(Check("GetCartesianForce", api_.get_cartesian_force(&force)));
  ArmWrench wrench;
  const kinova::CartesianInfo& c = force.Coordinates;
  wrench.force_n = Eigen::Vector3d(c.X, c.Y, c.Z);
  wrench.torque_nm = Eigen::Vector3d(c.ThetaX, c.ThetaY, c.ThetaZ);
  return wrench;
}

}  // namespace bitewise::jaco2
