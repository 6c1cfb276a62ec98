// ContactDetector finds the moment the fork first touches the food in a
// force/torque trace: it tares the sensor from the trace's quiet start,
// thresholds the tared force magnitude with hysteresis so a single noisy
// sample is never taken for contact, and extrapolates the rising edge back
// to zero force so the reported time does not lag on slowly rising (soft)
// foods. HapticNet's window starts at that time.
#ifndef BITEWISE_SERVICES_HAPTIC_CORE_CONTACT_DETECTOR_H_
#define BITEWISE_SERVICES_HAPTIC_CORE_CONTACT_DETECTOR_H_

#include <array>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/types/span.h"
#include "services/haptic/core/wrench_trace.h"

namespace bitewise::haptic {

struct ContactDetectorOptions {
  // The trace's first `tare_s` seconds are free motion; the per-channel
  // median over them is the sensor offset (bias) subtracted from every
  // sample. Default 0.05 s (5 samples at 100 Hz).
  double tare_s = 0.05;
  // Tared force magnitude (N) that starts contact. Default 1.0 N: well above
  // the Nano25's noise (about 0.15 N magnitude) and below any food's force.
  double threshold_n = 1.0;
  // Hysteresis: contact, once started, holds while the magnitude stays at or
  // above `release_n` (N). Default 0.5 N. Must not exceed threshold_n.
  double release_n = 0.5;
  // A contact must hold for this long (s) and for at least two samples;
  // shorter excursions above the threshold are noise. Default 0.003 s.
  double min_contact_s = 0.003;
  // Refuse (INVALID_ARGUMENT) a trace whose contact comes less than tare_s
  // after its first sample: its tare window held contact, so the offset,
  // and every force after it, is wrong. The service sets it; training and
  // the evaluation tools, whose simulated traces are built with the free
  // motion first, leave it off.
  bool require_free_tare = false;
};

// INVALID_ARGUMENT naming the field if the options are inconsistent.
absl::Status ValidateContactOptions(const ContactDetectorOptions& options);

struct ContactResult {
  // Sensor offset removed from every channel (N, N·m).
  std::array<double, kWrenchChannels> offset{};
  // Estimated time of first contact (s, the trace's clock).
  double contact_time_s = 0.0;
  // Index of the sample that crossed threshold_n and confirmed contact.
  int trigger_index = 0;
  // Largest tared force magnitude anywhere in the trace (N).
  double peak_force_n = 0.0;
};

// The sensor offset (bias) of `trace`: each channel's median over the samples
// less than `tare_s` seconds after the first (at least the first sample; the
// mean of the two middle values for an even count). A median rather than a
// mean, so that one spike during free motion does not shift the offset of
// the whole trace. `trace` must not be empty.
std::array<double, kWrenchChannels> SensorOffset(
    absl::Span<const TimedWrench> trace, double tare_s);

// The norm of `sample`'s force with `offset` (from SensorOffset) removed (N).
double TaredForceMagnitude(const TimedWrench& sample,
                           const std::array<double, kWrenchChannels>& offset);

// Stateless and thread-safe.
class ContactDetector {
 public:
  explicit ContactDetector(const ContactDetectorOptions& options)
      : options_(options) {}

  // Finds the first confirmed contact in `trace`, which must already have
  // passed ValidateTrace (finite, strictly increasing time). Errors:
  // FAILED_PRECONDITION when no contact is found, with the peak tared force
  // and the threshold in the message.
  absl::StatusOr<ContactResult> Detect(
      absl::Span<const TimedWrench> trace) const;

  const ContactDetectorOptions& options() const { return options_; }

 private:
  ContactDetectorOptions options_;
};

}  // namespace bitewise::haptic

#endif  // BITEWISE_SERVICES_HAPTIC_CORE_CONTACT_DETECTOR_H_
