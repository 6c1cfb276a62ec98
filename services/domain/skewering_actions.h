// The six skewering actions of the paper (Gordon et al. 2021; the table in
// docs/robot.md): fork pitch from vertical, roll relative to the item's
// major axis, and the largest force the skewer may apply. Defined once here;
// the bandit's default action names, the robot's motions and the simulated
// world's success tables find their actions in it by name. The position in
// the list is the RobotService's wire number for the action (0..5) and
// nothing else.
#ifndef BITEWISE_SERVICES_DOMAIN_SKEWERING_ACTIONS_H_
#define BITEWISE_SERVICES_DOMAIN_SKEWERING_ACTIONS_H_

#include <array>
#include <string_view>

namespace bitewise::domain {

struct SkeweringAction {
  const char* name;
  double pitch_rad;
  double roll_rad;
  double max_force_n;
  // For people at the table: a short title and what the fork does.
  const char* title;
  const char* description;
};

inline constexpr int kNumActions = 6;
inline constexpr double kQuarterTurnRad = 1.57079632679489661923;

// VS0, VS90 (vertical skewer), TV0, TV90 (tines vertical), TA0, TA90 (tilted
// angled). The order is the RobotService's wire numbering (0..5) and the
// default action list of a new bandit user; everything else finds an action
// by its name.
inline constexpr std::array<SkeweringAction, kNumActions> kSkeweringActions = {
    {{"VS0", 0.0, 0.0, 25.0, "Vertical skewer",
      "The fork comes straight down with its tines along the food's long "
      "side, pushing with up to 25 N."},
     {"VS90", 0.0, kQuarterTurnRad, 25.0, "Vertical skewer, turned",
      "The fork comes straight down with its tines across the food's long "
      "side, pushing with up to 25 N."},
     {"TV0", -0.5, 0.0, 20.0, "Tines vertical",
      "The handle leans back so the tines go in straight, along the food's "
      "long side, pushing with up to 20 N."},
     {"TV90", -0.5, kQuarterTurnRad, 20.0, "Tines vertical, turned",
      "The handle leans back so the tines go in straight, across the food's "
      "long side, pushing with up to 20 N."},
     {"TA0", 0.4, 0.0, 10.0, "Tilted, angled",
      "The fork tilts forward and slides in at an angle along the food's "
      "long side, gently, with up to 10 N, for soft food."},
     {"TA90", 0.4, kQuarterTurnRad, 10.0, "Tilted, angled, turned",
      "The fork tilts forward and slides in at an angle across the food's "
      "long side, gently, with up to 10 N, for soft food."}}};

// The action named `name`, or nullptr if no action has that name.
inline const SkeweringAction* FindSkeweringAction(std::string_view name) {
  for (const SkeweringAction& action : kSkeweringActions) {
    if (name == action.name) return &action;
  }
  return nullptr;
}

}  // namespace bitewise::domain

#endif  // BITEWISE_SERVICES_DOMAIN_SKEWERING_ACTIONS_H_
