#include "services/sim/trace_stories.h"

#include <algorithm>
#include <array>
#include <cmath>

#include "services/domain/random.h"

namespace bitewise::sim {
namespace {

using random::LogUniform;
using random::Uniform;

// ---------------------------------------------------------------------------
// Piecewise story.

// Fz (N) through (time after contact, force) knots, flat after the last.
struct PiecewiseLinear {
  std::vector<std::array<double, 2>> knots;  // (tau_s, fz_n), tau ascending
  double At(double tau) const {
    if (tau <= 0.0) return 0.0;
    for (size_t i = 1; i < knots.size(); ++i) {
      if (tau <= knots[i][0]) {
        const auto& a = knots[i - 1];
        const auto& b = knots[i];
        return a[1] + (b[1] - a[1]) * (tau - a[0]) / (b[0] - a[0]);
      }
    }
    return knots.back()[1];
  }
};

PiecewiseLinear PiecewiseItem(HapticCategory category, std::mt19937_64& rng) {
  PiecewiseLinear p;
  switch (category) {
    case HapticCategory::kHard: {
      // A straight ramp to a high force, then a slow creep or relaxation.
      const double peak = Uniform(rng, 8.0, 22.0);
      const double rise = Uniform(rng, 0.004, 0.016);
      p.knots = {
          {0.0, 0.0}, {rise, peak}, {0.2, peak * Uniform(rng, 0.9, 1.1)}};
      break;
    }
    case HapticCategory::kMedium: {
      // A moderate ramp, a plateau, a puncture losing 12-35 %, a slow rise.
      const double peak = Uniform(rng, 2.0, 6.0);
      const double rise = Uniform(rng, 0.010, 0.025);
      const double puncture = rise + Uniform(rng, 0.008, 0.020);
      const double after = peak * (1.0 - Uniform(rng, 0.12, 0.35));
      const double fall = Uniform(rng, 0.003, 0.008);
      p.knots = {{0.0, 0.0},
                 {rise, peak},
                 {puncture, peak * Uniform(rng, 0.95, 1.05)},
                 {puncture + fall, after},
                 {0.2, after * Uniform(rng, 1.0, 1.3)}};
      break;
    }
    case HapticCategory::kSoft: {
      // A slow ramp that levels off at a low force.
      const double slope = Uniform(rng, 12.0, 40.0);
      const double level = Uniform(rng, 1.5, 3.0);
      p.knots = {{0.0, 0.0},
                 {level / slope, level},
                 {0.2, level * Uniform(rng, 1.0, 1.2)}};
      break;
    }
    case HapticCategory::kHardSkin: {
      // A steep ramp to a peak, the skin breaks: a fast drop of 50-80 %.
      const double peak = Uniform(rng, 4.0, 10.0);
      const double rise = Uniform(rng, 0.007, 0.018);
      const double skin = rise + Uniform(rng, 0.002, 0.012);
      const double after = peak * (1.0 - Uniform(rng, 0.5, 0.8));
      const double fall = Uniform(rng, 0.001, 0.004);
      p.knots = {{0.0, 0.0},
                 {rise, peak},
                 {skin, peak * Uniform(rng, 1.0, 1.08)},
                 {skin + fall, after},
                 {0.2, after}};
      break;
    }
  }
  return p;
}

// ---------------------------------------------------------------------------
// Mechanics story.

// Internal step of the mechanics (50 kHz): fine enough for the fastest
// event (a brittle crack of 0.2 ms) at the fastest sensor rate (7 kHz).
constexpr double kStepS = 2e-5;

// Axial force (N) of one item against the depth of the tines, advanced in
// time order. Each category is a small state machine.
class Penetration {
 public:
  Penetration(HapticCategory category, std::mt19937_64& rng)
      : category_(category) {
    switch (category) {
      case HapticCategory::kHard:
        // Four tines load the tissue like Hertzian contacts (F ~ d^1.5)
        // until it cracks at 8-20 N; each crack sheds 8-30 % of the load in
        // 0.2-1 ms; the tines reload the cracked tissue linearly (the next
        // crack at about the same force, plus shaft friction growing by
        // 0.3-1 N per mm of depth).
        hertz_ = LogUniform(rng, 3e5, 1.5e6);
        crack_n_ = Uniform(rng, 8.0, 20.0);
        reload_m_ = Uniform(rng, 0.15e-3, 0.4e-3);
        friction_n_per_m_ = Uniform(rng, 300.0, 1000.0);
        break;
      case HapticCategory::kHardSkin:
        // A turgid skin over soft flesh: the skin stretches (F = Fr (a x +
        // (1 - a) x^2), x = d / dr) until it ruptures at 3-9 N after
        // 0.8-2 mm; it tears in 0.5-3 ms down to the flesh's 10-35 % of
        // that force, which then grows by cutting and friction (0.05-0.2 N
        // per mm: four tines in soft flesh).
        rupture_n_ = Uniform(rng, 3.0, 9.0);
        rupture_m_ = Uniform(rng, 0.8e-3, 2.0e-3);
        linear_share_ = Uniform(rng, 0.4, 0.8);
        tear_s_ = Uniform(rng, 0.5e-3, 3e-3);
        after_share_ = Uniform(rng, 0.10, 0.35);
        friction_n_per_m_ = Uniform(rng, 50.0, 200.0);
        break;
      case HapticCategory::kMedium:
        // A cellular solid: cell walls bend, then collapse (a concave rise
        // to 2-6 N over 0.5-1.5 mm); the surface tears under the tines and
        // sheds 10-35 % of the load over 2-8 ms (wet tissue tears slowly);
        // then the cells crush and densify ahead of the tines (0.1-0.4 N per
        // mm).
        yield_n_ = Uniform(rng, 2.0, 6.0);
        yield_m_ = Uniform(rng, 0.5e-3, 1.5e-3);
        concavity_ = Uniform(rng, 1.3, 2.0);
        tear_s_ = Uniform(rng, 2e-3, 8e-3);
        after_share_ = 1.0 - Uniform(rng, 0.10, 0.35);
        friction_n_per_m_ = Uniform(rng, 100.0, 400.0);
        break;
      case HapticCategory::kSoft:
        // A standard linear solid: instantaneous stiffness 2-5 times the
        // relaxed one, relaxation in 5-40 ms, the relaxed one 150-600 N/m;
        // the flesh flows around the tines at a cutting limit of 1-3 N.
        relaxed_n_per_m_ = Uniform(rng, 150.0, 600.0);
        instant_n_per_m_ = relaxed_n_per_m_ * Uniform(rng, 2.0, 5.0);
        relax_s_ = Uniform(rng, 5e-3, 40e-3);
        cut_n_ = Uniform(rng, 1.0, 3.0);
        break;
    }
    crack_threshold_n_ = crack_n_;
  }

