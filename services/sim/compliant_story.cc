// The compliant-arm story (trace_stories.h): the fork is driven through the
// arm's compliance, the tip has mass, and the food answers the tip's depth
// and speed with layered continuum mechanics. Written from its own physical
// account, sharing no code or shapes with the force-trace model or the
// other stories:
//
//  - The arm: the controller commands a descent at 3-8 cm/s, but the wrist
//    and the fork holder form a spring of 2-8 kN/m (the JACO2's joints under
//    load) with damping ratio 0.2-0.6 around an effective tip mass of
//    0.08-0.3 kg. So the tip lags the command while the food resists, and
//    when the food yields the stored spring energy throws the tip forward:
//    drops are as fast as the tip can move, and ring at the arm's own
//    frequency (15-50 Hz). The command stops at the skewering depth
//    (8-15 mm) or when the spring carries the force limit (15-30 N).
//  - The food (per category; depth d of the tip below the surface, speed u):
//    * hard: a flat punch into a stiff solid, F = k d (3-10 N/mm), until a
//      crack starts at 10-25 N; the crack's cohesive zone gives way over
//      0.05-0.2 mm of further travel, down to the cutting force (75-95 % of
//      the initiation force, varying +-8 % with depth over 0.2-0.6 mm, the
//      tissue's grain) plus the shaft's friction 0.2-0.6 N/mm;
//    * hard-skin: a membrane, F = F_p (d / d_p)^2, bursting at 3-8 N after
//      d_p = 1-3 mm, giving way over 0.05-0.15 mm; under it soft flesh that
//      resists with a yield force of 0.3-1.5 N reached over 1-2 mm plus
//      viscosity 2-8 N s/m;
//    * medium: a cellular solid, F = k d until its cells collapse at 2-6 N
//      after 0.8-2.5 mm (a tine punctures a strawberry within a few
//      millimetres), losing 15-40 % over 0.2-0.6 mm, then a crushing
//      plateau that hardens by 0.1-0.4 N/mm;
//    * soft: a viscoplastic paste, F = s d + c u (0.2-0.6 N/mm and
//      8-25 N s/m, the viscous part growing with the wetted tine over the
//      first 0.5-1.5 mm), with no failure at all.
//  - The sensor (another F/T cell than the Nano25): the reaction acts along
//    the tines, tilted 0-20 degrees from the sensor's z axis in any
//    direction, 25-45 mm below it, off centre by up to 3 mm; its electronics
//    a critically damped second-order low-pass at 20-45 % of the sample rate;
//    the host samples at 250 Hz-4 kHz (log-uniform) and stamps each record on
//    arrival, up to 5 % of a period late; untared offset up to 2 N
//    (0.04 N m), thermal drift up to 0.5 N/s; coloured noise (a first-order
//    autoregression, correlation time 1-10 ms, 0.02-0.1 N) over white noise
//    (0.01-0.05 N).
// The mechanics run on a 20 kHz grid (semi-implicit Euler), fine for the
// fastest ringing (50 Hz) and cohesive release (a few tenths of a
// millisecond) at the fastest sample rate.
#include <algorithm>
#include <array>
#include <cmath>

#include "services/domain/random.h"
#include "services/domain/wrench.h"
#include "services/sim/trace_stories.h"

namespace bitewise::sim {
namespace {

using random::LogUniform;
using random::Uniform;

constexpr double kGridS = 1.0 / 20000.0;

// The food's resistance to the tip: a function of depth and speed, with the
// failure state it has reached (a crack or burst never heals).
class LayeredFood {
 public:
  LayeredFood(HapticCategory category, std::mt19937_64& rng)
      : category_(category) {
    switch (category) {
      case HapticCategory::kHard:
        stiffness_ = Uniform(rng, 3000.0, 10000.0);
        failure_n_ = Uniform(rng, 10.0, 25.0);
        release_m_ = Uniform(rng, 0.05e-3, 0.2e-3);
        residual_ = Uniform(rng, 0.75, 0.95);
        grain_m_ = Uniform(rng, 0.2e-3, 0.6e-3);
        grain_phase_ = Uniform(rng, 0.0, 2.0 * M_PI);
        friction_n_per_m_ = Uniform(rng, 200.0, 600.0);
        break;
      case HapticCategory::kHardSkin:
        failure_n_ = Uniform(rng, 3.0, 8.0);
        burst_depth_m_ = Uniform(rng, 1e-3, 3e-3);
        release_m_ = Uniform(rng, 0.05e-3, 0.15e-3);
        flesh_yield_n_ = Uniform(rng, 0.3, 1.5);
        flesh_depth_m_ = Uniform(rng, 1e-3, 2e-3);
        viscosity_ = Uniform(rng, 2.0, 8.0);
        break;
      case HapticCategory::kMedium:
        failure_n_ = Uniform(rng, 2.0, 6.0);
        stiffness_ = failure_n_ / Uniform(rng, 0.8e-3, 2.5e-3);
        residual_ = 1.0 - Uniform(rng, 0.15, 0.40);
        release_m_ = Uniform(rng, 0.2e-3, 0.6e-3);
        hardening_n_per_m_ = Uniform(rng, 100.0, 400.0);
        break;
      case HapticCategory::kSoft:
        stiffness_ = Uniform(rng, 200.0, 600.0);
        viscosity_ = Uniform(rng, 8.0, 25.0);
        wetting_m_ = Uniform(rng, 0.5e-3, 1.5e-3);
        break;
    }
  }

