// One monotonic time base for everything on the robot side that has to agree
// on "when": F/T samples, arm set points and the simulated world's contact
// physics. Wall-clock time can jump; this cannot.
#ifndef BITEWISE_SERVICES_ROBOT_STEADY_TIME_H_
#define BITEWISE_SERVICES_ROBOT_STEADY_TIME_H_

#include <chrono>

namespace bitewise::robot {

// Seconds on std::chrono::steady_clock (arbitrary epoch).
inline double SteadyNowS() {
  return std::chrono::duration<double>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

}  // namespace bitewise::robot

#endif  // BITEWISE_SERVICES_ROBOT_STEADY_TIME_H_
