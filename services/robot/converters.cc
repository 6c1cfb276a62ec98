#include "services/robot/converters.h"

#include <string>

#include "absl/strings/str_cat.h"
#include "services/common/wrench_proto.h"

namespace bitewise::robot {

absl::StatusOr<AcquireTarget> TargetFromProto(
    const v1::AcquireRequest& request) {
  if (!request.has_target() || !request.target().has_center_camera_m()) {
    return absl::InvalidArgumentError(
        "target.center_camera_m is required (the item's top-surface centre "
        "in the camera frame, metres)");
  }
  const v1::Point3& c = request.target().center_camera_m();
  AcquireTarget target;
  target.p_CameraItem_m = Eigen::Vector3d(c.x(), c.y(), c.z());
  target.major_axis_angle_rad = request.target().major_axis_angle_rad();
  return target;
}

void ActionToProto(const ActionSpec& action, v1::Action* proto) {
  proto->set_index(action.index);
  proto->set_name(action.name);
  proto->set_pitch_rad(action.pitch_rad);
  proto->set_roll_rad(action.roll_rad);
  proto->set_max_force_n(action.max_force_n);
}

v1::AcquirePhase PhaseToProto(AcquirePhase phase) {
  switch (phase) {
    case AcquirePhase::kIdle:
      return v1::ACQUIRE_PHASE_UNSPECIFIED;
    case AcquirePhase::kApproach:
      return v1::ACQUIRE_PHASE_APPROACH;
    case AcquirePhase::kOrient:
      return v1::ACQUIRE_PHASE_ORIENT;
    case AcquirePhase::kDescend:
      return v1::ACQUIRE_PHASE_DESCEND;
    case AcquirePhase::kExtract:
      return v1::ACQUIRE_PHASE_EXTRACT;
    case AcquirePhase::kDone:
      return v1::ACQUIRE_PHASE_DONE;
  }
  return v1::ACQUIRE_PHASE_UNSPECIFIED;
}

void OutcomeToProto(const AcquireOutcome& outcome, const ActionSpec& action,
                    v1::AcquireResult* proto) {
  proto->set_success(outcome.attempt.success);
  proto->set_success_decided_by_operator(outcome.attempt.decided_by_operator);
  proto->set_true_food_type(outcome.attempt.true_food_type);
  if (outcome.attempt.true_haptic_class.has_value()) {
    // HapticCategory is HapticClass + 1 (UNSPECIFIED is 0).
    proto->set_true_haptic_category(static_cast<v1::HapticCategory>(
        static_cast<int>(*outcome.attempt.true_haptic_class) + 1));
  }
  proto->set_peak_force_n(outcome.peak_force_n);
  proto->set_force_limit_reached(outcome.force_limit_reached);
  proto->set_contact_time_s(outcome.contact_time_s);
  proto->set_static_load_n(outcome.static_load_n);
  proto->set_duration_s(outcome.duration_s);
  proto->set_dry_run(outcome.dry_run);
  ActionToProto(action, proto->mutable_action());
  AppendTraceToProto(outcome.trace, proto->mutable_trace());
}

void StatusToProto(const RobotStatusInfo& info, bool simulated, int items_left,
                   v1::RobotStatus* proto) {
  proto->set_simulated(simulated);
  proto->set_arm_ready(info.arm_ready);
  proto->set_arm_name(info.arm_name);
  proto->set_ft_streaming(info.ft_health.state ==
                          netft::StreamState::kStreaming);
  proto->set_ft_rate_hz(info.ft_health.rate_hz);
  proto->set_ft_packets_lost(info.ft_stats.packets_lost);
  proto->set_ft_sensor(info.ft_name);
  proto->set_ft_state(netft::StreamStateName(info.ft_health.state));
  proto->set_ft_silent_for_s(info.ft_health.silent_for_s);
  proto->set_ft_samples(info.ft_stats.samples_accepted);
  proto->set_ft_out_of_order(info.ft_stats.out_of_order);
  proto->set_ft_stale_dropped(info.ft_stats.stale_dropped);
  proto->set_ft_malformed(info.ft_stats.malformed);
  proto->set_ft_status_word(info.ft_stats.last_status);
  proto->set_ft_counter_state(
      netft::CounterClockStateName(info.ft_health.counter.state));
  proto->set_ft_counter_rate_hz(info.ft_health.counter.rate_hz);
  proto->set_ft_counter_measured_hz(info.ft_health.counter.measured_rate_hz);
  proto->set_ft_counter_problem(info.ft_health.counter.problem);
  proto->set_ft_readings_unchanged_s(info.ft_health.readings_unchanged_s);
  proto->set_ft_readings_unchanged_records(
      info.ft_health.readings_unchanged_records);
  proto->set_busy_with(info.busy_with == AcquirePhase::kIdle
                           ? ""
                           : AcquirePhaseName(info.busy_with));
  proto->set_items_left(items_left);
}

}  // namespace bitewise::robot