  // The force (N) on the tip at depth `d` (m, > 0 in the food) moving at
  // `u` (m/s, > 0 downwards). Call in time order: it records failure.
  double Force(double d, double u) {
    if (d <= 0.0) return 0.0;
    switch (category_) {
      case HapticCategory::kHard: {
        if (!failed_ && stiffness_ * d >= failure_n_) {
          failed_ = true;
          failure_depth_m_ = d;
        }
        if (!failed_) return stiffness_ * d;
        const double beyond = d - failure_depth_m_;
        const double cutting =
            residual_ * failure_n_ *
                (1.0 + 0.08 * std::sin(2.0 * M_PI * beyond / grain_m_ +
                                       grain_phase_)) +
            friction_n_per_m_ * beyond;
        return Release(beyond, failure_n_, cutting);
      }
      case HapticCategory::kHardSkin: {
        if (!failed_ && d >= burst_depth_m_) {
          failed_ = true;
          failure_depth_m_ = d;
        }
        if (!failed_) {
          const double x = d / burst_depth_m_;
          return failure_n_ * x * x;
        }
        const double beyond = d - failure_depth_m_;
        const double flesh =
            flesh_yield_n_ * (1.0 - std::exp(-beyond / flesh_depth_m_)) +
            viscosity_ * std::max(0.0, u);
        return Release(beyond, failure_n_, flesh);
      }
      case HapticCategory::kMedium: {
        if (!failed_ && stiffness_ * d >= failure_n_) {
          failed_ = true;
          failure_depth_m_ = d;
        }
        if (!failed_) return stiffness_ * d;
        const double beyond = d - failure_depth_m_;
        const double crushing =
            residual_ * failure_n_ + hardening_n_per_m_ * beyond;
        return Release(beyond, failure_n_, crushing);
      }
      case HapticCategory::kSoft:
        return stiffness_ * d +
               viscosity_ * std::max(0.0, u) * std::min(1.0, d / wetting_m_);
    }
    return 0.0;
  }

 private:
  // A cohesive zone: from the failure force to `after` over release_m_ of
  // travel, linearly in the opening.
  double Release(double beyond, double at_failure, double after) const {
    if (beyond >= release_m_) return after;
    const double w = beyond / release_m_;
    return (1.0 - w) * at_failure + w * after;
  }

