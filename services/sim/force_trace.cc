#include "services/sim/force_trace.h"

#include <cmath>

namespace bitewise::sim {
namespace {

double Uniform(std::mt19937_64& rng, double lo, double hi) {
  return std::uniform_real_distribution<double>(lo, hi)(rng);
}

}  // namespace

ForceProfile ForceProfile::Sample(HapticCategory category,
                                  std::mt19937_64& rng) {
  ForceProfile p;
  p.category_ = category;
  switch (category) {
    case HapticCategory::kHard:
      p.peak_n_ = Uniform(rng, 10.0, 18.0);
      p.rise_s_ = Uniform(rng, 0.006, 0.014);
      break;
    case HapticCategory::kHardSkin:
      p.peak_n_ = Uniform(rng, 5.0, 9.0);
      p.rise_s_ = Uniform(rng, 0.008, 0.014);
      p.break_s_ = Uniform(rng, 0.018, 0.030);
      p.drop_ = Uniform(rng, 0.55, 0.75);
      p.drop_s_ = Uniform(rng, 0.002, 0.004);
      break;
    case HapticCategory::kMedium:
      p.peak_n_ = Uniform(rng, 2.5, 5.0);
      p.rise_s_ = Uniform(rng, 0.012, 0.022);
      p.break_s_ = Uniform(rng, 0.028, 0.042);
      p.drop_ = Uniform(rng, 0.15, 0.30);
      p.drop_s_ = Uniform(rng, 0.004, 0.008);
      break;
    case HapticCategory::kSoft:
      p.slope_n_per_s_ = Uniform(rng, 15.0, 35.0);
      p.peak_n_ = Uniform(rng, 1.2, 2.2);
      p.rise_s_ = Uniform(rng, 0.040, 0.080);
      break;
  }
  const double angle = Uniform(rng, 0.0, 2.0 * M_PI);
  const double magnitude = Uniform(rng, 0.05, 0.20);
  p.lateral_ = {magnitude * std::cos(angle), magnitude * std::sin(angle)};
  p.lever_m_ = Uniform(rng, 0.025, 0.035);
  return p;
}

Wrench ForceProfile::At(double tau_s) const {
  Wrench w;
  if (tau_s <= 0.0) return w;
  double fz = 0.0;
  if (category_ == HapticCategory::kSoft) {
    // A slow, low, saturating rise.
    fz = std::min(slope_n_per_s_ * tau_s,
                  peak_n_ * (1.0 - std::exp(-tau_s / rise_s_)) +
                      0.5 * slope_n_per_s_ * tau_s);
  } else {
    fz = peak_n_ * (1.0 - std::exp(-tau_s / rise_s_));
    if (tau_s > break_s_) {
      // The skin or flesh gives way: a fast drop of `drop_` of the force.
      fz *= 1.0 - drop_ * (1.0 - std::exp(-(tau_s - break_s_) / drop_s_));
    }
  }
  w.force_n = {lateral_[0] * fz, lateral_[1] * fz, fz};
  // Torque from the force at the tines, `lever_m_` below the sensor:
  // tau = r x F with r = (0, 0, -lever).
  w.torque_nm = {lever_m_ * w.force_n[1], -lever_m_ * w.force_n[0], 0.0};
  return w;
}

Wrench Measure(const ForceProfile& profile, double tau_s,
               const SensorNoise& noise, const Wrench& bias,
               std::mt19937_64& rng) {
  std::normal_distribution<double> normal(0.0, 1.0);
  Wrench w = profile.At(tau_s);
  for (int i = 0; i < 3; ++i) {
    w.force_n[i] += bias.force_n[i] + noise.force_sd_n * normal(rng);
    w.torque_nm[i] += bias.torque_nm[i] + noise.torque_sd_nm * normal(rng);
  }
  return w;
}

std::vector<TimedWrench> SimulateTrace(const ForceProfile& profile,
                                       const TraceOptions& options,
                                       std::mt19937_64& rng) {
  Wrench bias = options.noise.bias;
  if (options.noise.random_bias_n > 0.0) {
    const double b = options.noise.random_bias_n;
    for (int i = 0; i < 3; ++i) {
      bias.force_n[i] += Uniform(rng, -b, b);
      bias.torque_nm[i] += Uniform(rng, -0.02 * b, 0.02 * b);
    }
  }
  const double dt = 1.0 / options.rate_hz;
  const int n =
      static_cast<int>(std::floor(options.duration_s * options.rate_hz));
  std::vector<TimedWrench> trace;
  trace.reserve(n);
  for (int i = 0; i < n; ++i) {
    double t = i * dt;
    if (options.jitter_fraction > 0.0 && i > 0) {
      t += Uniform(rng, -0.5, 0.5) * options.jitter_fraction * dt;
    }
    trace.push_back(
        {t, Measure(profile, t - options.contact_s, options.noise, bias, rng)});
  }
  return trace;
}

}  // namespace bitewise::sim
