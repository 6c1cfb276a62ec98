#include "services/sim/force_trace.h"

#include <algorithm>
#include <cmath>

#include "services/domain/random.h"

namespace bitewise::sim {
namespace {

using random::Uniform;

// The profile's axial force peak in its first 100 ms (0.1 ms steps): the
// skin break or puncture; for items that only rise, the end.
double PeakTime(const ForceProfile& profile) {
  double peak_s = 0.0, peak_n = -1.0;
  for (int i = 1; i <= 1000; ++i) {
    const double fz = profile.At(i * 1e-4).force_n[2];
    if (fz > peak_n) {
      peak_n = fz;
      peak_s = i * 1e-4;
    }
  }
  return peak_s;
}

// The noise-free wrench of `profile` varied by `v`, `tau_s` after contact;
// `peak_s` is PeakTime(profile).
Wrench VariedAt(const ForceProfile& profile, const TraceVariation& v,
                double peak_s, double tau_s) {
  double profile_tau = tau_s / v.time_scale;
  if (profile_tau > peak_s) {
    profile_tau = peak_s + (profile_tau - peak_s) / v.drop_time_scale;
  }
  const Wrench w = profile.At(profile_tau);
  double touch = 0.0;
  if (tau_s > 0.0) {
    touch = v.touch_n;
  } else if (v.touch_s > 0.0 && tau_s > -v.touch_s) {
    touch = v.touch_n * (tau_s + v.touch_s) / v.touch_s;
  }
  const double fz = v.amplitude * w.force_n[2] + touch;
  const double lateral = v.amplitude * v.lateral_scale;
  Wrench out;
  out.force_n = {lateral * w.force_n[0], lateral * w.force_n[1], fz};
  out.torque_nm = {lateral * w.torque_nm[0], lateral * w.torque_nm[1],
                   v.twist_m * fz};
  return out;
}

// `w` as the sensor reports it: plus `bias` and white noise.
Wrench AddSensorNoise(Wrench w, const SensorNoise& noise, const Wrench& bias,
                      std::mt19937_64& rng) {
  random::Normal normal;
  for (int i = 0; i < 3; ++i) {
    w.force_n[i] += bias.force_n[i] + noise.force_sd_n * normal(rng);
    w.torque_nm[i] += bias.torque_nm[i] + noise.torque_sd_nm * normal(rng);
  }
  return w;
}

}  // namespace

bool TraceVariation::IsIdentity() const {
  return amplitude == 1.0 && time_scale == 1.0 && drop_time_scale == 1.0 &&
         lateral_scale == 1.0 && twist_m == 0.0 && touch_n == 0.0 &&
         touch_s == 0.0;
}

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
  return AddSensorNoise(profile.At(tau_s), noise, bias, rng);
}

std::vector<TimedWrench> SimulateTrace(const ForceProfile& profile,
                                       const TraceOptions& options,
                                       std::mt19937_64& rng,
                                       bool* force_limit_reached) {
  Wrench bias = options.noise.bias;
  if (options.noise.random_bias_n > 0.0) {
    const double b = options.noise.random_bias_n;
    for (int i = 0; i < 3; ++i) {
      bias.force_n[i] += Uniform(rng, -b, b);
      bias.torque_nm[i] += Uniform(rng, -0.02 * b, 0.02 * b);
    }
  }
  const ForceLimitStop& stop = options.stop;
  const bool limited = stop.limit_n > 0.0;
  // The first force-limit check after contact.
  double next_check_s =
      limited ? options.contact_s + Uniform(rng, 0.0, stop.control_period_s)
              : 0.0;
  double max_force_n = 0.0;
  double halt_s = -1.0;  // when the limit halted the fork; < 0: not yet
  Wrench held;           // the item's wrench at the halt
  const double dt = 1.0 / options.rate_hz;
  const int n =
      static_cast<int>(std::floor(options.duration_s * options.rate_hz));
  const TraceVariation& variation = options.variation;
  const bool varied = !variation.IsIdentity();
  const double peak_s = varied ? PeakTime(profile) : 0.0;
  auto item_at = [&](double tau) {
    return varied ? VariedAt(profile, variation, peak_s, tau) : profile.At(tau);
  };
  std::vector<TimedWrench> trace;
  trace.reserve(n);
  for (int i = 0; i < n; ++i) {
    double t = i * dt;
    if (options.jitter_fraction > 0.0 && i > 0) {
      t += Uniform(rng, -0.5, 0.5) * options.jitter_fraction * dt;
    }
    const double tau = t - options.contact_s;
    if (limited && halt_s < 0.0) {
      // The checks that fell due before this sample, on what came before.
      while (next_check_s <= t && halt_s < 0.0) {
        if (max_force_n >= stop.limit_n) {
          halt_s = next_check_s;
          held = item_at(halt_s - options.contact_s);
        }
        next_check_s += stop.control_period_s;
      }
    }
    Wrench w;
    if (halt_s < 0.0) {
      w = item_at(tau);
      const auto& f = w.force_n;
      max_force_n = std::max(
          max_force_n, std::sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]));
    } else {
      // Halted: the depth holds, then the pull-back unloads the tines.
      const double back_s = t - halt_s - stop.lift_delay_s;
      const double scale =
          back_s <= 0.0 ? 1.0 : std::max(0.0, 1.0 - back_s / stop.unload_s);
      w = held;
      for (int c = 0; c < 3; ++c) {
        w.force_n[c] *= scale;
        w.torque_nm[c] *= scale;
      }
    }
    trace.push_back({t, AddSensorNoise(w, options.noise, bias, rng)});
  }
  if (force_limit_reached != nullptr) *force_limit_reached = halt_s >= 0.0;
  return trace;
}

}  // namespace bitewise::sim
