// libFuzzer target: the HapticService's trace checks and feature pipeline
// (contact detection, window, resampling) on arbitrary samples, 7 doubles
// each (t, fx, fy, fz, tx, ty, tz). A trace that passes must give finite
// network inputs.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <vector>

#include "services/haptic/core/haptic_classifier.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace bitewise::haptic;  // NOLINT: one namespace
  constexpr size_t kSampleBytes = 7 * sizeof(double);
  std::vector<TimedWrench> trace(size / kSampleBytes);
  for (size_t i = 0; i < trace.size(); ++i) {
    double v[7];
    std::memcpy(v, data + i * kSampleBytes, kSampleBytes);
    trace[i].t_s = v[0];
    for (int c = 0; c < kWrenchChannels; ++c) {
      Channel(trace[i].wrench, c) = v[1 + c];
    }
  }
  absl::StatusOr<HapticFeatures> features =
      ExtractHapticFeatures(trace, HapticPipelineOptions());
  if (features.ok()) {
    for (float x : features->window.inputs) {
      if (!std::isfinite(x)) std::abort();
    }
  }
  return 0;
}
