// The labelled force/torque trace CSV: what bitewise-haptic-train reads and
// what the meal's trace recording (clients/meal/trace_recording.h) and the
// trainer's --write_traces write (docs/haptic.md):
//
//   trace,label,t_s,fx_n,fy_n,fz_n,tx_nm,ty_nm,tz_nm
//   0,hard,0,0.01,-0.02,0.3,0.001,0.0,-0.002
//
// one row per sample, a trace's rows contiguous and in time order, its label
// (HapticClassName: hard, medium, soft, hard_skin; or "unknown" when nobody
// knew the food) on every row. Defined once here.
#ifndef BITEWISE_SERVICES_DOMAIN_TRACE_CSV_H_
#define BITEWISE_SERVICES_DOMAIN_TRACE_CSV_H_

#include <array>
#include <cstdio>
#include <string>

namespace bitewise::domain {

inline constexpr char kTraceCsvHeader[] =
    "trace,label,t_s,fx_n,fy_n,fz_n,tx_nm,ty_nm,tz_nm";
inline constexpr int kTraceCsvFields = 9;
// The label of a recorded trace whose food nobody named.
inline constexpr char kUnlabelled[] = "unknown";

// Appends one sample's row (and its newline) to `out`. Numbers as %.17g, so
// doubles survive the round trip exactly.
inline void AppendTraceCsvRow(std::string* out, const std::string& trace_id,
                              const char* label, double t_s,
                              const std::array<double, 6>& values) {
  char buffer[32];
  out->append(trace_id).append(",").append(label);
  std::snprintf(buffer, sizeof buffer, ",%.17g", t_s);
  out->append(buffer);
  for (double v : values) {
    std::snprintf(buffer, sizeof buffer, ",%.17g", v);
    out->append(buffer);
  }
  out->push_back('\n');
}

}  // namespace bitewise::domain

#endif  // BITEWISE_SERVICES_DOMAIN_TRACE_CSV_H_
