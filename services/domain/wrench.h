// A wrench: force (N) and torque (N·m) in the F/T sensor's frame, and a timed
// wrench, one sample of a force/torque trace. Defined once here for the Net
// F/T driver, the robot's recorder, the simulated world and the haptic
// pipeline, so a trace passes between them without conversion. The channel
// helpers below serve code that works channel by channel.
#ifndef BITEWISE_SERVICES_DOMAIN_WRENCH_H_
#define BITEWISE_SERVICES_DOMAIN_WRENCH_H_

#include <array>

namespace bitewise::domain {

struct Wrench {
  std::array<double, 3> force_n{0.0, 0.0, 0.0};
  std::array<double, 3> torque_nm{0.0, 0.0, 0.0};
};

// One sample of a force/torque trace.
struct TimedWrench {
  double t_s = 0.0;  // seconds since the trace (the acquisition) began
  Wrench wrench;
};

// A wrench's six channels, in the order HapticNet reads them and the trace
// CSV (trace_csv.h) writes them: fx, fy, fz (N), tx, ty, tz (N·m).
inline constexpr int kWrenchChannels = 6;

// Channel `k` (0..5: fx, fy, fz, tx, ty, tz) of `w`.
inline double Channel(const Wrench& w, int k) {
  return k < 3 ? w.force_n[k] : w.torque_nm[k - 3];
}
inline double& Channel(Wrench& w, int k) {
  return k < 3 ? w.force_n[k] : w.torque_nm[k - 3];
}

// All six channels of `w`, in channel order.
inline std::array<double, kWrenchChannels> Channels(const Wrench& w) {
  return {w.force_n[0],   w.force_n[1],   w.force_n[2],
          w.torque_nm[0], w.torque_nm[1], w.torque_nm[2]};
}

// The wrench whose channels are `channels` (the inverse of Channels()).
inline Wrench WrenchFromChannels(
    const std::array<double, kWrenchChannels>& channels) {
  return {{channels[0], channels[1], channels[2]},
          {channels[3], channels[4], channels[5]}};
}

}  // namespace bitewise::domain

#endif  // BITEWISE_SERVICES_DOMAIN_WRENCH_H_
