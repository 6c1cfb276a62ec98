// The force-trace model (services/sim/force_trace.h): a profile is zero
// before contact and its torques are the lever times the force, a trace is
// sampled at its rate with contact at its time and, unvaried, is Measure()'s
// sample for sample; the random bias is one per trace; each variation
// (amplitude, time, drop time, lateral, twist, touch) does what it says
// against the unvaried profile; jitter stays within its fraction; a force
// limit halts the fork at the first control-period check that finds it
// reached, holds the force, then unloads it as the fork pulls back.
#include "services/sim/force_trace.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "gtest/gtest.h"

namespace bitewise::sim {
namespace {

constexpr HapticCategory kCategories[] = {
    HapticCategory::kHard, HapticCategory::kMedium, HapticCategory::kSoft,
    HapticCategory::kHardSkin};

ForceProfile Profile(HapticCategory category, uint64_t seed) {
  std::mt19937_64 rng(seed);
  return ForceProfile::Sample(category, rng);
}

// No noise, no bias: the trace is the (varied) profile itself.
TraceOptions Clean() {
  TraceOptions options;
  options.noise.force_sd_n = 0.0;
  options.noise.torque_sd_nm = 0.0;
  options.noise.random_bias_n = 0.0;
  return options;
}

TEST(ForceProfileTest, IsZeroBeforeContactAndItsTorqueIsTheLeverTimesForce) {
  for (const HapticCategory category : kCategories) {
    const ForceProfile profile = Profile(category, 5);
    for (const double tau : {-0.1, 0.0}) {
      const Wrench w = profile.At(tau);
      for (int i = 0; i < 3; ++i) {
        EXPECT_EQ(w.force_n[i], 0.0);
        EXPECT_EQ(w.torque_nm[i], 0.0);
      }
    }
    // The tines 25-35 mm below the sensor, along -z: tau = r x F.
    const Wrench first = profile.At(0.02);
    const double lever = first.torque_nm[0] / first.force_n[1];
    EXPECT_GE(lever, 0.025);
    EXPECT_LE(lever, 0.035);
    // Fx and Fy a fixed 5-20 % of Fz, whatever the time.
    const double lateral =
        std::hypot(first.force_n[0], first.force_n[1]) / first.force_n[2];
    EXPECT_GE(lateral, 0.05 - 1e-12);
    EXPECT_LE(lateral, 0.20 + 1e-12);
    for (const double tau : {0.001, 0.03, 0.2}) {
      const Wrench w = profile.At(tau);
      EXPECT_GT(w.force_n[2], 0.0);
      EXPECT_NEAR(w.torque_nm[0], lever * w.force_n[1], 1e-12);
      EXPECT_NEAR(w.torque_nm[1], -lever * w.force_n[0], 1e-12);
      EXPECT_EQ(w.torque_nm[2], 0.0);
      EXPECT_NEAR(std::hypot(w.force_n[0], w.force_n[1]) / w.force_n[2],
                  lateral, 1e-12);
    }
  }
}

TEST(SimulateTraceTest, SamplesAtTheRateWithContactAtItsTime) {
  const ForceProfile profile = Profile(HapticCategory::kHardSkin, 7);
  TraceOptions options = Clean();
  options.rate_hz = 2500.0;
  options.contact_s = 0.1;
  options.duration_s = 0.3;
  std::mt19937_64 rng(1);
  const std::vector<TimedWrench> trace = SimulateTrace(profile, options, rng);
  ASSERT_EQ(trace.size(), 750u);
  for (size_t i = 0; i < trace.size(); ++i) {
    const double t = i / 2500.0;
    EXPECT_NEAR(trace[i].t_s, t, 1e-15);
    const Wrench want = profile.At(trace[i].t_s - 0.1);
    for (int c = 0; c < 3; ++c) {
      ASSERT_EQ(trace[i].wrench.force_n[c], want.force_n[c]) << i;
      ASSERT_EQ(trace[i].wrench.torque_nm[c], want.torque_nm[c]) << i;
    }
  }
  // Nothing until contact, then the item.
  EXPECT_EQ(trace[249].wrench.force_n[2], 0.0);
  EXPECT_GT(trace[251].wrench.force_n[2], 0.0);
}

// Unvaried, a trace is the profile plus the fixed bias plus white noise of
// the configured size on every channel: the residuals' means are within
// four standard errors of zero and their spreads within 15 % of the
// configured ones (600 samples per channel, 3 channels each).
TEST(SimulateTraceTest, UnvariedItIsTheProfilePlusBiasPlusWhiteNoise) {
  const ForceProfile profile = Profile(HapticCategory::kMedium, 3);
  TraceOptions options;  // noise on
  options.noise.random_bias_n = 0.0;
  options.noise.bias.force_n = {0.2, -0.1, 0.4};
  options.noise.bias.torque_nm = {0.01, 0.0, -0.02};
  std::mt19937_64 rng(9);
  const std::vector<TimedWrench> trace = SimulateTrace(profile, options, rng);
  ASSERT_EQ(trace.size(), 600u);
  const double n = static_cast<double>(trace.size());
  for (int c = 0; c < 3; ++c) {
    double f_sum = 0, f_sq = 0, t_sum = 0, t_sq = 0;
    for (const TimedWrench& sample : trace) {
      const Wrench clean = profile.At(sample.t_s - options.contact_s);
      const double f = sample.wrench.force_n[c] - clean.force_n[c] -
                       options.noise.bias.force_n[c];
      const double t = sample.wrench.torque_nm[c] - clean.torque_nm[c] -
                       options.noise.bias.torque_nm[c];
      f_sum += f;
      f_sq += f * f;
      t_sum += t;
      t_sq += t * t;
    }
    const double f_sd = options.noise.force_sd_n;
    const double t_sd = options.noise.torque_sd_nm;
    EXPECT_LT(std::abs(f_sum / n), 4 * f_sd / std::sqrt(n)) << c;
    EXPECT_LT(std::abs(t_sum / n), 4 * t_sd / std::sqrt(n)) << c;
    EXPECT_NEAR(std::sqrt(f_sq / n), f_sd, 0.15 * f_sd) << c;
    EXPECT_NEAR(std::sqrt(t_sq / n), t_sd, 0.15 * t_sd) << c;
  }
}

TEST(SimulateTraceTest, TheRandomBiasIsOnePerTraceWithinItsBounds) {
  const ForceProfile profile = Profile(HapticCategory::kHard, 2);
  TraceOptions options = Clean();
  options.noise.random_bias_n = 0.5;
  std::mt19937_64 rng(4);
  std::vector<Wrench> biases;
  for (int trace_index = 0; trace_index < 20; ++trace_index) {
    const std::vector<TimedWrench> trace = SimulateTrace(profile, options, rng);
    // Before contact the sensor reads its bias alone, the same throughout.
    const Wrench bias = trace[0].wrench;
    for (int i = 1; i < 300; ++i) {
      for (int c = 0; c < 3; ++c) {
        ASSERT_EQ(trace[i].wrench.force_n[c], bias.force_n[c]);
        ASSERT_EQ(trace[i].wrench.torque_nm[c], bias.torque_nm[c]);
      }
    }
    for (int c = 0; c < 3; ++c) {
      EXPECT_LE(std::abs(bias.force_n[c]), 0.5);
      EXPECT_LE(std::abs(bias.torque_nm[c]), 0.01);
    }
    // After contact: the profile plus the same bias.
    const Wrench at = profile.At(trace[450].t_s - options.contact_s);
    EXPECT_NEAR(trace[450].wrench.force_n[2], at.force_n[2] + bias.force_n[2],
                1e-12);
    biases.push_back(bias);
  }
  EXPECT_NE(biases[0].force_n[2], biases[1].force_n[2]);
}

// The trace's Fz at sample i.
double Fz(const std::vector<TimedWrench>& trace, int i) {
  return trace[i].wrench.force_n[2];
}

TEST(SimulateTraceTest, AmplitudeLateralTwistAndTouchDoWhatTheySay) {
  const ForceProfile profile = Profile(HapticCategory::kHard, 11);
  TraceOptions options = Clean();
  options.variation.amplitude = 1.5;
  options.variation.lateral_scale = 0.0;
  options.variation.twist_m = 0.01;
  options.variation.touch_n = 0.4;
  options.variation.touch_s = 0.1;
  std::mt19937_64 rng(1);
  const std::vector<TimedWrench> trace = SimulateTrace(profile, options, rng);
  ASSERT_EQ(trace.size(), 600u);
  for (int i = 0; i < 600; ++i) {
    const double tau = trace[i].t_s - options.contact_s;
    // The touch: nothing until 0.1 s before contact, a ramp to 0.4 N, then
    // 0.4 N under the item's force.
    double touch = 0.0;
    if (tau > 0.0) {
      touch = 0.4;
    } else if (tau > -0.1) {
      touch = 0.4 * (tau + 0.1) / 0.1;
    }
    const double fz = 1.5 * profile.At(tau).force_n[2] + touch;
    ASSERT_NEAR(Fz(trace, i), fz, 1e-12) << i;
    const Wrench& w = trace[i].wrench;
    ASSERT_EQ(w.force_n[0], 0.0);
    ASSERT_EQ(w.force_n[1], 0.0);
    ASSERT_EQ(w.torque_nm[0], 0.0);
    ASSERT_EQ(w.torque_nm[1], 0.0);
    ASSERT_NEAR(w.torque_nm[2], 0.01 * fz, 1e-12);
  }
  EXPECT_EQ(Fz(trace, 199), 0.0);
  EXPECT_NEAR(Fz(trace, 250), 0.2, 1e-12);
}

TEST(SimulateTraceTest, TimeScalesStretchTheRiseAndThenTheDrop) {
  const ForceProfile profile = Profile(HapticCategory::kHardSkin, 13);
  // The force peak (the skin break) in the first 100 ms, on a 0.1 ms grid.
  double peak_s = 0.0, peak_n = -1.0;
  for (int i = 1; i <= 1000; ++i) {
    if (profile.At(i * 1e-4).force_n[2] > peak_n) {
      peak_n = profile.At(i * 1e-4).force_n[2];
      peak_s = i * 1e-4;
    }
  }
  ASSERT_GT(peak_s, 0.01);
  ASSERT_LT(peak_s, 0.05);

  TraceOptions options = Clean();
  options.rate_hz = 4000.0;
  options.variation.time_scale = 2.0;
  options.variation.drop_time_scale = 3.0;
  std::mt19937_64 rng(1);
  const std::vector<TimedWrench> trace = SimulateTrace(profile, options, rng);
  for (size_t i = 0; i < trace.size(); ++i) {
    const double tau = trace[i].t_s - options.contact_s;
    // Up to the peak the profile runs at half speed; after it, at a sixth.
    double profile_tau = tau / 2.0;
    if (profile_tau > peak_s) profile_tau = peak_s + (profile_tau - peak_s) / 3;
    ASSERT_NEAR(trace[i].wrench.force_n[2], profile.At(profile_tau).force_n[2],
                1e-12)
        << "tau " << tau;
  }
}

TEST(SimulateTraceTest, JitterMovesEachStampByLessThanItsFraction) {
  const ForceProfile profile = Profile(HapticCategory::kSoft, 1);
  TraceOptions options = Clean();
  options.jitter_fraction = 0.5;
  std::mt19937_64 rng(6);
  const std::vector<TimedWrench> trace = SimulateTrace(profile, options, rng);
  EXPECT_EQ(trace[0].t_s, 0.0);
  double moved = 0.0;
  for (size_t i = 1; i < trace.size(); ++i) {
    const double off = trace[i].t_s - i / options.rate_hz;
    EXPECT_LE(std::abs(off), 0.25 / options.rate_hz + 1e-15);
    EXPECT_GT(trace[i].t_s, trace[i - 1].t_s);
    moved = std::max(moved, std::abs(off));
  }
  EXPECT_GT(moved, 0.2 / options.rate_hz);
}

double Magnitude(const Wrench& w) {
  return std::sqrt(w.force_n[0] * w.force_n[0] + w.force_n[1] * w.force_n[1] +
                   w.force_n[2] * w.force_n[2]);
}

TEST(SimulateTraceTest, AForceLimitHoldsTheForceAtTheCheckThenUnloads) {
  for (uint64_t seed = 1; seed <= 20; ++seed) {
    const ForceProfile profile = Profile(HapticCategory::kHard, seed);
    TraceOptions options = Clean();
    options.stop.limit_n = 10.0;
    if (profile.PeakForce() < 10.5) continue;  // reaches 10 N too late
    std::mt19937_64 rng(seed);
    bool reached = false;
    const std::vector<TimedWrench> trace =
        SimulateTrace(profile, options, rng, &reached);
    ASSERT_TRUE(reached) << seed;
    // When the item's force first reaches the limit, on the trace's samples.
    double first_s = -1.0;
    for (const TimedWrench& sample : trace) {
      if (Magnitude(profile.At(sample.t_s - options.contact_s)) >= 10.0) {
        first_s = sample.t_s;
        break;
      }
    }
    ASSERT_GT(first_s, options.contact_s) << seed;
    // Before the halt the trace is the profile; the halt comes at the next
    // check, within one control period; then the force holds.
    double halt_s = -1.0, held_n = 0.0;
    for (size_t i = 1; i < trace.size(); ++i) {
      const double clean =
          Magnitude(profile.At(trace[i].t_s - options.contact_s));
      if (std::abs(Magnitude(trace[i].wrench) - clean) > 1e-9) {
        halt_s = trace[i - 1].t_s;
        held_n = Magnitude(trace[i].wrench);
        break;
      }
    }
    ASSERT_GT(halt_s, 0.0) << seed;
    EXPECT_GE(halt_s, first_s - 1e-9) << seed;
    EXPECT_LE(halt_s, first_s + options.stop.control_period_s + 1e-3) << seed;
    EXPECT_GE(held_n, 10.0) << seed;
    EXPECT_LT(held_n, profile.PeakForce()) << seed;
    for (const TimedWrench& sample : trace) {
      const double since_halt = sample.t_s - halt_s;
      const double force = Magnitude(sample.wrench);
      if (since_halt > 1e-3 && since_halt < options.stop.lift_delay_s) {
        EXPECT_NEAR(force, held_n, 1e-9) << seed << " " << sample.t_s;
      }
      // Unloading: never above the held force, zero once pulled back.
      if (since_halt > 0.0) {
        EXPECT_LE(force, held_n + 1e-9) << seed;
      }
      if (since_halt >
          options.stop.lift_delay_s + options.stop.unload_s + 1e-3) {
        EXPECT_EQ(force, 0.0) << seed << " " << sample.t_s;
      }
    }
  }
}

TEST(SimulateTraceTest, AForceLimitAboveThePeakChangesNothingButTheNoise) {
  for (const HapticCategory category : kCategories) {
    const ForceProfile profile = Profile(category, 4);
    TraceOptions options = Clean();
    double max_n = 0.0;
    for (double tau = 0.0; tau <= options.duration_s; tau += 1e-4) {
      max_n = std::max(max_n, Magnitude(profile.At(tau)));
    }
    options.stop.limit_n = max_n + 0.01;
    std::mt19937_64 rng(4);
    bool reached = true;
    const std::vector<TimedWrench> trace =
        SimulateTrace(profile, options, rng, &reached);
    EXPECT_FALSE(reached);
    for (const TimedWrench& sample : trace) {
      const Wrench clean = profile.At(sample.t_s - options.contact_s);
      for (int c = 0; c < 3; ++c) {
        EXPECT_EQ(sample.wrench.force_n[c], clean.force_n[c]);
      }
    }
  }
}

}  // namespace
}  // namespace bitewise::sim
