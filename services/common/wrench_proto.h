// A force/torque trace on the wire (v1::WrenchSample, the API's one sample
// type) and in the core (domain::TimedWrench), both ways, written once for
// the RobotService's Acquire replies, the HapticService's Classify requests
// and the clients that pass a trace from one to the other.
#ifndef BITEWISE_SERVICES_COMMON_WRENCH_PROTO_H_
#define BITEWISE_SERVICES_COMMON_WRENCH_PROTO_H_

#include <vector>

#include "bitewise/v1/common.pb.h"
#include "google/protobuf/repeated_field.h"
#include "services/domain/wrench.h"

namespace bitewise {

inline domain::TimedWrench TimedWrenchFromProto(const v1::WrenchSample& s) {
  return {s.t_s(),
          {{s.fx_n(), s.fy_n(), s.fz_n()}, {s.tx_nm(), s.ty_nm(), s.tz_nm()}}};
}

inline void TimedWrenchToProto(const domain::TimedWrench& s,
                               v1::WrenchSample* out) {
  out->set_t_s(s.t_s);
  out->set_fx_n(s.wrench.force_n[0]);
  out->set_fy_n(s.wrench.force_n[1]);
  out->set_fz_n(s.wrench.force_n[2]);
  out->set_tx_nm(s.wrench.torque_nm[0]);
  out->set_ty_nm(s.wrench.torque_nm[1]);
  out->set_tz_nm(s.wrench.torque_nm[2]);
}

// Appends `trace` to a repeated WrenchSample field.
inline void AppendTraceToProto(
    const std::vector<domain::TimedWrench>& trace,
    google::protobuf::RepeatedPtrField<v1::WrenchSample>* out) {
  out->Reserve(out->size() + static_cast<int>(trace.size()));
  for (const domain::TimedWrench& s : trace) TimedWrenchToProto(s, out->Add());
}

}  // namespace bitewise

#endif  // BITEWISE_SERVICES_COMMON_WRENCH_PROTO_H_
