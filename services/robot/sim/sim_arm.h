// SimArm: a kinematic stand-in for the JACO2. Each command moves the fork
// tip in a straight line from where it is to the set point over one control
// period (a first-order hold, as a stiff Cartesian controller does), at no
// more than max_speed_mps; Halt() freezes it where it is. The pose is
// queryable at any recent time, so the simulated world can time the fork's
// contact with food at the F/T box's sample rate rather than at 100 Hz.
//
// Thread-safe.
#ifndef BITEWISE_SERVICES_ROBOT_SIM_SIM_ARM_H_
#define BITEWISE_SERVICES_ROBOT_SIM_SIM_ARM_H_

#include <deque>
#include <string>

#include "absl/base/thread_annotations.h"
#include "absl/synchronization/mutex.h"
#include "services/robot/arm.h"

namespace bitewise::sim {

struct SimArmOptions {
  // 0.15 m above the plate centre, fork vertical.
  robot::ForkPose home{Eigen::Vector3d(0.0, 0.0, 0.15), 0.0, 0.0};
  double control_period_s = 0.01;
  // The JACO2's Cartesian speed limit.
  double max_speed_mps = 0.2;
};

class SimArm final : public robot::Arm {
 public:
  explicit SimArm(const SimArmOptions& options);

  std::string name() const override { return "simulated arm"; }
  absl::Status MoveHome() override;
  absl::StatusOr<robot::ForkPose> MeasuredPose() override;
  absl::Status Command(const robot::ForkPose& setpoint,
                       const robot::ForkVelocity& velocity) override;
  absl::Status Halt() override;

  // The pose at `time_s` (SteadyNowS()); times older than the kept
  // history give the oldest known pose.
  robot::ForkPose PoseAt(double time_s) const;
  // How many Command() and Halt() calls arrived, and when the last halt was.
  int commands() const;
  int halts() const;
  double last_halt_s() const;

 private:
  struct Segment {
    double start_s;
    robot::ForkPose from;
    robot::ForkPose to;
  };
  robot::ForkPose PoseAtLocked(double time_s) const
      ABSL_SHARED_LOCKS_REQUIRED(mu_);
  void Push(const Segment& segment) ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_);

  const SimArmOptions options_;
  mutable absl::Mutex mu_;
  std::deque<Segment> segments_ ABSL_GUARDED_BY(mu_);
  int commands_ ABSL_GUARDED_BY(mu_) = 0;
  int halts_ ABSL_GUARDED_BY(mu_) = 0;
  double last_halt_s_ ABSL_GUARDED_BY(mu_) = -1.0;
};

}  // namespace bitewise::sim

#endif  // BITEWISE_SERVICES_ROBOT_SIM_SIM_ARM_H_
