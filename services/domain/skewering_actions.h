// The six skewering actions of the paper (Gordon et al. 2021; the table in
// docs/robot.md): fork pitch from vertical, roll relative to the item's
// major axis, and the largest force the skewer may apply. Defined once here;
// the bandit's default action names, the robot's motions and the simulated
// world's success tables all index this list.
#ifndef BITEWISE_SERVICES_DOMAIN_SKEWERING_ACTIONS_H_
#define BITEWISE_SERVICES_DOMAIN_SKEWERING_ACTIONS_H_

#include <array>

namespace bitewise::domain {

struct SkeweringAction {
  const char* name;
  double pitch_rad;
  double roll_rad;
  double max_force_n;
};

inline constexpr int kNumActions = 6;
inline constexpr double kQuarterTurnRad = 1.57079632679489661923;

// VS0, VS90 (vertical skewer), TV0, TV90 (tines vertical), TA0, TA90 (tilted
// angled), in this index order everywhere.
inline constexpr std::array<SkeweringAction, kNumActions> kSkeweringActions = {
    {{"VS0", 0.0, 0.0, 25.0},
     {"VS90", 0.0, kQuarterTurnRad, 25.0},
     {"TV0", -0.5, 0.0, 20.0},
     {"TV90", -0.5, kQuarterTurnRad, 20.0},
     {"TA0", 0.4, 0.0, 10.0},
     {"TA90", 0.4, kQuarterTurnRad, 10.0}}};

}  // namespace bitewise::domain

#endif  // BITEWISE_SERVICES_DOMAIN_SKEWERING_ACTIONS_H_
