#include "services/robot/sim/sim_arm.h"

#include <algorithm>
#include <cmath>

#include "absl/strings/str_cat.h"
#include "services/domain/steady_time.h"

namespace bitewise::sim {
namespace {

// Enough history for the F/T box to look back a few hundred ms.
constexpr size_t kKeptSegments = 512;

}  // namespace

SimArm::SimArm(const SimArmOptions& options) : options_(options) {
  absl::MutexLock lock(&mu_);
  Push({SteadyNowS(), options.home, options.home});
}

absl::Status SimArm::MoveHome() {
  absl::MutexLock lock(&mu_);
  Push({SteadyNowS(), options_.home, options_.home});
  return absl::OkStatus();
}

absl::StatusOr<robot::ForkPose> SimArm::MeasuredPose() {
  absl::MutexLock lock(&mu_);
  return PoseAtLocked(SteadyNowS());
}

absl::Status SimArm::Command(const robot::ForkPose& setpoint,
                             const robot::ForkVelocity&) {
  if (!setpoint.p_TaskTip_m.allFinite() || !std::isfinite(setpoint.yaw_rad) ||
      !std::isfinite(setpoint.pitch_rad)) {
    return absl::InvalidArgumentError("simulated arm: set point not finite");
  }
  const double now_s = SteadyNowS();
  absl::MutexLock lock(&mu_);
  ++commands_;
  const robot::ForkPose from = PoseAtLocked(now_s);
  robot::ForkPose to = setpoint;
  const Eigen::Vector3d step = to.p_TaskTip_m - from.p_TaskTip_m;
  const double max_step = options_.max_speed_mps * options_.control_period_s;
  if (step.norm() > max_step) {
    to.p_TaskTip_m = from.p_TaskTip_m + step * (max_step / step.norm());
  }
  Push({now_s, from, to});
  return absl::OkStatus();
}

absl::Status SimArm::Halt() {
  const double now_s = SteadyNowS();
  absl::MutexLock lock(&mu_);
  ++halts_;
  last_halt_s_ = now_s;
  const robot::ForkPose here = PoseAtLocked(now_s);
  Push({now_s, here, here});
  return absl::OkStatus();
}

robot::ForkPose SimArm::PoseAt(double time_s) const {
  absl::MutexLock lock(&mu_);
  return PoseAtLocked(time_s);
}

int SimArm::commands() const {
  absl::MutexLock lock(&mu_);
  return commands_;
}

int SimArm::halts() const {
  absl::MutexLock lock(&mu_);
  return halts_;
}

double SimArm::last_halt_s() const {
  absl::MutexLock lock(&mu_);
  return last_halt_s_;
}

robot::ForkPose SimArm::PoseAtLocked(double time_s) const {
  // The newest segment that had started by `time_s`.
  auto it =
      std::find_if(segments_.rbegin(), segments_.rend(),
                   [time_s](const Segment& s) { return s.start_s <= time_s; });
  const Segment& segment = it == segments_.rend() ? segments_.front() : *it;
  if (it == segments_.rend()) return segment.from;
  const double s = std::clamp(
      (time_s - segment.start_s) / options_.control_period_s, 0.0, 1.0);
  robot::ForkPose pose;
  pose.p_TaskTip_m = segment.from.p_TaskTip_m +
                     s * (segment.to.p_TaskTip_m - segment.from.p_TaskTip_m);
  pose.yaw_rad =
      segment.from.yaw_rad + s * (segment.to.yaw_rad - segment.from.yaw_rad);
  pose.pitch_rad = segment.from.pitch_rad +
                   s * (segment.to.pitch_rad - segment.from.pitch_rad);
  return pose;
}

void SimArm::Push(const Segment& segment) {
  segments_.push_back(segment);
  while (segments_.size() > kKeptSegments) segments_.pop_front();
}

}  // namespace bitewise::sim
