#include "services/haptic/converters.h"

namespace bitewise::haptic {

std::vector<TimedWrench> TraceFromProto(const v1::ClassifyRequest& request) {
  std::vector<TimedWrench> trace;
  trace.reserve(request.samples_size());
  for (const v1::WrenchSample& s : request.samples()) {
    trace.push_back(
        {s.t_s(),
         {{s.fx_n(), s.fy_n(), s.fz_n()}, {s.tx_nm(), s.ty_nm(), s.tz_nm()}}});
  }
  return trace;
}

void TraceToProto(const std::vector<TimedWrench>& trace,
                  v1::ClassifyRequest* request) {
  for (const TimedWrench& s : trace) {
    v1::WrenchSample* out = request->add_samples();
    out->set_t_s(s.t_s);
    out->set_fx_n(s.wrench.force_n[0]);
    out->set_fy_n(s.wrench.force_n[1]);
    out->set_fz_n(s.wrench.force_n[2]);
    out->set_tx_nm(s.wrench.torque_nm[0]);
    out->set_ty_nm(s.wrench.torque_nm[1]);
    out->set_tz_nm(s.wrench.torque_nm[2]);
  }
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
}

}  // namespace bitewise::haptic
