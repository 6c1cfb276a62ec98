#include "services/robot/ft_recorder.h"

#include <algorithm>
#include <cmath>
#include <utility>

namespace bitewise::robot {
namespace {

double ForceMagnitude(const netft::Wrench& w, const netft::Wrench& baseline) {
  const double dx = w.force_n[0] - baseline.force_n[0];
  const double dy = w.force_n[1] - baseline.force_n[1];
  const double dz = w.force_n[2] - baseline.force_n[2];
  return std::sqrt(dx * dx + dy * dy + dz * dz);
}

}  // namespace

FtRecorder::FtRecorder(double contact_threshold_n)
    : contact_threshold_n_(contact_threshold_n) {}

void FtRecorder::Start(const std::vector<netft::FtSample>& recent,
                       double start_s, double baseline_s) {
  start_s_ = start_s;
  baseline_ = netft::Wrench();
  if (recent.empty()) return;
  int n = 0;
  netft::Wrench sum;
  for (const netft::FtSample& s : recent) {
    if (s.arrival_s < start_s - baseline_s) continue;
    for (int i = 0; i < 3; ++i) {
      sum.force_n[i] += s.wrench.force_n[i];
      sum.torque_nm[i] += s.wrench.torque_nm[i];
    }
    ++n;
  }
  if (n == 0) {
    baseline_ = recent.back().wrench;
    return;
  }
  for (int i = 0; i < 3; ++i) {
    baseline_.force_n[i] = sum.force_n[i] / n;
    baseline_.torque_nm[i] = sum.torque_nm[i] / n;
  }
}

void FtRecorder::Add(const std::vector<netft::FtSample>& fresh) {
  for (const netft::FtSample& s : fresh) {
    const double force = ForceMagnitude(s.wrench, baseline_);
    last_force_n_ = force;
    max_force_since_call_ = std::max(max_force_since_call_, force);
    peak_force_n_ = std::max(peak_force_n_, force);
    if (!have_offset_) {
      trace_offset_s_ = s.host_time_s - s.sensor_time_s - start_s_;
      have_offset_ = true;
    }
    const double t_s = s.sensor_time_s + trace_offset_s_;
    if (contact_time_s_ < 0.0 && force > contact_threshold_n_) {
      contact_time_s_ = t_s;
    }
    if (!trace_.empty() && t_s <= trace_.back().t_s) continue;
    trace_.push_back({t_s, s.wrench});
  }
}

double FtRecorder::TakeMaxForceSinceLastCall() {
  const double max = max_force_since_call_;
  max_force_since_call_ = 0.0;
  return max;
}

double FtRecorder::StaticLoad(double from_s) const {
  double sum = 0.0;
  int n = 0;
  for (const domain::TimedWrench& s : trace_) {
    if (s.t_s < from_s) continue;
    sum += s.wrench.force_n[2];
    ++n;
  }
  if (n == 0) return 0.0;
  return baseline_.force_n[2] - sum / n;
}

}  // namespace bitewise::robot