  // Force after the tines have advanced by `step_m` during kStepS.
  double Advance(double step_m, std::mt19937_64& rng) {
    depth_m_ += step_m;
    time_s_ += kStepS;
    switch (category_) {
      case HapticCategory::kHard:
        return AdvanceHard(rng);
      case HapticCategory::kHardSkin:
        return AdvanceSkin();
      case HapticCategory::kMedium:
        return AdvanceMedium();
      case HapticCategory::kSoft:
        return AdvanceSoft(step_m);
    }
    return 0.0;
  }

 private:
  // The load carried by the structure now, and what is still relaxing
  // after the last failure event (decaying with event_s_).
  double Relaxing() const {
    if (event_excess_n_ == 0.0) return 0.0;
    return event_excess_n_ * std::exp(-(time_s_ - event_time_s_) / event_s_);
  }

  double AdvanceHard(std::mt19937_64& rng) {
    double structure;
    if (!cracked_) {
      structure = hertz_ * std::pow(depth_m_, 1.5);
    } else {
      structure = branch_n_ + (crack_n_ / reload_m_) * (depth_m_ - branch_m_);
    }
    const bool settled = !cracked_ || time_s_ - event_time_s_ > 3.0 * event_s_;
    if (settled && structure >= crack_threshold_n_) {
      const double shed = Uniform(rng, 0.08, 0.30);
      event_excess_n_ = structure * shed;
      event_time_s_ = time_s_;
      event_s_ = Uniform(rng, 0.2e-3, 1e-3);
      branch_n_ = structure * (1.0 - shed);
      branch_m_ = depth_m_;
      cracked_ = true;
      crack_threshold_n_ =
          crack_n_ * Uniform(rng, 0.85, 1.1) + friction_n_per_m_ * depth_m_;
      structure = branch_n_;
    }
    return structure + Relaxing();
  }

  double AdvanceSkin() {
    if (!cracked_) {
      const double x = depth_m_ / rupture_m_;
      const double f =
          rupture_n_ * (linear_share_ * x + (1.0 - linear_share_) * x * x);
      if (x < 1.0) return f;
      cracked_ = true;
      event_excess_n_ = f * (1.0 - after_share_);
      event_time_s_ = time_s_;
      event_s_ = tear_s_;
      branch_n_ = f * after_share_;
      branch_m_ = depth_m_;
    }
    return branch_n_ + friction_n_per_m_ * (depth_m_ - branch_m_) + Relaxing();
  }

