#include "services/haptic/core/haptic_classifier.h"

#include <algorithm>

#include "absl/strings/str_cat.h"
#include "services/common/status_macros.h"

namespace bitewise::haptic {

absl::Status ValidatePipelineOptions(const HapticPipelineOptions& options) {
  RETURN_IF_ERROR(ValidateContactOptions(options.contact));
  RETURN_IF_ERROR(ValidateWindowOptions(options.window));
  if (options.min_trace_samples < 2) {
    return absl::InvalidArgumentError(absl::StrCat(
        "min_trace_samples must be >= 2, got ", options.min_trace_samples));
  }
  return absl::OkStatus();
}

absl::StatusOr<HapticFeatures> ExtractHapticFeatures(
    absl::Span<const TimedWrench> trace, const HapticPipelineOptions& options) {
  RETURN_IF_ERROR(ValidateTrace(trace, options.min_trace_samples));
  HapticFeatures features;
  ASSIGN_OR_RETURN(features.contact,
                   ContactDetector(options.contact).Detect(trace));
  ASSIGN_OR_RETURN(features.window,
                   ExtractWindow(trace, features.contact.contact_time_s,
                                 features.contact.offset, options.window));
  return features;
}

absl::StatusOr<HapticClassification> HapticClassifier::Classify(
    absl::Span<const TimedWrench> trace) const {
  ASSIGN_OR_RETURN(HapticFeatures features,
                   ExtractHapticFeatures(trace, options_));
  ASSIGN_OR_RETURN(HapticNetOutput output, net_->Run(features.window.inputs));
  HapticClassification result;
  result.probabilities = output.probabilities;
  result.log_probabilities = output.log_probabilities;
  result.category = static_cast<HapticClass>(
      std::max_element(output.log_probabilities.begin(),
                       output.log_probabilities.end()) -
      output.log_probabilities.begin());
  result.contact_time_s = features.contact.contact_time_s;
  result.peak_force_n = features.contact.peak_force_n;
  if (familiarity_ != nullptr) {
    result.has_familiarity = true;
    result.familiarity =
        familiarity_->Score(FamiliarityFeatures(features.window.inputs));
  }
  return result;
}

}  // namespace bitewise::haptic
