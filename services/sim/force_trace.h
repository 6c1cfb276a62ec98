// The simulated world's force-trace model: what the Forque (an ATI Nano25
// on the fork) measures while the fork enters a food item. One model serves
// two consumers, so they never drift apart: HapticNet's trainer draws
// labelled traces from it, and the simulated Net F/T box streams it over UDP
// with the contact time set by the simulated arm's motion.
//
// Each category has its own shape (Fz, the axial force, in newtons; the
// fork pushes down, so the reaction on the sensor is positive):
//  - hard: a steep rise to a high force that the fork cannot get through;
//  - hard-skin: a rise to a peak, then a sharp drop when the skin breaks;
//  - medium: a moderate rise, then a smaller drop at the puncture;
//  - soft: a slow, low rise.
// Every item draws its own parameters (food-to-food variation), and the
// sensor adds white noise and a constant bias.
#ifndef BITEWISE_SERVICES_SIM_FORCE_TRACE_H_
#define BITEWISE_SERVICES_SIM_FORCE_TRACE_H_

#include <array>
#include <random>
#include <vector>

#include "services/domain/wrench.h"
#include "services/sim/food_catalog.h"

namespace bitewise::sim {

using Wrench = domain::Wrench;
// A trace's sample: t_s seconds from the start of the trace.
using TimedWrench = domain::TimedWrench;

// One item's noise-free response to the fork, as a function of the time
// since first contact. Cheap to copy; deterministic once sampled.
class ForceProfile {
 public:
  // Draws an item of `category` with the model's food-to-food variation.
  static ForceProfile Sample(HapticCategory category, std::mt19937_64& rng);

  HapticCategory category() const { return category_; }
  // The wrench `tau_s` seconds after first contact; zero before it.
  Wrench At(double tau_s) const;
  // The largest axial force of the profile (N), for force-limit checks.
  double PeakForce() const { return peak_n_; }

 private:
  HapticCategory category_ = HapticCategory::kSoft;
  double peak_n_ = 0.0;         // force scale
  double rise_s_ = 0.01;        // time constant of the rise
  double break_s_ = 1e9;        // skin break / puncture time
  double drop_ = 0.0;           // fraction of force lost at the break
  double drop_s_ = 0.004;       // how fast the force drops
  double slope_n_per_s_ = 0.0;  // soft foods: linear rise
  std::array<double, 2> lateral_{0.0, 0.0};  // Fx, Fy as fractions of Fz
  double lever_m_ = 0.03;  // tine tip to sensor: torque = lever x force
};

struct SensorNoise {
  double force_sd_n = 0.08;     // white noise per force channel
  double torque_sd_nm = 0.004;  // white noise per torque channel
  // Constant offset of every channel (not tared); drawn per trace when
  // random_bias_n > 0: forces uniform in +-random_bias_n, torques
  // +-random_bias_n * 0.02 m.
  Wrench bias;
  double random_bias_n = 0.5;
};

// One item's departure from the profile it was drawn from, for training
// data that must cover more than the world model's own variation (HapticNet's
// trainer draws one per trace; the simulated world never varies). The
// identity by default.
//  - amplitude: the whole wrench scaled (a stiffer or weaker item);
//  - time_scale: the profile's time axis stretched (a faster or slower fork,
//    another size);
//  - drop_time_scale: after the profile's force peak (the skin break or
//    puncture; for items that only rise, the end of the first 100 ms), time
//    stretched again, so a puncture may be as fast as a skin break;
//  - lateral_scale: Fx, Fy and the torques they cause scaled;
//  - twist_m: a twist Tz = twist_m * Fz;
//  - touch_n, touch_s: a gentle touch before the fork bites: Fz ramps
//    linearly to touch_n over touch_s before the profile starts and stays.
struct TraceVariation {
  double amplitude = 1.0;
  double time_scale = 1.0;
  double drop_time_scale = 1.0;
  double lateral_scale = 1.0;
  double twist_m = 0.0;
  double touch_n = 0.0;
  double touch_s = 0.0;

  bool IsIdentity() const;
};

// The robot's force limit acting on the trace, as the acquisition does it
// (services/robot/robot.cc): the limit is checked once per control period
// on the largest force magnitude since the last check; at the first check
// that finds it reached, the arm halts where it is (the fork's depth, and so
// the item's force, holds), the extraction starts one period later, and the
// tines unload linearly as the fork pulls back release_m (sim::ItemContact)
// at the extraction speed. Defaults: AcquisitionConfig's 100 Hz control and
// 0.08 m/s extraction, ContactModelOptions' 0.5 mm release.
struct ForceLimitStop {
  // The action's force limit (N): 10 for TA0/TA90, 20 for TV, 25 for VS
  // (domain/skewering_actions.h). 0: no limit, the fork goes on.
  double limit_n = 0.0;
  double control_period_s = 0.01;
  double lift_delay_s = 0.01;
  double unload_s = 0.0005 / 0.08;
};

struct TraceOptions {
  double rate_hz = 1000.0;       // 100 Hz to 7 kHz
  double contact_s = 0.3;        // first contact, from the start of the trace
  double duration_s = 0.6;       // whole trace
  double jitter_fraction = 0.0;  // timestamp jitter as a fraction of 1/rate
  SensorNoise noise;
  TraceVariation variation;
  // With a limit, the check's phase against contact is drawn uniformly over
  // one control period (one more draw from the trace's generator).
  ForceLimitStop stop;
};

// The wrench that the sensor reports at time `tau_s` after contact: the
// profile plus noise and `bias`.
Wrench Measure(const ForceProfile& profile, double tau_s,
               const SensorNoise& noise, const Wrench& bias,
               std::mt19937_64& rng);

// A whole trace sampled at `options.rate_hz`, contact at
// `options.contact_s`, with noise and a bias (fixed or random), of the
// profile varied by `options.variation`. With the identity variation every
// sample is Measure()'s, as the simulated Net F/T box streams.
// `force_limit_reached` (may be null) tells whether options.stop's limit
// halted the fork.
std::vector<TimedWrench> SimulateTrace(const ForceProfile& profile,
                                       const TraceOptions& options,
                                       std::mt19937_64& rng,
                                       bool* force_limit_reached = nullptr);

}  // namespace bitewise::sim

#endif  // BITEWISE_SERVICES_SIM_FORCE_TRACE_H_
