// Traces for the haptic tests and benchmarks: one simulated item of a
// category, and a trace that packs many samples into a few milliseconds.
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

// 50 ms of free motion at 1 kHz, then 150,000 samples 1 ns apart at
// fz = 0.8 N (above the release force, below the contact threshold), then
// 5 N at 1 kHz for 100 ms and one last sample at 20 s: a valid average
// rate, about 3 MB as a request, and a rising edge that reaches back
// through the packed samples.
inline std::vector<TimedWrench> PackedTrace() {
  std::vector<TimedWrench> trace;
  auto add = [&](double t_s, double fz_n) {
    TimedWrench s;
    s.t_s = t_s;
    Channel(s.wrench, 2) = fz_n;
    trace.push_back(s);
  };
  for (int i = 0; i < 50; ++i) add(i * 1e-3, 0.0);
  for (int i = 0; i < 150000; ++i) add(0.0505 + i * 1e-9, 0.8);
  for (int i = 0; i < 100; ++i) add(0.0515 + i * 1e-3, 5.0);
  add(20.0, 5.0);
  return trace;
}

}  // namespace bitewise::haptic

#endif  // BITEWISE_TESTS_HAPTIC_HAPTIC_TEST_TRACES_H_
