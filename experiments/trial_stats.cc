#include "experiments/trial_stats.h"

#include <cmath>
#include <cstddef>

namespace bitewise::experiments {

CurveSummary SummarizeCurves(const std::vector<std::vector<double>>& curves) {
  CurveSummary out;
  if (curves.empty()) return out;
  const size_t length = curves.front().size();
  const double n = static_cast<double>(curves.size());
  out.mean.assign(length, 0.0);
  out.standard_error.assign(length, 0.0);
  for (const auto& curve : curves) {
    for (size_t i = 0; i < length; ++i) out.mean[i] += curve[i] / n;
  }
  if (curves.size() < 2) return out;
  for (size_t i = 0; i < length; ++i) {
    double ss = 0.0;
    for (const auto& curve : curves) {
      const double dev = curve[i] - out.mean[i];
      ss += dev * dev;
    }
    out.standard_error[i] = std::sqrt(ss / (n - 1.0)) / std::sqrt(n);
  }
  return out;
}

std::vector<double> Difference(const std::vector<double>& a,
                               const std::vector<double>& b) {
  std::vector<double> out(a.size());
  for (size_t i = 0; i < a.size(); ++i) out[i] = a[i] - b[i];
  return out;
}

}  // namespace bitewise::experiments
