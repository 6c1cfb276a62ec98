// Traces for the haptic tests: one simulated item of a category.
#ifndef BITEWISE_TESTS_HAPTIC_HAPTIC_TEST_TRACES_H_
#define BITEWISE_TESTS_HAPTIC_HAPTIC_TEST_TRACES_H_

#include <random>
#include <vector>

#include "services/haptic/core/wrench_trace.h"
#include "services/haptic/training/labelled_traces.h"
#include "services/sim/force_trace.h"

namespace bitewise::haptic {

inline std::vector<TimedWrench> SimulatedTrace(HapticClass haptic_class,
                                               std::mt19937_64& rng,
                                               double rate_hz = 1000.0,
                                               double contact_s = 0.3) {
  const auto profile = sim::ForceProfile::Sample(
      static_cast<sim::HapticCategory>(haptic_class), rng);
  sim::TraceOptions options;
  options.rate_hz = rate_hz;
  options.contact_s = contact_s;
  options.duration_s = contact_s + 0.3;
  return sim::SimulateTrace(profile, options, rng);
}

}  // namespace bitewise::haptic

#endif  // BITEWISE_TESTS_HAPTIC_HAPTIC_TEST_TRACES_H_
