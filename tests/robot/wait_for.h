// Polling for the robot tests, which wait on UDP streams and arm threads:
// one loop on the robot side's steady clock instead of one per test file.
#ifndef BITEWISE_TESTS_ROBOT_WAIT_FOR_H_
#define BITEWISE_TESTS_ROBOT_WAIT_FOR_H_

#include <chrono>
#include <functional>
#include <thread>

#include "services/domain/steady_time.h"

namespace bitewise::testing {

// Polls `done` every 2 ms until it holds or `timeout_s` seconds pass (the
// default is generous: the machine may be loaded). Returns `done()`'s last
// value, checked once more at the deadline.
inline bool WaitFor(const std::function<bool()>& done,
                    double timeout_s = 30.0) {
  const double deadline = SteadyNowS() + timeout_s;
  while (SteadyNowS() < deadline) {
    if (done()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  return done();
}

}  // namespace bitewise::testing

#endif  // BITEWISE_TESTS_ROBOT_WAIT_FOR_H_
