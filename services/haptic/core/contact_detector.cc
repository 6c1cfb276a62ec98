#include "services/haptic/core/contact_detector.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"

namespace bitewise::haptic {
namespace {

// Half-width of the smoothing used to find where the rising edge starts.
constexpr double kSmoothingS = 0.002;

}  // namespace

double TaredForceMagnitude(const TimedWrench& sample,
                           const std::array<double, kWrenchChannels>& offset) {
  double sum = 0.0;
  for (int c = 0; c < 3; ++c) {
    const double f = Channel(sample.wrench, c) - offset[c];
    sum += f * f;
  }
  return std::sqrt(sum);
}

std::array<double, kWrenchChannels> SensorOffset(
    absl::Span<const TimedWrench> trace, double tare_s) {
  size_t n = 1;
  while (n < trace.size() && trace[n].t_s - trace[0].t_s < tare_s) ++n;
  std::array<double, kWrenchChannels> offset{};
  std::vector<double> values(n);
  for (int c = 0; c < kWrenchChannels; ++c) {
    for (size_t i = 0; i < n; ++i) values[i] = Channel(trace[i].wrench, c);
    std::sort(values.begin(), values.end());
    offset[c] =
        n % 2 == 1 ? values[n / 2] : 0.5 * (values[n / 2 - 1] + values[n / 2]);
  }
  return offset;
}

absl::Status ValidateContactOptions(const ContactDetectorOptions& options) {
  if (!(options.tare_s >= 0.0) || !std::isfinite(options.tare_s)) {
    return absl::InvalidArgumentError(
        absl::StrCat("tare_s must be >= 0, got ", options.tare_s));
  }
  if (!(options.threshold_n > 0.0) || !std::isfinite(options.threshold_n)) {
    return absl::InvalidArgumentError(
        absl::StrCat("threshold_n must be > 0, got ", options.threshold_n));
  }
  if (!(options.release_n > 0.0) ||
      !(options.release_n <= options.threshold_n)) {
    return absl::InvalidArgumentError(absl::StrCat(
        "release_n must be in (0, threshold_n = ", options.threshold_n,
        "], got ", options.release_n));
  }
  if (!(options.min_contact_s >= 0.0) ||
      !std::isfinite(options.min_contact_s)) {
    return absl::InvalidArgumentError(absl::StrCat(
        "min_contact_s must be >= 0, got ", options.min_contact_s));
  }
  return absl::OkStatus();
}

absl::StatusOr<ContactResult> ContactDetector::Detect(
    absl::Span<const TimedWrench> trace) const {
  if (trace.empty()) {
    return absl::InvalidArgumentError("samples: the trace is empty");
  }
  ContactResult result;
  result.offset = SensorOffset(trace, options_.tare_s);
  const int n = static_cast<int>(trace.size());
  std::vector<double> magnitude(n);
  int peak_index = 0;
  for (int i = 0; i < n; ++i) {
    magnitude[i] = TaredForceMagnitude(trace[i], result.offset);
    if (magnitude[i] > magnitude[peak_index]) peak_index = i;
  }
  result.peak_force_n = magnitude[peak_index];

  // Hysteresis: enter at threshold_n, stay while >= release_n; a run that
  // ends before min_contact_s (or after a single sample) is rejected.
  int trigger = -1;
  for (int i = 0; i < n && trigger < 0; ++i) {
    if (magnitude[i] < options_.threshold_n) continue;
    int last = i;
    while (last + 1 < n && magnitude[last + 1] >= options_.release_n) ++last;
    const bool long_enough =
        last > i && trace[last].t_s - trace[i].t_s >= options_.min_contact_s;
    // A run cut off by the end of the trace is still contact if it lasts.
    if (long_enough) {
      trigger = i;
    } else {
      i = last;
    }
  }
  if (trigger < 0) {
    return absl::FailedPreconditionError(absl::StrFormat(
        "no contact found: peak force %.3f N (at t = %.4f s, after removing "
        "the sensor offset) never held above the %.3f N contact threshold",
        result.peak_force_n, trace[peak_index].t_s, options_.threshold_n));
  }
  result.trigger_index = trigger;

  // The rising edge: back from the trigger while the force, smoothed over
  // +-2 ms so that one noisy dip does not end the edge early, stays above
  // release_n; then forward to the first raw sample above it.
  std::vector<double> prefix(n + 1, 0.0);
  for (int i = 0; i < n; ++i) prefix[i + 1] = prefix[i] + magnitude[i];
  // The window's ends by binary search over the (strictly increasing)
  // timestamps, with the same comparisons as a walk: a trace that packs
  // many samples into a few milliseconds costs a logarithm, not a walk
  // over them at every step of the edge.
  auto smoothed = [&](int i) {
    int lo = 0, lo_end = i;  // first j in [0, i] within kSmoothingS of i
    while (lo < lo_end) {
      const int mid = lo + (lo_end - lo) / 2;
      if (trace[i].t_s - trace[mid].t_s <= kSmoothingS) {
        lo_end = mid;
      } else {
        lo = mid + 1;
      }
    }
    int hi = i, hi_end = n - 1;  // last j in [i, n) within kSmoothingS of i
    while (hi < hi_end) {
      const int mid = hi + (hi_end - hi + 1) / 2;
      if (trace[mid].t_s - trace[i].t_s <= kSmoothingS) {
        hi = mid;
      } else {
        hi_end = mid - 1;
      }
    }
    return (prefix[hi + 1] - prefix[lo]) / (hi - lo + 1);
  };
  int first = trigger;
  while (first > 0 && smoothed(first - 1) >= options_.release_n) --first;
  while (magnitude[first] < options_.release_n) ++first;
  // Least-squares line through the edge's early part (up to 4 x the
  // threshold, where even a hard food's rise is still straight),
  // extrapolated to zero force: the threshold crossing alone would lag by
  // threshold / slope, tens of milliseconds on soft foods.
  int last = trigger;
  while (last < first + 2 && last + 1 < n &&
         magnitude[last + 1] <= 4.0 * options_.threshold_n) {
    ++last;
  }
  const double t_ref = trace[first].t_s;
  double contact = t_ref;
  if (last > first) {
    double st = 0.0, sm = 0.0, stt = 0.0, stm = 0.0;
    const int count = last - first + 1;
    for (int i = first; i <= last; ++i) {
      const double t = trace[i].t_s - t_ref;
      st += t;
      sm += magnitude[i];
      stt += t * t;
      stm += t * magnitude[i];
    }
    const double slope = (count * stm - st * sm) / (count * stt - st * st);
    const double intercept = (sm - slope * st) / count;
    if (slope > 0.0) {
      contact = t_ref - intercept / slope;
      // A flat, noisy fit must not reach far back.
      contact = std::max(contact, t_ref - 2.0 * (trace[last].t_s - t_ref));
    }
  } else if (first > 0) {
    // The edge outran the sample rate (a hard food at 100 Hz): the best
    // estimate is the line from the last sample before it.
    const double t_before = trace[first - 1].t_s;
    const double m_before = magnitude[first - 1];
    contact = t_ref - magnitude[first] * (t_ref - t_before) /
                          (magnitude[first] - m_before);
  }
  // Never after the edge's first sample, never before the trace.
  contact = std::clamp(contact, trace[0].t_s, t_ref);
  if (options_.require_free_tare && contact - trace[0].t_s < options_.tare_s) {
    return absl::InvalidArgumentError(absl::StrFormat(
        "samples: contact at t = %.4f s, %.1f ms after the first sample; the "
        "trace must begin with %.0f ms of free motion, from which the sensor "
        "offset is taken",
        contact, 1e3 * (contact - trace[0].t_s), 1e3 * options_.tare_s));
  }
  result.contact_time_s = contact;
  return result;
}

}  // namespace bitewise::haptic
