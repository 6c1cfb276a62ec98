// HapticClassifier is the whole HapticService pipeline without gRPC: check
// the trace, find first contact, cut and resample the window, run HapticNet.
// Its answer is the post hoc context the bandit learns from.
#ifndef BITEWISE_SERVICES_HAPTIC_CORE_HAPTIC_CLASSIFIER_H_
#define BITEWISE_SERVICES_HAPTIC_CORE_HAPTIC_CLASSIFIER_H_

#include <array>
#include <memory>
#include <string>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/types/span.h"
#include "services/haptic/core/contact_detector.h"
#include "services/haptic/core/familiarity.h"
#include "services/haptic/core/haptic_net.h"
#include "services/haptic/core/haptic_window.h"
#include "services/haptic/core/wrench_trace.h"

namespace bitewise::haptic {

struct HapticPipelineOptions {
  ContactDetectorOptions contact;
  WindowOptions window;
  // Fewer samples than this are rejected before any processing. Default 8:
  // a tare, a contact and a minimal window.
  int min_trace_samples = 8;
};

// INVALID_ARGUMENT naming the field if any option is out of range.
absl::Status ValidatePipelineOptions(const HapticPipelineOptions& options);

// Everything up to the network: contact and window. Shared by the
// classifier and the trainer so both see identical inputs.
struct HapticFeatures {
  ContactResult contact;
  HapticWindow window;
};

// Validates `trace` and extracts its window. Errors: INVALID_ARGUMENT for
// too few samples, non-finite values, non-increasing timestamps or a trace
// that ends too soon after contact; FAILED_PRECONDITION when there is no
// contact (the message gives the peak force).
absl::StatusOr<HapticFeatures> ExtractHapticFeatures(
    absl::Span<const TimedWrench> trace, const HapticPipelineOptions& options);

struct HapticClassification {
  std::array<double, kHapticClasses> probabilities{};
  std::array<double, kHapticClasses> log_probabilities{};
  HapticClass category = HapticClass::kHard;
  double contact_time_s = 0.0;
  double peak_force_n = 0.0;
  // How familiar the trace is (familiarity.h); only when the classifier
  // has a familiarity model (has_familiarity).
  bool has_familiarity = false;
  FamiliarityScore familiarity;
};

// Thread-safe.
class HapticClassifier {
 public:
  // `options` must have passed ValidatePipelineOptions. `familiarity`
  // null: answers carry no familiarity score.
  HapticClassifier(std::unique_ptr<HapticNet> net,
                   const HapticPipelineOptions& options,
                   std::unique_ptr<FamiliarityModel> familiarity = nullptr)
      : net_(std::move(net)),
        options_(options),
        familiarity_(std::move(familiarity)) {}

  // Errors as ExtractHapticFeatures; INTERNAL if the network fails.
  absl::StatusOr<HapticClassification> Classify(
      absl::Span<const TimedWrench> trace) const;

  const HapticNet& net() const { return *net_; }
  const HapticPipelineOptions& options() const { return options_; }
  // Null when there is no familiarity model.
  const FamiliarityModel* familiarity() const { return familiarity_.get(); }

 private:
  const std::unique_ptr<HapticNet> net_;
  const HapticPipelineOptions options_;
  const std::unique_ptr<FamiliarityModel> familiarity_;
};

}  // namespace bitewise::haptic

#endif  // BITEWISE_SERVICES_HAPTIC_CORE_HAPTIC_CLASSIFIER_H_
