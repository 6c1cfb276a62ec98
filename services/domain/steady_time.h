// One monotonic time base for everything that has to agree on "when" within
// a process: F/T samples, arm set points, the simulated world's contact
// physics, camera capture times and frame ages. Wall-clock time can jump;
// this cannot.
#ifndef BITEWISE_SERVICES_DOMAIN_STEADY_TIME_H_
#define BITEWISE_SERVICES_DOMAIN_STEADY_TIME_H_

#include <chrono>

namespace bitewise {

// Seconds on std::chrono::steady_clock (arbitrary epoch).
inline double SteadyNowS() {
  return std::chrono::duration<double>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

}  // namespace bitewise

#endif  // BITEWISE_SERVICES_DOMAIN_STEADY_TIME_H_
