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

// A 1 kHz trace of free motion until 0.2 s, then Fz(t) of a rigid arm.
template <typename Force>
std::vector<TimedWrench> RigidTrace(Force fz) {
  std::vector<TimedWrench> trace;
  for (int i = 0; i <= 400; ++i) {
    TimedWrench s;
    s.t_s = 1e-3 * i;
    s.wrench.force_n[2] = s.t_s < 0.2 ? 0.0 : fz(s.t_s - 0.2);
    trace.push_back(s);
  }
  return trace;
}

// A wrist of 4 N/mm at 5 cm/s carries at most 200 N/s.
ArmCompliance Wrist4NPerMm() {
  ArmCompliance arm;
  arm.probability = 1.0;
  arm.min_stiffness_n_per_m = arm.max_stiffness_n_per_m = 4000.0;
  return arm;
}

TEST(CompliantArmTest, ARampRisesAtTheSeriesStiffnessOfFoodAndWrist) {
  // A hard item's 800 N/s through a 200 N/s wrist: 1 / (1/800 + 1/200) =
  // 160 N/s, on the same clock; the free motion before it is untouched.
  const std::vector<TimedWrench> rigid =
      RigidTrace([](double t) { return 800.0 * t; });
  std::mt19937_64 rng(1);
  const std::vector<TimedWrench> out = CompliantArm(rigid, Wrist4NPerMm(), rng);
  ASSERT_EQ(out.size(), rigid.size());
  for (size_t i = 0; i < out.size(); ++i) {
    ASSERT_EQ(out[i].t_s, rigid[i].t_s);
    const double t = out[i].t_s;
    const double expected = t < 0.2 ? 0.0 : 160.0 * (t - 0.2);
    ASSERT_NEAR(out[i].wrench.force_n[2], expected, 1e-9) << "at " << t;
  }
  // A soft item's 60 N/s is slowed far less: 1 / (1/60 + 1/200) = 46 N/s.
  const std::vector<TimedWrench> soft = CompliantArm(
      RigidTrace([](double t) { return 60.0 * t; }), Wrist4NPerMm(), rng);
  EXPECT_NEAR(soft[300].wrench.force_n[2], 0.1 * 60.0 / 1.3, 1e-9);
}

TEST(CompliantArmTest, ADropComesLaterByThePeakOverTheRateAndStaysSudden) {
  // 1,000 N/s to 10 N at 0.21 s, then the item yields to 4 N. Through the
  // wrist the peak is felt at 0.21 + 10 / 200 = 0.26 s, and the tip then
  // jumps to where the spring carries 4 N: the fall takes a sample or two.
  const std::vector<TimedWrench> rigid =
      RigidTrace([](double t) { return t <= 0.0100001 ? 1000.0 * t : 4.0; });
  std::mt19937_64 rng(2);
  const std::vector<TimedWrench> out = CompliantArm(rigid, Wrist4NPerMm(), rng);
  size_t peak = 0;
  for (size_t i = 0; i < out.size(); ++i) {
    if (out[i].wrench.force_n[2] > out[peak].wrench.force_n[2]) peak = i;
  }
  // On the 1 ms clock the peak and the jump share the sample at 0.26 s.
  EXPECT_NEAR(out[peak].t_s, 0.26, 1.001e-3);
  EXPECT_GT(out[peak].wrench.force_n[2], 9.5);
  EXPECT_LT(out[peak + 2].wrench.force_n[2], 4.5);
  for (size_t i = peak + 3; i < out.size(); ++i) {
    ASSERT_NEAR(out[i].wrench.force_n[2], 4.0, 1e-9) << "at " << out[i].t_s;
  }
}

TEST(CompliantArmTest, ItsShareIsItsProbabilityAndStoriesStayServiceable) {
  const std::vector<TimedWrench> rigid =
      RigidTrace([](double t) { return 800.0 * t; });
  ArmCompliance off;
  off.probability = 0.0;
  std::mt19937_64 rng(3);
  const std::vector<TimedWrench> same = CompliantArm(rigid, off, rng);
  for (size_t i = 0; i < rigid.size(); ++i) {
    EXPECT_EQ(same[i].wrench.force_n[2], rigid[i].wrench.force_n[2]);
  }
  const ArmCompliance half;  // the default: half the traces
  int changed = 0;
  for (int draw = 0; draw < 400; ++draw) {
    changed += CompliantArm(rigid, half, rng)[300].wrench.force_n[2] !=
               rigid[300].wrench.force_n[2];
  }
  EXPECT_GT(changed, 160);
  EXPECT_LT(changed, 240);

  // Every story's traces, each through an arm: finite, on their own clock,
  // and mostly still a trace the service classifies.
  ArmCompliance always;
  always.probability = 1.0;
  int accepted = 0, total = 0;
  for (TraceStory story :
       {TraceStory::kWorld, TraceStory::kPiecewise, TraceStory::kMechanics}) {
    for (const LabelledTrace& trace : StoryTraces(story, 10, 5)) {
      const std::vector<TimedWrench> out =
          CompliantArm(trace.samples, always, rng);
      ASSERT_EQ(out.size(), trace.samples.size());
      for (size_t i = 0; i < out.size(); ++i) {
        ASSERT_EQ(out[i].t_s, trace.samples[i].t_s);
        for (double v : Channels(out[i].wrench)) ASSERT_TRUE(std::isfinite(v));
      }
      accepted += ExtractHapticFeatures(out, HapticPipelineOptions()).ok();
      ++total;
    }
  }
  EXPECT_GE(accepted, total - 2) << "of " << total;
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
