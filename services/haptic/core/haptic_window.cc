#include "services/haptic/core/haptic_window.h"

#include <algorithm>
#include <cmath>

#include "absl/strings/str_cat.h"

namespace bitewise::haptic {

absl::Status ValidateWindowOptions(const WindowOptions& options) {
  if (!(options.window_s > 0.0) || !std::isfinite(options.window_s)) {
    return absl::InvalidArgumentError(
        absl::StrCat("window_s must be > 0, got ", options.window_s));
  }
  if (options.min_window_samples < 2) {
    return absl::InvalidArgumentError(absl::StrCat(
        "min_window_samples must be >= 2, got ", options.min_window_samples));
  }
  return absl::OkStatus();
}

std::vector<std::array<double, kWrenchChannels>> ResampleLinear(
    absl::Span<const TimedWrench> trace, absl::Span<const double> times_s) {
  std::vector<std::array<double, kWrenchChannels>> out(times_s.size());
  size_t right = 0;  // first sample with t_s >= the query time
  for (size_t k = 0; k < times_s.size(); ++k) {
    const double t = times_s[k];
    while (right < trace.size() && trace[right].t_s < t) ++right;
    if (right == 0) {
      out[k] = Channels(trace.front().wrench);
    } else if (right == trace.size()) {
      out[k] = Channels(trace.back().wrench);
    } else {
      const TimedWrench& a = trace[right - 1];
      const TimedWrench& b = trace[right];
      const double w = (t - a.t_s) / (b.t_s - a.t_s);
      for (int c = 0; c < kWrenchChannels; ++c) {
        out[k][c] = Channel(a.wrench, c) +
                    w * (Channel(b.wrench, c) - Channel(a.wrench, c));
      }
    }
  }
  return out;
}

absl::StatusOr<HapticWindow> ExtractWindow(
    absl::Span<const TimedWrench> trace, double contact_time_s,
    const std::array<double, kWrenchChannels>& offset,
    const WindowOptions& options) {
  const auto first_after = std::upper_bound(
      trace.begin(), trace.end(), contact_time_s,
      [](double t, const TimedWrench& s) { return t < s.t_s; });
  const int after = static_cast<int>(trace.end() - first_after);
  if (after < options.min_window_samples) {
    return absl::InvalidArgumentError(absl::StrCat(
        "samples: only ", after, " samples after the contact at t = ",
        contact_time_s, " s, need at least ", options.min_window_samples,
        " (the trace ends too soon after contact)"));
  }
  HapticWindow window;
  window.start_s = contact_time_s;
  window.end_s = std::max(contact_time_s + options.window_s,
                          first_after[options.min_window_samples - 1].t_s);
  std::array<double, kWindowPoints> times;
  for (int k = 0; k < kWindowPoints; ++k) {
    times[k] = window.start_s +
               (window.end_s - window.start_s) * k / (kWindowPoints - 1);
  }
  const auto values = ResampleLinear(trace, times);
  for (int k = 0; k < kWindowPoints; ++k) {
    for (int c = 0; c < kWrenchChannels; ++c) {
      window.inputs[c * kWindowPoints + k] =
          static_cast<float>(values[k][c] - offset[c]);
    }
  }
  return window;
}

}  // namespace bitewise::haptic
