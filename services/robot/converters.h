// Conversions between the bitewise.v1 robot protos and the robot core's
// types, so the handlers read as validate, call, convert.
#ifndef BITEWISE_SERVICES_ROBOT_CONVERTERS_H_
#define BITEWISE_SERVICES_ROBOT_CONVERTERS_H_

#include "absl/status/statusor.h"
#include "bitewise/v1/robot.pb.h"
#include "services/robot/actions.h"
#include "services/robot/robot.h"

namespace bitewise::robot {

// INVALID_ARGUMENT when the request has no target or no centre.
absl::StatusOr<AcquireTarget> TargetFromProto(
    const v1::AcquireRequest& request);

void ActionToProto(const ActionSpec& action, v1::Action* proto);
v1::AcquirePhase PhaseToProto(AcquirePhase phase);
void OutcomeToProto(const AcquireOutcome& outcome, const ActionSpec& action,
                    v1::AcquireResult* proto);
void StatusToProto(const RobotStatusInfo& info, bool simulated, int items_left,
                   v1::RobotStatus* proto);

}  // namespace bitewise::robot

#endif  // BITEWISE_SERVICES_ROBOT_CONVERTERS_H_
