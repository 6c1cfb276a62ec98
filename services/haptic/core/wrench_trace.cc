#include "services/haptic/core/wrench_trace.h"

#include <cmath>

#include "absl/strings/str_cat.h"

namespace bitewise::haptic {
namespace {

constexpr const char* kChannelNames[kWrenchChannels] = {
    "fx_n", "fy_n", "fz_n", "tx_nm", "ty_nm", "tz_nm"};

}  // namespace

absl::Status ValidateTrace(absl::Span<const TimedWrench> trace,
                           int min_samples) {
  if (static_cast<int>(trace.size()) < min_samples) {
    return absl::InvalidArgumentError(absl::StrCat(
        "samples: ", trace.size(), " samples, need at least ", min_samples));
  }
  for (size_t i = 0; i < trace.size(); ++i) {
    const TimedWrench& sample = trace[i];
    if (!std::isfinite(sample.t_s)) {
      return absl::InvalidArgumentError(absl::StrCat(
          "samples[", i, "].t_s is not finite (", sample.t_s, ")"));
    }
    for (int c = 0; c < kWrenchChannels; ++c) {
      const double value = Channel(sample.wrench, c);
      if (!std::isfinite(value)) {
        return absl::InvalidArgumentError(
            absl::StrCat("samples[", i, "].", kChannelNames[c],
                         " is not finite (", value, ")"));
      }
      const double limit = c < 3 ? kMaxForceN : kMaxTorqueNm;
      if (std::abs(value) > limit) {
        return absl::InvalidArgumentError(absl::StrCat(
            "samples[", i, "].", kChannelNames[c], " = ", value,
            " is beyond any F/T sensor's range (limit ", limit, ")"));
      }
    }
    if (i > 0 && !(sample.t_s > trace[i - 1].t_s)) {
      return absl::InvalidArgumentError(absl::StrCat(
          "samples[", i, "].t_s = ", sample.t_s,
          " s does not increase (samples[", i - 1, "].t_s = ", trace[i - 1].t_s,
          " s); timestamps must be strictly increasing"));
    }
  }
  if (trace.size() >= 2) {
    const double rate_hz =
        (trace.size() - 1) / (trace.back().t_s - trace.front().t_s);
    if (rate_hz < kMinRateHz || rate_hz > kMaxRateHz) {
      return absl::InvalidArgumentError(
          absl::StrCat("samples: ", trace.size(), " samples at ", rate_hz,
                       " Hz on average; HapticNet was trained on ", kMinRateHz,
                       "-", kMaxRateHz, " Hz"));
    }
  }
  return absl::OkStatus();
}

}  // namespace bitewise::haptic
