// The simulated world's foods: what each type feels like (its haptic
// category), how often each skewering action picks it up, and how it looks.
// Shared by the force-trace model (HapticNet's training data and the
// simulated Net F/T box), the camera renderer and the simulated meals.
//
// The success probabilities are assumptions built on the paper
// (docs/robot.md)'s known optima (grape TV90; strawberry VS0 or TV0; banana TA0
// or TA90; carrot VS90) and on the physical reasoning behind them: hard foods
// need a vertical skewer across the fibres, soft foods need the tilted angled
// scoop, hard-skinned foods need the tines-vertical approach across the
// skin, and medium foods take any vertical skewer. See docs/simulation.md.
#ifndef BITEWISE_SERVICES_SIM_FOOD_CATALOG_H_
#define BITEWISE_SERVICES_SIM_FOOD_CATALOG_H_

#include <array>
#include <string>
#include <string_view>
#include <vector>

#include "absl/status/statusor.h"
#include "services/domain/haptic_class.h"
#include "services/domain/skewering_actions.h"

namespace bitewise::sim {

// A food's haptic category is one of HapticNet's four classes.
using HapticCategory = domain::HapticClass;
inline constexpr int kHapticCategories = domain::kHapticClasses;

// VS0, VS90, TV0, TV90, TA0, TA90 (services/domain/skewering_actions.h).
inline constexpr int kNumActions = domain::kNumActions;

// How often one skewering action, by name, acquires a food.
struct ActionSuccess {
  const char* action;
  double probability;
};

struct FoodType {
  std::string name;
  HapticCategory category;
  // Probability that each action acquires the item, one entry per action of
  // services/domain/skewering_actions.h, by name.
  std::array<ActionSuccess, kNumActions> success;
  // Appearance: mean colour (linear RGB in [0, 1]) and its per-item spread;
  // items vary in size within [min, max] metres and lie at any angle.
  std::array<double, 3> rgb;
  double rgb_spread;
  std::array<double, 2> length_m;  // major axis
  std::array<double, 2> width_m;   // minor axis
  std::array<double, 2> height_m;  // above the plate
  // Part of the paper's unseen-food evaluation set.
  bool unseen;
};

// Every food type, unseen foods first in the paper's order.
const std::vector<FoodType>& FoodCatalog();
// The paper's eight unseen foods: carrot, celery, strawberry, cantaloupe,
// banana, kiwi, cherry_tomato, grape.
std::vector<const FoodType*> UnseenFoods();
// The other foods (nine): what featurizer statistics, HapticNet and any
// model meant for unseen foods are built from, never the unseen ones.
std::vector<const FoodType*> SeenFoods();
// nullptr if no food has this name.
const FoodType* FindFood(const std::string& name);

// The probability that the action named `action` acquires `food`;
// NOT_FOUND naming the food and the action if the catalog has no entry.
absl::StatusOr<double> SuccessProbability(const FoodType& food,
                                          std::string_view action);

}  // namespace bitewise::sim

#endif  // BITEWISE_SERVICES_SIM_FOOD_CATALOG_H_