  double AdvanceMedium() {
    if (!cracked_) {
      const double x = depth_m_ / yield_m_;
      const double f =
          yield_n_ * (1.0 - std::pow(1.0 - std::min(x, 1.0), concavity_));
      if (x < 1.0) return f;
      cracked_ = true;
      event_excess_n_ = f * (1.0 - after_share_);
      event_time_s_ = time_s_;
      event_s_ = tear_s_;
      branch_n_ = f * after_share_;
      branch_m_ = depth_m_;
    }
    return branch_n_ + friction_n_per_m_ * (depth_m_ - branch_m_) + Relaxing();
  }

  double AdvanceSoft(double step_m) {
    // q: the relaxing part of the standard linear solid's force.
    viscous_n_ += (instant_n_per_m_ - relaxed_n_per_m_) * step_m -
                  viscous_n_ * kStepS / relax_s_;
    const double elastic = relaxed_n_per_m_ * depth_m_ + viscous_n_;
    return cut_n_ * std::tanh(elastic / cut_n_);
  }

  HapticCategory category_;
  double depth_m_ = 0.0;
  double time_s_ = 0.0;
  // Hard.
  double hertz_ = 0.0;
  double crack_n_ = 0.0;
  double reload_m_ = 1.0;
  double crack_threshold_n_ = 0.0;
  // Hard-skin and medium.
  double rupture_n_ = 0.0, rupture_m_ = 1.0, linear_share_ = 1.0;
  double yield_n_ = 0.0, yield_m_ = 1.0, concavity_ = 1.0;
  double tear_s_ = 1e-3;
  double after_share_ = 1.0;
  double friction_n_per_m_ = 0.0;
  // Soft.
  double relaxed_n_per_m_ = 0.0, instant_n_per_m_ = 0.0, relax_s_ = 1.0;
  double cut_n_ = 1.0;
  double viscous_n_ = 0.0;
  // The last failure event (crack, rupture, tear).
  bool cracked_ = false;
  double branch_n_ = 0.0, branch_m_ = 0.0;
  double event_excess_n_ = 0.0, event_time_s_ = 0.0, event_s_ = 1e-3;
};

}  // namespace

std::vector<TimedWrench> PiecewiseStoryTrace(HapticCategory category,
                                             std::mt19937_64& rng) {
  constexpr std::array<double, 6> kRates = {100.0,  250.0,  500.0,
                                            1000.0, 2500.0, 7000.0};
  random::Normal normal;
  const PiecewiseLinear fz = PiecewiseItem(category, rng);
  const double rate = kRates[rng() % kRates.size()];
  const double contact = Uniform(rng, 0.15, 0.35);
  const double force_sd = Uniform(rng, 0.03, 0.15);
  const double torque_sd = Uniform(rng, 0.002, 0.008);
  const double angle = Uniform(rng, 0.0, 2.0 * M_PI);
  const double lateral = Uniform(rng, 0.0, 0.3);
  const double lever = Uniform(rng, 0.015, 0.045);
  std::array<double, 6> offset;
  for (int c = 0; c < 6; ++c) {
    offset[c] = Uniform(rng, -1.5, 1.5) * (c < 3 ? 1.0 : 0.02);
  }
  const int n = static_cast<int>((contact + 0.25) * rate);
  std::vector<TimedWrench> trace;
  trace.reserve(n);
  for (int j = 0; j < n; ++j) {
    const double t = j / rate;
    const double f = fz.At(t - contact);
    const double fx = lateral * std::cos(angle) * f;
    const double fy = lateral * std::sin(angle) * f;
    TimedWrench s;
    s.t_s = t;
    s.wrench.force_n = {fx, fy, f};
    s.wrench.torque_nm = {lever * fy, -lever * fx, 0.0};
    for (int c = 0; c < 3; ++c) {
      s.wrench.force_n[c] += offset[c] + force_sd * normal(rng);
      s.wrench.torque_nm[c] += offset[3 + c] + torque_sd * normal(rng);
    }
    trace.push_back(s);
  }
  return trace;
}

std::vector<TimedWrench> MechanicsStoryTrace(HapticCategory category,
                                             std::mt19937_64& rng) {
  // The item and the fork. The arm commands 5 cm/s and tracks it within
  // 20 %, and stops at the skewering depth (8-15 mm into the item) or at
  // its force limit (20-30 N), whichever comes first, and holds; the tines
  // lean 0-8 degrees in any direction (lateral force); the tips are 20-40 mm
  // below the sensor; off-centre tines twist by up to 2 mm of lever.
  Penetration item(category, rng);
  const double speed = Uniform(rng, 0.04, 0.06);
  const double stop_depth_m = Uniform(rng, 0.008, 0.015);
  const double force_limit_n = Uniform(rng, 20.0, 30.0);
  const double lean = std::tan(Uniform(rng, 0.0, 8.0) * M_PI / 180.0);
  const double lean_angle = Uniform(rng, 0.0, 2.0 * M_PI);
  const double lever = Uniform(rng, 0.020, 0.040);
  const double twist = Uniform(rng, -0.002, 0.002);

  // The sensor as recorded: one of four rates; untared offset (the fork's
  // weight, temperature) up to 3 N and 0.06 N m; thermal drift up to 1 N/s;
  // the moving arm's vibration at 8-30 Hz up to 0.25 N in a random
  // direction; mains hum at 50 or 60 Hz up to 0.04 N; the gauges and
  // anti-alias filter as a first-order low-pass of 0.05-0.3 ms; white noise
  // 0.02-0.12 N and 0.001-0.006 N m; the Nano25's counts (1/48 N,
  // 1/1320 N m); up to 2 % of the UDP records lost.
  constexpr std::array<double, 4> kRates = {250.0, 500.0, 1000.0, 7000.0};
  const double rate = kRates[rng() % kRates.size()];
  std::array<double, 6> offset, drift;
  for (int c = 0; c < 6; ++c) {
    const double scale = c < 3 ? 1.0 : 0.02;
    offset[c] = Uniform(rng, -3.0, 3.0) * scale;
    drift[c] = Uniform(rng, -1.0, 1.0) * scale;
  }
  const double vibration_hz = Uniform(rng, 8.0, 30.0);
  const double vibration_n = Uniform(rng, 0.02, 0.25);
  const double vibration_phase = Uniform(rng, 0.0, 2.0 * M_PI);
  std::array<double, 3> vibration_direction;
  {
    random::Normal normal;
    double norm = 0.0;
    for (double& v : vibration_direction) {
      v = normal(rng);
      norm += v * v;
    }
    for (double& v : vibration_direction) v /= std::sqrt(norm);
  }
  const double hum_hz = rng() % 2 == 0 ? 50.0 : 60.0;
  const double hum_n = Uniform(rng, 0.0, 0.04);
  const double low_pass_s = Uniform(rng, 0.05e-3, 0.3e-3);
  const double force_sd = Uniform(rng, 0.02, 0.12);
  const double torque_sd = Uniform(rng, 0.001, 0.006);
  const double loss = Uniform(rng, 0.0, 0.02);
  constexpr double kForceCount = 1.0 / 48.0;
  constexpr double kTorqueCount = 1.0 / 1320.0;
  const double contact = Uniform(rng, 0.1, 0.3);
  const double duration = contact + 0.25;

  // The axial force on the internal grid, low-passed by the gauges.
  const int steps = static_cast<int>(std::ceil(duration / kStepS)) + 2;
  std::vector<float> fz(steps, 0.0f);
  double filtered = 0.0, raw = 0.0, depth_m = 0.0;
  bool stopped = false;
  const double alpha = 1.0 - std::exp(-kStepS / low_pass_s);
  for (int i = 0; i < steps; ++i) {
    const double t = i * kStepS;
    if (t > contact) {
      stopped = stopped || depth_m >= stop_depth_m || raw >= force_limit_n;
      const double step_m = stopped ? 0.0 : speed * kStepS;
      depth_m += step_m;
      raw = item.Advance(step_m, rng);
    }
    filtered += alpha * (raw - filtered);
    fz[i] = static_cast<float>(filtered);
  }

  random::Normal normal;
  const int n = static_cast<int>(duration * rate);
  std::vector<TimedWrench> trace;
  trace.reserve(n);
  for (int j = 0; j < n; ++j) {
    const double t = j / rate;
    const bool lost = random::Canonical(rng) < loss;
    const double f = fz[std::min(steps - 1, static_cast<int>(t / kStepS))];
    const double vibration =
        vibration_n * std::sin(2.0 * M_PI * vibration_hz * t + vibration_phase);
    const double hum = hum_n * std::sin(2.0 * M_PI * hum_hz * t);
    Wrench w;
    w.force_n = {lean * std::cos(lean_angle) * f,
                 lean * std::sin(lean_angle) * f, f};
    w.torque_nm = {lever * w.force_n[1], -lever * w.force_n[0], twist * f};
    for (int c = 0; c < 3; ++c) {
      w.force_n[c] += offset[c] + drift[c] * t +
                      vibration * vibration_direction[c] + hum +
                      force_sd * normal(rng);
      w.force_n[c] = kForceCount * std::round(w.force_n[c] / kForceCount);
      w.torque_nm[c] += offset[3 + c] + drift[3 + c] * t +
                        lever * vibration * vibration_direction[c] * 0.5 +
                        torque_sd * normal(rng);
      w.torque_nm[c] = kTorqueCount * std::round(w.torque_nm[c] / kTorqueCount);
    }
    if (!lost) trace.push_back({t, w});
  }
  return trace;
}

}  // namespace bitewise::sim
