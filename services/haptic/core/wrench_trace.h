// The HapticService's view of a force/torque trace from the fork: timed
// six-axis samples in the sensor frame. Kept free of protos and of the
// simulated world so the haptic pipeline can be fed from the wire, from CSV
// files or from the simulator alike.
#ifndef BITEWISE_SERVICES_HAPTIC_CORE_WRENCH_TRACE_H_
#define BITEWISE_SERVICES_HAPTIC_CORE_WRENCH_TRACE_H_

#include "absl/status/status.h"
#include "absl/types/span.h"
#include "services/domain/haptic_class.h"
#include "services/domain/wrench.h"

namespace bitewise::haptic {

// A trace's sample (services/domain/wrench.h): t_s, then the wrench, whose
// channels HapticNet reads in the order fx, fy, fz (N), tx, ty, tz (N·m);
// Channel(), Channels() and WrenchFromChannels() work by that order.
using TimedWrench = domain::TimedWrench;
using domain::Channel;
using domain::Channels;
using domain::kWrenchChannels;
using domain::WrenchFromChannels;

// HapticNet's classes, in the order of its outputs
// (services/domain/haptic_class.h).
using HapticClass = domain::HapticClass;
inline constexpr int kHapticClasses = domain::kHapticClasses;
using domain::HapticClassName;

// What a trace may hold: forces up to 10 kN and torques up to 1 kN·m (far
// beyond the Forque's Nano25 and any Net F/T sensor, but finite ones that
// keep every later sum finite), and an average rate within HapticNet's
// trained range of 100 Hz to 7 kHz, with 10% slack either side.
inline constexpr double kMaxForceN = 1e4;
inline constexpr double kMaxTorqueNm = 1e3;
inline constexpr double kMinRateHz = 90.0;
inline constexpr double kMaxRateHz = 7700.0;

// Checks what every stage downstream relies on: at least `min_samples`
// samples, finite values within the limits above, strictly increasing
// timestamps, the average rate within the limits. INVALID_ARGUMENT naming
// the first offending sample and field (or the measured rate) otherwise.
absl::Status ValidateTrace(absl::Span<const TimedWrench> trace,
                           int min_samples);

}  // namespace bitewise::haptic

#endif  // BITEWISE_SERVICES_HAPTIC_CORE_WRENCH_TRACE_H_
