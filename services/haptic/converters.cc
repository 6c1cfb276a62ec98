#include "services/haptic/converters.h"

#include "services/common/wrench_proto.h"

namespace bitewise::haptic {

std::vector<TimedWrench> TraceFromProto(const v1::ClassifyRequest& request) {
  std::vector<TimedWrench> trace;
  trace.reserve(request.samples_size());
  for (const v1::WrenchSample& s : request.samples()) {
    trace.push_back(TimedWrenchFromProto(s));
  }
  return trace;
}

void TraceToProto(const std::vector<TimedWrench>& trace,
                  v1::ClassifyRequest* request) {
  AppendTraceToProto(trace, request->mutable_samples());
}

v1::HapticCategory CategoryToProto(HapticClass haptic_class) {
  switch (haptic_class) {
    case HapticClass::kHard:
      return v1::HAPTIC_CATEGORY_HARD;
    case HapticClass::kMedium:
      return v1::HAPTIC_CATEGORY_MEDIUM;
    case HapticClass::kSoft:
      return v1::HAPTIC_CATEGORY_SOFT;
    case HapticClass::kHardSkin:
      return v1::HAPTIC_CATEGORY_HARD_SKIN;
  }
  return v1::HAPTIC_CATEGORY_UNSPECIFIED;
}

void ClassificationToProto(const HapticClassification& result,
                           const std::string& model_fingerprint,
                           v1::ClassifyResponse* response) {
  response->mutable_probabilities()->Add(result.probabilities.begin(),
                                         result.probabilities.end());
  response->mutable_log_probabilities()->Add(result.log_probabilities.begin(),
                                             result.log_probabilities.end());
  response->set_category(CategoryToProto(result.category));
  response->set_contact_time_s(result.contact_time_s);
  response->set_peak_force_n(result.peak_force_n);
  response->set_model_fingerprint(model_fingerprint);
  if (result.has_familiarity) {
    response->set_familiarity(result.familiarity.familiarity);
    response->set_unfamiliar(result.familiarity.unfamiliar);
  }
}

}  // namespace bitewise::haptic
