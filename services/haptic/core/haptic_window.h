// HapticNet's input: the tared trace from first contact, over a fixed
// window, resampled per channel to 64 evenly spaced points by linear
// interpolation on the timestamps, so sensors running anywhere from 100 Hz
// to 7 kHz (and with jittery clocks) give the network the same picture.
#ifndef BITEWISE_SERVICES_HAPTIC_CORE_HAPTIC_WINDOW_H_
#define BITEWISE_SERVICES_HAPTIC_CORE_HAPTIC_WINDOW_H_

#include <array>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/types/span.h"
#include "services/haptic/core/wrench_trace.h"

namespace bitewise::haptic {

// Points per channel after resampling; HapticNet takes 6 x 64 = 384 inputs.
constexpr int kWindowPoints = 64;
constexpr int kHapticInputs = kWrenchChannels * kWindowPoints;

struct WindowOptions {
  // Length of the window after contact (s). Default 0.05 s, as in the
  // original HapticNet.
  double window_s = 0.05;
  // At low sample rates the window is stretched until it holds this many
  // samples after contact (at 100 Hz a 50 ms window holds only 5). Default
  // 5, so stretching starts below 100 Hz.
  int min_window_samples = 5;
};

// INVALID_ARGUMENT naming the field if the options are out of range.
absl::Status ValidateWindowOptions(const WindowOptions& options);

// Linear interpolation of every channel of `trace` at each time in
// `times_s`; times outside the trace take the nearest end sample. `trace`
// must be non-empty with strictly increasing timestamps; `times_s` must be
// non-decreasing.
std::vector<std::array<double, kWrenchChannels>> ResampleLinear(
    absl::Span<const TimedWrench> trace, absl::Span<const double> times_s);

struct HapticWindow {
  // Channel-major: inputs[c * 64 + k] is channel c (fx, fy, fz, tx, ty, tz)
  // at start_s + k * (end_s - start_s) / 63, minus the sensor offset.
  std::array<float, kHapticInputs> inputs{};
  double start_s = 0.0;
  double end_s = 0.0;
};

// The window of `trace` starting at `contact_time_s`, with `offset`
// subtracted. Errors: INVALID_ARGUMENT when fewer than min_window_samples
// samples follow the contact (the trace ends too soon).
absl::StatusOr<HapticWindow> ExtractWindow(
    absl::Span<const TimedWrench> trace, double contact_time_s,
    const std::array<double, kWrenchChannels>& offset,
    const WindowOptions& options);

}  // namespace bitewise::haptic

#endif  // BITEWISE_SERVICES_HAPTIC_CORE_HAPTIC_WINDOW_H_
