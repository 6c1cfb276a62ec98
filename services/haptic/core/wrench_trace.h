// The HapticService's view of a force/torque trace from the fork: timed
// six-axis samples in the sensor frame. Kept free of protos and of the
// simulated world so the haptic pipeline can be fed from the wire, from CSV
// files or from the simulator alike.
#ifndef BITEWISE_SERVICES_HAPTIC_CORE_WRENCH_TRACE_H_
#define BITEWISE_SERVICES_HAPTIC_CORE_WRENCH_TRACE_H_

#include <array>

#include "absl/status/status.h"
#include "absl/types/span.h"
#include "services/domain/haptic_class.h"

namespace bitewise::haptic {

// Channels in the order HapticNet reads them: fx, fy, fz (N), tx, ty, tz
// (N·m).
constexpr int kWrenchChannels = 6;

struct WrenchSample {
  double t_s = 0.0;
  // fx_n, fy_n, fz_n, tx_nm, ty_nm, tz_nm.
  std::array<double, kWrenchChannels> values{};
};

// HapticNet's classes, in the order of its outputs
// (services/domain/haptic_class.h).
using HapticClass = domain::HapticClass;
inline constexpr int kHapticClasses = domain::kHapticClasses;
using domain::HapticClassName;

// Checks what every stage downstream relies on: at least `min_samples`
// samples, finite values, strictly increasing timestamps. INVALID_ARGUMENT
// naming the first offending sample and field otherwise.
absl::Status ValidateTrace(absl::Span<const WrenchSample> trace,
                           int min_samples);

}  // namespace bitewise::haptic

#endif  // BITEWISE_SERVICES_HAPTIC_CORE_WRENCH_TRACE_H_
