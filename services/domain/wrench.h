// A wrench: force (N) and torque (N·m) in the F/T sensor's frame. Defined
// once here for the Net F/T driver, the robot and the simulated world.
#ifndef BITEWISE_SERVICES_DOMAIN_WRENCH_H_
#define BITEWISE_SERVICES_DOMAIN_WRENCH_H_

#include <array>

namespace bitewise::domain {

struct Wrench {
  std::array<double, 3> force_n{0.0, 0.0, 0.0};
  std::array<double, 3> torque_nm{0.0, 0.0, 0.0};
};

}  // namespace bitewise::domain

#endif  // BITEWISE_SERVICES_DOMAIN_WRENCH_H_