  HapticCategory category_;
  double stiffness_ = 0.0, failure_n_ = 0.0, release_m_ = 1e-4;
  double residual_ = 1.0, grain_m_ = 1e-3, grain_phase_ = 0.0;
  double friction_n_per_m_ = 0.0, burst_depth_m_ = 1e-3;
  double flesh_yield_n_ = 0.0, flesh_depth_m_ = 1e-3, viscosity_ = 0.0;
  double hardening_n_per_m_ = 0.0, wetting_m_ = 1e-3;
  bool failed_ = false;
  double failure_depth_m_ = 0.0;
};

}  // namespace

std::vector<TimedWrench> CompliantStoryTrace(HapticCategory category,
                                             std::mt19937_64& rng) {
  LayeredFood food(category, rng);
  // The arm.
  const double speed = Uniform(rng, 0.03, 0.08);
  const double spring = Uniform(rng, 2000.0, 8000.0);
  const double mass = Uniform(rng, 0.08, 0.3);
  const double damping =
      2.0 * Uniform(rng, 0.2, 0.6) * std::sqrt(spring * mass);
  const double stop_depth = Uniform(rng, 0.008, 0.015);
  const double force_limit = Uniform(rng, 15.0, 30.0);
  // The sensor's geometry.
  const double tilt = Uniform(rng, 0.0, 20.0) * M_PI / 180.0;
  const double azimuth = Uniform(rng, 0.0, 2.0 * M_PI);
  const std::array<double, 3> axis = {std::sin(tilt) * std::cos(azimuth),
                                      std::sin(tilt) * std::sin(azimuth),
                                      std::cos(tilt)};
  const double lever = Uniform(rng, 0.025, 0.045);
  const std::array<double, 3> tip = {
      -lever * axis[0] + Uniform(rng, -0.003, 0.003),
      -lever * axis[1] + Uniform(rng, -0.003, 0.003), -lever * axis[2]};
  // Its electronics and the host.
  const double rate = LogUniform(rng, 250.0, 4000.0);
  const double cutoff_hz = Uniform(rng, 0.2, 0.45) * rate;
  const double omega = 2.0 * M_PI * cutoff_hz;
  std::array<double, 6> offset, drift;
  for (int c = 0; c < 6; ++c) {
    const double scale = c < 3 ? 1.0 : 0.02;
    offset[c] = Uniform(rng, -2.0, 2.0) * scale;
    drift[c] = Uniform(rng, -0.5, 0.5) * scale;
  }
  const double correlation_s = LogUniform(rng, 1e-3, 10e-3);
  const double coloured_sd = Uniform(rng, 0.02, 0.1);
  const double white_sd = Uniform(rng, 0.01, 0.05);
  const double contact = Uniform(rng, 0.1, 0.3);
  const double duration = contact + 0.25;

  // The mechanics on the grid: tip and command descend together while
  // nothing resists and reach the surface at `contact`.
  const int steps = static_cast<int>(std::ceil(duration / kGridS)) + 2;
  std::vector<double> axial(steps, 0.0);
  double command = -speed * contact;  // depth of the command
  double depth = command, velocity = speed;
  bool holding = false;
  // The electronics' two-pole filter state (position and rate).
  double filtered = 0.0, filtered_rate = 0.0;
  for (int i = 0; i < steps; ++i) {
    const double spring_force = spring * (command - depth);
    holding = holding || command >= stop_depth || spring_force >= force_limit;
    const double command_speed = holding ? 0.0 : speed;
    command += command_speed * kGridS;
    const double resistance = food.Force(depth, velocity);
    const double acceleration =
        (spring_force + damping * (command_speed - velocity) - resistance) /
        mass;
    velocity += acceleration * kGridS;
    depth += velocity * kGridS;
    // The sensor sits between the spring and the fork: it carries the
    // food's reaction (the fork's own mass below it is neglected).
    const double input = resistance;
    const double filtered_acceleration =
        omega * omega * (input - filtered) - 2.0 * omega * filtered_rate;
    filtered_rate += filtered_acceleration * kGridS;
    filtered += filtered_rate * kGridS;
    axial[i] = filtered;
  }

  random::Normal normal;
  const int n = static_cast<int>(duration * rate);
  const double keep = std::exp(-1.0 / (rate * correlation_s));
  const double innovation = coloured_sd * std::sqrt(1.0 - keep * keep);
  std::array<double, 6> coloured{};
  for (int c = 0; c < 6; ++c) {
    coloured[c] = coloured_sd * normal(rng) * (c < 3 ? 1.0 : 0.02);
  }
  std::vector<TimedWrench> trace;
  trace.reserve(n);
  for (int j = 0; j < n; ++j) {
    const double t = j / rate;
    const double f = axial[std::min(steps - 1, static_cast<int>(t / kGridS))];
    std::array<double, 3> force = {f * axis[0], f * axis[1], f * axis[2]};
    // The reaction pushes up the fork, at the tip: torque = tip x force.
    std::array<double, 3> torque = {tip[1] * force[2] - tip[2] * force[1],
                                    tip[2] * force[0] - tip[0] * force[2],
                                    tip[0] * force[1] - tip[1] * force[0]};
    TimedWrench sample;
    sample.t_s = t + Uniform(rng, 0.0, 0.05) / rate;
    for (int c = 0; c < 6; ++c) {
      const double scale = c < 3 ? 1.0 : 0.02;
      coloured[c] = keep * coloured[c] + innovation * scale * normal(rng);
      const double value = (c < 3 ? force[c] : torque[c - 3]) + offset[c] +
                           drift[c] * t + coloured[c] +
                           white_sd * scale * normal(rng);
      domain::Channel(sample.wrench, c) = value;
    }
    trace.push_back(sample);
  }
  return trace;
}

}  // namespace bitewise::sim
