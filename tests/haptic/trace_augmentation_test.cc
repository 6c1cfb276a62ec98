// The trainer's sensor augmentation (TraceAugmentation) and the
// per-category over-confidence of ScorePredictions.
#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "gtest/gtest.h"
#include "services/haptic/training/haptic_trainer.h"
#include "services/haptic/training/labelled_traces.h"

namespace bitewise::haptic {
namespace {

TraceAugmentation Nothing() {
  TraceAugmentation a;
  a.max_time_scale = 1.0;
  a.max_amplitude_scale = 1.0;
  a.max_tilt_deg = 0.0;
  a.max_offset_m = 0.0;
  a.max_lag_s = 0.0;
  a.resample_probability = 0.0;
  a.max_drift_n_per_s = 0.0;
  a.max_coloured_noise_n = 0.0;
  return a;
}

std::vector<TimedWrench> Trace() {
  return StoryTraces(TraceStory::kMechanics, 1, 3)[0].samples;
}

// The norm of the force (`first` 0) or the torque (`first` 3).
double Norm(const TimedWrench& s, int first) {
  const auto& v = first == 0 ? s.wrench.force_n : s.wrench.torque_nm;
  return std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
}

TEST(TraceAugmentationTest, WithNothingOnItIsTheIdentity) {
  const std::vector<TimedWrench> trace = Trace();
  std::mt19937_64 rng(1);
  const std::vector<TimedWrench> out = AugmentTrace(trace, Nothing(), rng);
  ASSERT_EQ(out.size(), trace.size());
  for (size_t i = 0; i < trace.size(); ++i) {
    EXPECT_DOUBLE_EQ(out[i].t_s, trace[i].t_s);
    for (int k = 0; k < kWrenchChannels; ++k) {
      EXPECT_NEAR(Channel(out[i].wrench, k), Channel(trace[i].wrench, k),
                  1e-12);
    }
  }
}

TEST(TraceAugmentationTest,
     AForkAngleMixesFzIntoTheOtherChannelsAndKeepsTheNorm) {
  TraceAugmentation tilt = Nothing();
  tilt.max_tilt_deg = 30.0;
  const std::vector<TimedWrench> trace = Trace();
  std::mt19937_64 rng(5);
  const std::vector<TimedWrench> out = AugmentTrace(trace, tilt, rng);
  ASSERT_EQ(out.size(), trace.size());
  double changed = 0.0;
  for (size_t i = 0; i < trace.size(); ++i) {
    EXPECT_NEAR(Norm(out[i], 0), Norm(trace[i], 0), 1e-9);
    EXPECT_NEAR(Norm(out[i], 3), Norm(trace[i], 3), 1e-9);
    changed = std::max(changed, std::abs(Channel(out[i].wrench, 0) -
                                         Channel(trace[i].wrench, 0)));
  }
  EXPECT_GT(changed, 0.1);  // Fz leaked into Fx
}

TEST(TraceAugmentationTest, TheFullAugmentationKeepsATraceTheServiceAccepts) {
  const TraceAugmentation all;
  std::mt19937_64 rng(11);
  const std::vector<LabelledTrace> traces =
      StoryTraces(TraceStory::kPiecewise, 25, 4);
  int accepted = 0;
  for (const LabelledTrace& trace : traces) {
    const std::vector<TimedWrench> out = AugmentTrace(trace.samples, all, rng);
    ASSERT_GE(out.size(), 8u);
    for (size_t i = 1; i < out.size(); ++i) {
      ASSERT_GT(out[i].t_s, out[i - 1].t_s);
      for (double v : Channels(out[i].wrench)) ASSERT_TRUE(std::isfinite(v));
    }
    accepted += ExtractHapticFeatures(out, HapticPipelineOptions()).ok();
  }
  // Of 100, 90 here: a 100 Hz piecewise trace stretched below the service's
  // 90 Hz floor, or a weak soft item shrunk below the contact threshold, is
  // rejected as the service would, and the trainer skips and counts it.
  EXPECT_GE(accepted, 85);
}

TEST(TraceAugmentationTest, ASlowApproachStretchesTheClockAndNothingElse) {
  const std::vector<TimedWrench> trace = Trace();
  std::mt19937_64 rng(3);
  double smallest = 1e9, largest = 0.0;
  for (int draw = 0; draw < 200; ++draw) {
    const std::vector<TimedWrench> out = SlowApproach(trace, 3.0, rng);
    ASSERT_EQ(out.size(), trace.size());
    const double factor = out.back().t_s / trace.back().t_s;
    ASSERT_GE(factor, 1.0);
    ASSERT_LE(factor, 3.0);
    smallest = std::min(smallest, factor);
    largest = std::max(largest, factor);
    for (size_t i = 0; i < trace.size(); ++i) {
      ASSERT_NEAR(out[i].t_s, trace[i].t_s * factor, 1e-12);
      for (int k = 0; k < kWrenchChannels; ++k) {
        ASSERT_EQ(Channel(out[i].wrench, k), Channel(trace[i].wrench, k));
      }
    }
  }
  EXPECT_LT(smallest, 1.05);  // log-uniform over [1, 3]
  EXPECT_GT(largest, 2.85);
  // At 1, nothing moves.
  const std::vector<TimedWrench> same = SlowApproach(trace, 1.0, rng);
  for (size_t i = 0; i < trace.size(); ++i) {
    EXPECT_EQ(same[i].t_s, trace[i].t_s);
  }
}

TEST(ScorePredictionsTest,
     OverconfidenceIsTopProbabilityMinusAccuracyPerClass) {
  // Class 0: two traces, sure (0.9) and right once: 0.9 - 0.5 = +0.4.
  // Class 1: one trace, 0.6 and right: 0.6 - 1 = -0.4.
  const std::vector<std::array<double, kHapticClasses>> p = {
      {0.9, 0.05, 0.03, 0.02}, {0.05, 0.9, 0.03, 0.02}, {0.2, 0.6, 0.1, 0.1}};
  const ProbabilisticScore score = ScorePredictions(p, {0, 0, 1});
  EXPECT_NEAR(score.overconfidence[0], 0.4, 1e-12);
  EXPECT_NEAR(score.overconfidence[1], -0.4, 1e-12);
  EXPECT_EQ(score.overconfidence[2], 0.0);  // no traces
  EXPECT_NEAR(score.MaxOverconfidence(), 0.4, 1e-12);
}

}  // namespace
}  // namespace bitewise::haptic
