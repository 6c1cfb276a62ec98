// The simulated arm (services/robot/sim/sim_arm.h): each command moves the
// tip in a straight line over one control period, no further than the speed
// limit allows, a halt freezes it where it is, a non-finite set point moves
// nothing, and the pose is known back through the kept history.
#include "services/robot/sim/sim_arm.h"

#include <chrono>
#include <cmath>
#include <limits>
#include <thread>

#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "services/domain/steady_time.h"

namespace bitewise::sim {
namespace {

using robot::ForkPose;
using ::testing::HasSubstr;

// Later than any segment of a test ends.
double Far() { return SteadyNowS() + 1e6; }

ForkPose Pose(double x, double y, double z, double yaw, double pitch) {
  return ForkPose{Eigen::Vector3d(x, y, z), yaw, pitch};
}

void ExpectPoseNear(const ForkPose& got, const ForkPose& want, double tol) {
  EXPECT_NEAR((got.p_TaskTip_m - want.p_TaskTip_m).norm(), 0.0, tol)
      << got.p_TaskTip_m.transpose() << " vs " << want.p_TaskTip_m.transpose();
  EXPECT_NEAR(got.yaw_rad, want.yaw_rad, tol);
  EXPECT_NEAR(got.pitch_rad, want.pitch_rad, tol);
}

TEST(SimArmTest, StartsAtHomeAndMoveHomeReturnsThereAtOnce) {
  SimArmOptions options;
  options.home = Pose(0.01, -0.02, 0.2, 0.3, 0.1);
  SimArm arm(options);
  absl::StatusOr<ForkPose> measured = arm.MeasuredPose();
  ASSERT_TRUE(measured.ok()) << measured.status();
  ExpectPoseNear(*measured, options.home, 0.0);

  ASSERT_TRUE(arm.Command(Pose(0.011, -0.02, 0.2, 0.5, 0.2), {}).ok());
  ASSERT_TRUE(arm.MoveHome().ok());
  ExpectPoseNear(*arm.MeasuredPose(), options.home, 0.0);
  ExpectPoseNear(arm.PoseAt(Far()), options.home, 0.0);
  EXPECT_EQ(arm.commands(), 1);
}

TEST(SimArmTest, ASetPointWithinTheSpeedLimitIsReachedAfterOnePeriod) {
  SimArmOptions options;  // 0.2 m/s over 10 ms: 2 mm a command
  SimArm arm(options);
  const ForkPose target = Pose(0.001, 0.0005, 0.1495, 0.2, -0.1);
  const double before_s = SteadyNowS();
  ASSERT_TRUE(arm.Command(target, {}).ok());
  const double after_s = SteadyNowS();
  ExpectPoseNear(arm.PoseAt(after_s + options.control_period_s), target, 1e-15);
  // Before the command the tip was at home.
  ExpectPoseNear(arm.PoseAt(before_s), options.home, 0.0);
  EXPECT_EQ(arm.commands(), 1);
  EXPECT_EQ(arm.halts(), 0);
}

TEST(SimArmTest, TheTipMovesInAStraightLineAtAConstantRateOverThePeriod) {
  SimArmOptions options;
  options.control_period_s = 10.0;  // slow enough to look inside
  options.max_speed_mps = 1.0;      // 10 m a command: no clipping
  SimArm arm(options);
  const ForkPose target = Pose(0.1, -0.2, 0.05, 1.0, 0.5);
  const double before_s = SteadyNowS();
  ASSERT_TRUE(arm.Command(target, {}).ok());
  const double after_s = SteadyNowS();
  // Halfway through the period (give or take the call's own duration).
  const ForkPose mid = arm.PoseAt(after_s + 5.0);
  const double s_lo = (after_s + 5.0 - after_s) / options.control_period_s;
  const double s_hi = (after_s + 5.0 - before_s) / options.control_period_s;
  const Eigen::Vector3d home = options.home.p_TaskTip_m;
  const Eigen::Vector3d step = target.p_TaskTip_m - home;
  // The fraction travelled, read off x, is the same on every axis.
  const double s = (mid.p_TaskTip_m.x() - home.x()) / step.x();
  EXPECT_GE(s, s_lo - 1e-12);
  EXPECT_LE(s, s_hi + 1e-12);
  EXPECT_NEAR(mid.p_TaskTip_m.y(), home.y() + s * step.y(), 1e-12);
  EXPECT_NEAR(mid.p_TaskTip_m.z(), home.z() + s * step.z(), 1e-12);
  EXPECT_NEAR(mid.yaw_rad, s * target.yaw_rad, 1e-12);
  EXPECT_NEAR(mid.pitch_rad, s * target.pitch_rad, 1e-12);
}

TEST(SimArmTest, AFarSetPointIsApproachedOneSpeedLimitedStepAtATime) {
  SimArmOptions options;
  const double max_step_m = options.max_speed_mps * options.control_period_s;
  SimArm arm(options);
  // 10 cm away along (3, 4, 0) / 5; orientation is not speed limited.
  const Eigen::Vector3d direction(0.6, 0.8, 0.0);
  const ForkPose far_target{options.home.p_TaskTip_m + 0.1 * direction, 0.4,
                            -0.2};
  constexpr int kCommands = 4;
  for (int i = 1; i <= kCommands; ++i) {
    ASSERT_TRUE(arm.Command(far_target, {}).ok());
    const ForkPose reached = arm.PoseAt(Far());
    const Eigen::Vector3d moved =
        reached.p_TaskTip_m - options.home.p_TaskTip_m;
    EXPECT_NEAR(moved.norm(), i * max_step_m, 1e-12) << "command " << i;
    EXPECT_NEAR(moved.normalized().dot(direction), 1.0, 1e-12);
    EXPECT_EQ(reached.yaw_rad, 0.4);
    EXPECT_EQ(reached.pitch_rad, -0.2);
    // The next command starts where this one ended.
    std::this_thread::sleep_for(
        std::chrono::duration<double>(options.control_period_s * 1.5));
  }
  EXPECT_EQ(arm.commands(), kCommands);
}

TEST(SimArmTest, HaltFreezesTheTipPartWayAlongItsMove) {
  SimArmOptions options;
  options.control_period_s = 10.0;
  options.max_speed_mps = 1.0;
  SimArm arm(options);
  const ForkPose target = Pose(1.0, 0.0, 0.15, 0.0, 0.0);
  const double command_before_s = SteadyNowS();
  ASSERT_TRUE(arm.Command(target, {}).ok());
  const double command_after_s = SteadyNowS();
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  const double halt_before_s = SteadyNowS();
  ASSERT_TRUE(arm.Halt().ok());
  const double halt_after_s = SteadyNowS();

  EXPECT_EQ(arm.halts(), 1);
  EXPECT_GE(arm.last_halt_s(), halt_before_s);
  EXPECT_LE(arm.last_halt_s(), halt_after_s);
  const ForkPose frozen = arm.PoseAt(Far());
  ExpectPoseNear(arm.PoseAt(arm.last_halt_s()), frozen, 0.0);
  // Where the line had got to when the halt came, and no further.
  EXPECT_GE(
      frozen.p_TaskTip_m.x(),
      (arm.last_halt_s() - command_after_s) / options.control_period_s - 1e-12);
  EXPECT_LE(frozen.p_TaskTip_m.x(),
            (arm.last_halt_s() - command_before_s) / options.control_period_s +
                1e-12);
  EXPECT_GT(frozen.p_TaskTip_m.x(), 0.0);
}

TEST(SimArmTest, ANonFiniteSetPointIsRefusedAndMovesNothing) {
  SimArmOptions options;
  SimArm arm(options);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  for (const ForkPose& bad :
       {Pose(nan, 0.0, 0.1, 0.0, 0.0), Pose(0.0, 0.0, -inf, 0.0, 0.0),
        Pose(0.0, 0.0, 0.1, nan, 0.0), Pose(0.0, 0.0, 0.1, 0.0, inf)}) {
    const absl::Status status = arm.Command(bad, {});
    EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
    EXPECT_THAT(status.message(), HasSubstr("not finite"));
  }
  EXPECT_EQ(arm.commands(), 0);
  ExpectPoseNear(arm.PoseAt(Far()), options.home, 0.0);
}

TEST(SimArmTest, TimesBeforeTheKeptHistoryGiveTheOldestKeptPose) {
  SimArmOptions options;
  options.home = Pose(0.0, 0.0, 0.15, 0.0, 0.0);
  options.control_period_s = 1e-6;
  options.max_speed_mps = 1e6;
  SimArm arm(options);
  // 600 moves of 1 mm, each finished before the next: with the first
  // segment (home) that is 601, of which the newest 512 are kept.
  constexpr int kCommands = 600;
  for (int i = 1; i <= kCommands; ++i) {
    ASSERT_TRUE(arm.Command(Pose(i * 0.001, 0.0, 0.15, 0.0, 0.0), {}).ok());
    std::this_thread::sleep_for(std::chrono::microseconds(2));
  }
  EXPECT_EQ(arm.commands(), kCommands);
  EXPECT_NEAR(arm.PoseAt(Far()).p_TaskTip_m.x(), 0.6, 1e-12);
  // The oldest kept segment is command 89's, which started from 88 mm.
  const double oldest_command = kCommands + 1 - 512;
  EXPECT_NEAR(arm.PoseAt(0.0).p_TaskTip_m.x(), (oldest_command - 1) * 0.001,
              1e-12);
}

}  // namespace
}  // namespace bitewise::sim
