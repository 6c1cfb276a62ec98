// ContactDetector on traces with known contact times: hand-built ramps with
// a sensor offset, single-sample spikes that must not count, and traces of
// every category from the simulated world's force-trace model.
#include "services/haptic/core/contact_detector.h"

#include <cmath>
#include <random>
#include <vector>

#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "services/haptic/training/labelled_traces.h"
#include "services/sim/force_trace.h"
#include "tests/haptic/haptic_test_traces.h"

namespace bitewise::haptic {
namespace {

using ::testing::HasSubstr;

// fz rises at `slope_n_per_s` from `contact_s`; every channel carries
// `offset`. Sampled at `rate_hz` for `duration_s`.
std::vector<TimedWrench> Ramp(double contact_s, double slope_n_per_s,
                              double rate_hz, double duration_s,
                              const std::array<double, 6>& offset) {
  std::vector<TimedWrench> trace;
  const int n = static_cast<int>(std::round(duration_s * rate_hz));
  for (int i = 0; i < n; ++i) {
    TimedWrench s;
    s.t_s = i / rate_hz;
    s.wrench = WrenchFromChannels(offset);
    Channel(s.wrench, 2) += slope_n_per_s * std::max(0.0, s.t_s - contact_s);
    trace.push_back(s);
  }
  return trace;
}

TEST(ContactDetectorTest, FindsRampStartAndOffsetExactly) {
  const std::array<double, 6> offset = {0.3, -0.7, -1.2, 0.01, 0.02, -0.03};
  // Steep (hard food) and slow (soft food) rises; the slow one crosses the
  // 1 N threshold 50 ms after contact, which the edge extrapolation undoes.
  for (double slope : {2000.0, 20.0}) {
    const auto trace = Ramp(0.2004, slope, 1000.0, 0.5, offset);
    absl::StatusOr<ContactResult> contact =
        ContactDetector(ContactDetectorOptions()).Detect(trace);
    ASSERT_TRUE(contact.ok()) << contact.status();
    EXPECT_NEAR(contact->contact_time_s, 0.2004, 1e-9) << "slope " << slope;
    for (int c = 0; c < 6; ++c) EXPECT_DOUBLE_EQ(contact->offset[c], offset[c]);
    EXPECT_NEAR(contact->peak_force_n, slope * (0.499 - 0.2004), 1e-9);
  }
}

// A trace that packs 150,000 samples into 0.15 ms (a valid average rate
// over its 20 s) under a force the rising edge walks back through. The
// edge's smoothing window is found by binary search; walking over the
// window at every step of the edge, this trace took 15 s, 19 ms now (once,
// 2026-12-07; speed is not asserted here). The edge reaches back through
// the packed samples: its line, extrapolated to zero force, starts before
// them.
TEST(ContactDetectorTest, AFewMillisecondsPackedWithSamplesCostsLittle) {
  const std::vector<TimedWrench> trace = PackedTrace();
  absl::StatusOr<ContactResult> contact =
      ContactDetector(ContactDetectorOptions()).Detect(trace);
  ASSERT_TRUE(contact.ok()) << contact.status();
  EXPECT_LT(contact->contact_time_s, 0.0505);
  EXPECT_GT(contact->contact_time_s, 0.045);
}

// The tare window must be free motion: a force rising from 20 ms on puts
// contact inside it, which the service refuses (the offset would be the
// median of a rising force) and training, which leaves the option off, does
// not see.
TEST(ContactDetectorTest, ContactInsideTheTareWindowIsRefusedWhenAsked) {
  const auto trace = Ramp(0.02, 1000.0, 1000.0, 0.3, {});
  ContactDetectorOptions options;
  ASSERT_TRUE(ContactDetector(options).Detect(trace).ok());
  options.require_free_tare = true;
  absl::StatusOr<ContactResult> refused =
      ContactDetector(options).Detect(trace);
  EXPECT_EQ(refused.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(refused.status().message(),
              HasSubstr("the trace must begin with 50 ms of free motion"));
  // Contact after the tare window passes.
  EXPECT_TRUE(
      ContactDetector(options).Detect(Ramp(0.2, 1000.0, 1000.0, 0.5, {})).ok());
}

TEST(ContactDetectorTest, SingleSampleSpikeIsNotContact) {
  auto trace = Ramp(0.3, 500.0, 1000.0, 0.5, {});
  // A 5 N spike in free motion, one sample long.
  Channel(trace[150].wrench, 2) = 5.0;
  absl::StatusOr<ContactResult> contact =
      ContactDetector(ContactDetectorOptions()).Detect(trace);
  ASSERT_TRUE(contact.ok()) << contact.status();
  EXPECT_NEAR(contact->contact_time_s, 0.3, 1e-9);
}

TEST(ContactDetectorTest, ExcursionShorterThanMinContactIsNotContact) {
  auto trace = Ramp(0.3, 500.0, 1000.0, 0.5, {});
  // Two samples at 2 N: above the threshold, but only 1 ms long.
  Channel(trace[120].wrench, 2) = 2.0;
  Channel(trace[121].wrench, 2) = 2.0;
  ContactDetectorOptions options;
  absl::StatusOr<ContactResult> contact =
      ContactDetector(options).Detect(trace);
  ASSERT_TRUE(contact.ok()) << contact.status();
  EXPECT_NEAR(contact->contact_time_s, 0.3, 1e-9);
  // With no minimum duration the same excursion is contact: the option is
  // what rejects it.
  options.min_contact_s = 0.0;
  contact = ContactDetector(options).Detect(trace);
  ASSERT_TRUE(contact.ok()) << contact.status();
  EXPECT_LT(contact->contact_time_s, 0.121);
}

TEST(ContactDetectorTest, SpikeDuringTareDoesNotShiftOffset) {
  auto trace = Ramp(0.3, 500.0, 1000.0, 0.5, {0.0, 0.0, 2.0, 0, 0, 0});
  Channel(trace[10].wrench, 2) = 40.0;
  absl::StatusOr<ContactResult> contact =
      ContactDetector(ContactDetectorOptions()).Detect(trace);
  ASSERT_TRUE(contact.ok()) << contact.status();
  EXPECT_DOUBLE_EQ(contact->offset[2], 2.0);
}

// The tare window is [t0, t0 + tare_s): a sample exactly tare_s after the
// first is outside it. An even count takes the mean of the two middle values.
TEST(ContactDetectorTest, SensorOffsetIsTheMedianOfTheTareWindow) {
  std::vector<TimedWrench> trace(6);
  const double fx[] = {4.0, 1.0, 3.0, 2.0, 100.0, 100.0};
  for (int i = 0; i < 6; ++i) {
    trace[i].t_s = 0.25 + i / 64.0;  // exact in binary
    Channel(trace[i].wrench, 0) = fx[i];
    Channel(trace[i].wrench, 2) = -fx[i];
  }
  // 1/16 s holds samples 0-3; sample 4 is exactly 1/16 s after the first.
  const auto offset = SensorOffset(trace, 1.0 / 16.0);
  EXPECT_DOUBLE_EQ(offset[0], 2.5);
  EXPECT_DOUBLE_EQ(offset[2], -2.5);
  EXPECT_DOUBLE_EQ(offset[1], 0.0);
  // Three samples: the middle one. A zero window keeps the first sample.
  EXPECT_DOUBLE_EQ(SensorOffset(trace, 0.04)[0], 3.0);
  EXPECT_DOUBLE_EQ(SensorOffset(trace, 0.0)[0], 4.0);
  // The tared norm of sample 4: (97.5, 0, -97.5).
  EXPECT_NEAR(TaredForceMagnitude(trace[4], offset), 97.5 * std::sqrt(2.0),
              1e-12);
}

TEST(ContactDetectorTest, ThresholdIsConfigurable) {
  // 0.8 N of force: contact at a 0.5 N threshold, none at the default 1 N.
  auto trace = Ramp(0.2, 0.0, 1000.0, 0.4, {});
  for (int i = 200; i < 400; ++i) Channel(trace[i].wrench, 2) = 0.8;
  EXPECT_EQ(
      ContactDetector(ContactDetectorOptions()).Detect(trace).status().code(),
      absl::StatusCode::kFailedPrecondition);
  ContactDetectorOptions low;
  low.threshold_n = 0.5;
  low.release_n = 0.3;
  absl::StatusOr<ContactResult> contact = ContactDetector(low).Detect(trace);
  ASSERT_TRUE(contact.ok()) << contact.status();
  EXPECT_NEAR(contact->contact_time_s, 0.2, 1e-3);
}

TEST(ContactDetectorTest, NoContactReportsPeakForce) {
  auto trace = Ramp(0.2, 0.0, 1000.0, 0.4, {0.0, 0.0, 3.0, 0, 0, 0});
  Channel(trace[300].wrench, 2) = 3.42;  // 0.42 N above the offset, one sample
  absl::StatusOr<ContactResult> contact =
      ContactDetector(ContactDetectorOptions()).Detect(trace);
  ASSERT_EQ(contact.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(contact.status().message(), HasSubstr("peak force 0.420 N"));
  EXPECT_THAT(contact.status().message(), HasSubstr("1.000 N"));
}

TEST(ContactDetectorTest, RejectsInconsistentOptions) {
  ContactDetectorOptions options;
  options.release_n = 2.0;  // above the threshold
  EXPECT_EQ(ValidateContactOptions(options).code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(ValidateContactOptions(options).message(),
              HasSubstr("release_n"));
  options = ContactDetectorOptions();
  options.threshold_n = std::nan("");
  EXPECT_THAT(ValidateContactOptions(options).message(),
              HasSubstr("threshold_n"));
}

// Every category of the force-trace model, with noise and an untared
// offset, at the rates the Forque runs at: the estimate stays within 4 ms
// of the true contact (12 ms for slowly rising soft foods) at 1 kHz and
// above, and within 3.5 sample periods at 100 Hz.
TEST(ContactDetectorTest, SimulatedTracesOfEveryCategory) {
  std::mt19937_64 rng(7);
  for (double rate_hz : {100.0, 1000.0, 7000.0}) {
    for (int k = 0; k < 4; ++k) {
      const auto category = static_cast<sim::HapticCategory>(k);
      double worst_s = 0.0;
      for (int item = 0; item < 25; ++item) {
        const auto profile = sim::ForceProfile::Sample(category, rng);
        sim::TraceOptions options;
        options.rate_hz = rate_hz;
        options.contact_s = 0.2 + 0.0013 * item;  // off the sample grid
        options.duration_s = 0.5;
        options.noise.random_bias_n = 2.0;
        const std::vector<TimedWrench> trace =
            sim::SimulateTrace(profile, options, rng);
        absl::StatusOr<ContactResult> contact =
            ContactDetector(ContactDetectorOptions()).Detect(trace);
        ASSERT_TRUE(contact.ok()) << contact.status();
        worst_s = std::max(
            worst_s, std::abs(contact->contact_time_s - options.contact_s));
      }
      // Soft foods rise at 15-35 N/s, so their edge is buried in the noise
      // for its first ~10 ms; at 100 Hz the edge spans only a few samples.
      const double tolerance_s = rate_hz < 200.0 ? 3.5 / rate_hz
                                 : category == sim::HapticCategory::kSoft
                                     ? 0.012
                                     : 0.004;
      EXPECT_LT(worst_s, tolerance_s)
          << domain::HapticClassLabel(category) << " at " << rate_hz << " Hz";
    }
  }
}

}  // namespace
}  // namespace bitewise::haptic
