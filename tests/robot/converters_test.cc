// The RobotService's proto conversions (services/robot/converters.h): a
// request without a target is refused naming the field, and outcomes,
// phases and status reach the wire field by field.
#include "services/robot/converters.h"

#include <string>
#include <vector>

#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace bitewise::robot {
namespace {

using ::testing::HasSubstr;

TEST(TargetFromProtoTest, CopiesTheCentreAndTheAxisAngle) {
  v1::AcquireRequest request;
  request.mutable_target()->mutable_center_camera_m()->set_x(0.01);
  request.mutable_target()->mutable_center_camera_m()->set_y(-0.02);
  request.mutable_target()->mutable_center_camera_m()->set_z(0.35);
  request.mutable_target()->set_major_axis_angle_rad(0.7);
  const absl::StatusOr<AcquireTarget> target = TargetFromProto(request);
  ASSERT_TRUE(target.ok()) << target.status();
  EXPECT_EQ(target->p_CameraItem_m, Eigen::Vector3d(0.01, -0.02, 0.35));
  EXPECT_EQ(target->major_axis_angle_rad, 0.7);
}

TEST(TargetFromProtoTest, ARequestWithoutTargetOrCentreIsRefusedNamingIt) {
  v1::AcquireRequest no_target;
  v1::AcquireRequest no_centre;
  no_centre.mutable_target()->set_major_axis_angle_rad(0.3);
  for (const v1::AcquireRequest& request : {no_target, no_centre}) {
    const absl::Status status = TargetFromProto(request).status();
    EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
    EXPECT_THAT(status.message(), HasSubstr("target.center_camera_m"));
  }
}

TEST(PhaseToProtoTest, EveryPhaseHasItsOwnValueAndIdleIsUnspecified) {
  EXPECT_EQ(PhaseToProto(AcquirePhase::kIdle), v1::ACQUIRE_PHASE_UNSPECIFIED);
  EXPECT_EQ(PhaseToProto(AcquirePhase::kApproach), v1::ACQUIRE_PHASE_APPROACH);
  EXPECT_EQ(PhaseToProto(AcquirePhase::kOrient), v1::ACQUIRE_PHASE_ORIENT);
  EXPECT_EQ(PhaseToProto(AcquirePhase::kDescend), v1::ACQUIRE_PHASE_DESCEND);
  EXPECT_EQ(PhaseToProto(AcquirePhase::kExtract), v1::ACQUIRE_PHASE_EXTRACT);
  EXPECT_EQ(PhaseToProto(AcquirePhase::kDone), v1::ACQUIRE_PHASE_DONE);
}

TEST(OutcomeToProtoTest, CarriesTheOutcomeTheActionAndTheRawTrace) {
  AcquireOutcome outcome;
  outcome.attempt.success = true;
  outcome.attempt.decided_by_operator = true;
  outcome.attempt.true_food_type = "grape";
  outcome.attempt.true_haptic_class = domain::HapticClass::kHardSkin;
  outcome.trace = {{0.5, {{1.0, 2.0, 3.0}, {0.1, 0.2, 0.3}}},
                   {0.501, {{-1.5, 0.0, 7.25}, {0.0, -0.4, 0.05}}}};
  outcome.peak_force_n = 7.5;
  outcome.force_limit_reached = true;
  outcome.contact_time_s = 0.42;
  outcome.static_load_n = 0.3;
  outcome.duration_s = 2.5;
  outcome.dry_run = true;
  const ActionSpec action{3, "TV90", 0.4, 1.57, 12.0};

  v1::AcquireResult proto;
  OutcomeToProto(outcome, action, &proto);
  EXPECT_TRUE(proto.success());
  EXPECT_TRUE(proto.success_decided_by_operator());
  EXPECT_EQ(proto.true_food_type(), "grape");
  EXPECT_EQ(proto.true_haptic_category(), v1::HAPTIC_CATEGORY_HARD_SKIN);
  EXPECT_EQ(proto.peak_force_n(), 7.5);
  EXPECT_TRUE(proto.force_limit_reached());
  EXPECT_EQ(proto.contact_time_s(), 0.42);
  EXPECT_EQ(proto.static_load_n(), 0.3);
  EXPECT_EQ(proto.duration_s(), 2.5);
  EXPECT_TRUE(proto.dry_run());
  EXPECT_EQ(proto.action().index(), 3);
  EXPECT_EQ(proto.action().name(), "TV90");
  EXPECT_EQ(proto.action().pitch_rad(), 0.4);
  EXPECT_EQ(proto.action().roll_rad(), 1.57);
  EXPECT_EQ(proto.action().max_force_n(), 12.0);
  ASSERT_EQ(proto.trace_size(), 2);
  for (int i = 0; i < 2; ++i) {
    const domain::TimedWrench& want = outcome.trace[i];
    const v1::WrenchSample& got = proto.trace(i);
    EXPECT_EQ(got.t_s(), want.t_s);
    EXPECT_EQ(got.fx_n(), want.wrench.force_n[0]);
    EXPECT_EQ(got.fy_n(), want.wrench.force_n[1]);
    EXPECT_EQ(got.fz_n(), want.wrench.force_n[2]);
    EXPECT_EQ(got.tx_nm(), want.wrench.torque_nm[0]);
    EXPECT_EQ(got.ty_nm(), want.wrench.torque_nm[1]);
    EXPECT_EQ(got.tz_nm(), want.wrench.torque_nm[2]);
  }
}

TEST(OutcomeToProtoTest, EachTrueHapticClassBecomesItsCategory) {
  const std::vector<std::pair<domain::HapticClass, v1::HapticCategory>> pairs =
      {{domain::HapticClass::kHard, v1::HAPTIC_CATEGORY_HARD},
       {domain::HapticClass::kMedium, v1::HAPTIC_CATEGORY_MEDIUM},
       {domain::HapticClass::kSoft, v1::HAPTIC_CATEGORY_SOFT},
       {domain::HapticClass::kHardSkin, v1::HAPTIC_CATEGORY_HARD_SKIN}};
  for (const auto& [haptic_class, category] : pairs) {
    AcquireOutcome outcome;
    outcome.attempt.true_haptic_class = haptic_class;
    v1::AcquireResult proto;
    OutcomeToProto(outcome, ActionSpec(), &proto);
    EXPECT_EQ(proto.true_haptic_category(), category)
        << domain::HapticClassName(haptic_class);
  }
}

TEST(OutcomeToProtoTest, HardwareOutcomesLeaveTheTrueCategoryUnspecified) {
  AcquireOutcome outcome;
  outcome.attempt.success = true;
  v1::AcquireResult proto;
  OutcomeToProto(outcome, ActionSpec(), &proto);
  EXPECT_EQ(proto.true_haptic_category(), v1::HAPTIC_CATEGORY_UNSPECIFIED);
  EXPECT_EQ(proto.true_food_type(), "");
  EXPECT_EQ(proto.trace_size(), 0);
}

TEST(StatusToProtoTest, CarriesTheArmTheSensorAndItsCounterClock) {
  RobotStatusInfo info;
  info.arm_ready = true;
  info.arm_name = "JACO2 (USB)";
  info.ft_name = "Net F/T 192.168.1.1";
  info.ft_health.state = netft::StreamState::kStreaming;
  info.ft_health.rate_hz = 6998.5;
  info.ft_health.silent_for_s = 0.002;
  info.ft_health.counter.state = netft::CounterClockState::kFault;
  info.ft_health.counter.rate_hz = 7000.0;
  info.ft_health.counter.measured_rate_hz = 3500.0;
  info.ft_health.counter.problem = "counter runs at half the rate";
  info.ft_health.readings_unchanged_s = 0.25;
  info.ft_health.readings_unchanged_records = 1750;
  info.ft_stats.packets_lost = 11;
  info.ft_stats.samples_accepted = 123456;
  info.ft_stats.out_of_order = 3;
  info.ft_stats.stale_dropped = 4;
  info.ft_stats.malformed = 5;
  info.ft_stats.last_status = 0x80000000u;
  info.busy_with = AcquirePhase::kDescend;

  v1::RobotStatus proto;
  StatusToProto(info, /*simulated=*/false, /*items_left=*/-1, &proto);
  EXPECT_FALSE(proto.simulated());
  EXPECT_TRUE(proto.arm_ready());
  EXPECT_EQ(proto.arm_name(), "JACO2 (USB)");
  EXPECT_EQ(proto.ft_sensor(), "Net F/T 192.168.1.1");
  EXPECT_TRUE(proto.ft_streaming());
  EXPECT_EQ(proto.ft_state(), "streaming");
  EXPECT_EQ(proto.ft_rate_hz(), 6998.5);
  EXPECT_EQ(proto.ft_silent_for_s(), 0.002);
  EXPECT_EQ(proto.ft_packets_lost(), 11u);
  EXPECT_EQ(proto.ft_samples(), 123456u);
  EXPECT_EQ(proto.ft_out_of_order(), 3u);
  EXPECT_EQ(proto.ft_stale_dropped(), 4u);
  EXPECT_EQ(proto.ft_malformed(), 5u);
  EXPECT_EQ(proto.ft_status_word(), 0x80000000u);
  EXPECT_EQ(proto.ft_counter_state(), "fault");
  EXPECT_EQ(proto.ft_counter_rate_hz(), 7000.0);
  EXPECT_EQ(proto.ft_counter_measured_hz(), 3500.0);
  EXPECT_EQ(proto.ft_counter_problem(), "counter runs at half the rate");
  EXPECT_EQ(proto.ft_readings_unchanged_s(), 0.25);
  EXPECT_EQ(proto.ft_readings_unchanged_records(), 1750u);
  EXPECT_EQ(proto.busy_with(), "descend");
  EXPECT_EQ(proto.items_left(), -1);
}

TEST(StatusToProtoTest, AnIdleRobotWithASilentSensorIsNotStreamingNorBusy) {
  RobotStatusInfo info;
  info.ft_health.state = netft::StreamState::kSilent;
  v1::RobotStatus proto;
  StatusToProto(info, /*simulated=*/true, /*items_left=*/4, &proto);
  EXPECT_TRUE(proto.simulated());
  EXPECT_FALSE(proto.ft_streaming());
  EXPECT_EQ(proto.ft_state(), "silent");
  EXPECT_EQ(proto.ft_counter_state(), "verifying");
  EXPECT_EQ(proto.busy_with(), "");
  EXPECT_EQ(proto.items_left(), 4);

  info.ft_health.state = netft::StreamState::kWaitingForData;
  StatusToProto(info, true, 4, &proto);
  EXPECT_FALSE(proto.ft_streaming());
  EXPECT_EQ(proto.ft_state(), "waiting for data");
}

}  // namespace
}  // namespace bitewise::robot
