#include "services/sim/food_catalog.h"

namespace bitewise::sim {

const std::vector<FoodType>& FoodCatalog() {
  using C = HapticCategory;
  // Actions:                 VS0   VS90  TV0   TV90  TA0   TA90
  static const auto* const kFoods = new std::vector<FoodType>{
      {"carrot",
       C::kHard,
       {0.55, 0.90, 0.40, 0.50, 0.10, 0.10},
       {0.93, 0.45, 0.10},
       0.05,
       {0.040, 0.060},
       {0.012, 0.018},
       {0.010, 0.015},
       true},
      {"celery",
       C::kHard,
       {0.55, 0.85, 0.40, 0.45, 0.10, 0.10},
       {0.55, 0.78, 0.35},
       0.06,
       {0.040, 0.060},
       {0.010, 0.015},
       {0.008, 0.012},
       true},
      {"strawberry",
       C::kMedium,
       {0.90, 0.70, 0.90, 0.70, 0.45, 0.40},
       {0.85, 0.12, 0.15},
       0.06,
       {0.025, 0.040},
       {0.020, 0.030},
       {0.020, 0.030},
       true},
      {"cantaloupe",
       C::kMedium,
       {0.85, 0.70, 0.85, 0.65, 0.50, 0.45},
       {0.98, 0.62, 0.30},
       0.05,
       {0.025, 0.040},
       {0.020, 0.030},
       {0.015, 0.025},
       true},
      {"banana",
       C::kSoft,
       {0.30, 0.30, 0.40, 0.35, 0.90, 0.90},
       {0.96, 0.90, 0.62},
       0.04,
       {0.020, 0.030},
       {0.020, 0.030},
       {0.010, 0.016},
       true},
      {"kiwi",
       C::kSoft,
       {0.35, 0.35, 0.45, 0.40, 0.85, 0.85},
       {0.55, 0.70, 0.20},
       0.05,
       {0.020, 0.030},
       {0.020, 0.030},
       {0.010, 0.016},
       true},
      {"cherry_tomato",
       C::kHardSkin,
       {0.35, 0.45, 0.60, 0.90, 0.15, 0.15},
       {0.90, 0.15, 0.10},
       0.05,
       {0.020, 0.028},
       {0.020, 0.028},
       {0.020, 0.026},
       true},
      {"grape",
       C::kHardSkin,
       {0.35, 0.45, 0.60, 0.90, 0.15, 0.15},
       {0.55, 0.75, 0.25},
       0.06,
       {0.018, 0.025},
       {0.015, 0.020},
       {0.015, 0.020},
       true},
      // Seen foods and look-alikes. An unripe banana looks like a ripe one
      // but is firm: vision alone cannot tell them apart.
      {"banana_unripe",
       C::kMedium,
       {0.80, 0.65, 0.85, 0.65, 0.40, 0.40},
       {0.94, 0.90, 0.58},
       0.04,
       {0.020, 0.030},
       {0.020, 0.030},
       {0.010, 0.016},
       false},
      {"apple",
       C::kHard,
       {0.60, 0.85, 0.45, 0.55, 0.10, 0.10},
       {0.95, 0.92, 0.75},
       0.04,
       {0.030, 0.045},
       {0.015, 0.025},
       {0.012, 0.018},
       false},
      {"blueberry",
       C::kHardSkin,
       {0.30, 0.35, 0.55, 0.85, 0.15, 0.15},
       {0.25, 0.30, 0.55},
       0.05,
       {0.010, 0.014},
       {0.010, 0.014},
       {0.010, 0.013},
       false},
      {"honeydew",
       C::kMedium,
       {0.85, 0.70, 0.85, 0.70, 0.45, 0.45},
       {0.75, 0.88, 0.55},
       0.04,
       {0.025, 0.040},
       {0.020, 0.030},
       {0.015, 0.025},
       false},
      {"egg",
       C::kSoft,
       {0.35, 0.30, 0.40, 0.35, 0.85, 0.85},
       {0.97, 0.95, 0.85},
       0.03,
       {0.030, 0.040},
       {0.020, 0.030},
       {0.012, 0.018},
       false},
      // More seen foods, one or more per category, so that statistics and
      // models built on seen foods see every category more than once.
      {"cucumber",
       C::kHard,
       {0.55, 0.85, 0.40, 0.50, 0.10, 0.10},
       {0.70, 0.85, 0.55},
       0.05,
       {0.025, 0.040},
       {0.015, 0.025},
       {0.010, 0.015},
       false},
      {"pear",
       C::kMedium,
       {0.85, 0.70, 0.85, 0.65, 0.45, 0.40},
       {0.93, 0.90, 0.70},
       0.04,
       {0.025, 0.040},
       {0.020, 0.030},
       {0.015, 0.025},
       false},
      {"mango",
       C::kSoft,
       {0.35, 0.30, 0.45, 0.40, 0.85, 0.85},
       {0.98, 0.68, 0.18},
       0.05,
       {0.020, 0.035},
       {0.020, 0.030},
       {0.010, 0.018},
       false},
      {"olive",
       C::kHardSkin,
       {0.35, 0.45, 0.60, 0.85, 0.15, 0.15},
       {0.30, 0.35, 0.12},
       0.05,
       {0.018, 0.025},
       {0.014, 0.018},
       {0.014, 0.018},
       false},
  };
  return *kFoods;
}

std::vector<const FoodType*> UnseenFoods() {
  std::vector<const FoodType*> out;
  for (const FoodType& food : FoodCatalog()) {
    if (food.unseen) out.push_back(&food);
  }
  return out;
}

std::vector<const FoodType*> SeenFoods() {
  std::vector<const FoodType*> out;
  for (const FoodType& food : FoodCatalog()) {
    if (!food.unseen) out.push_back(&food);
  }
  return out;
}

const FoodType* FindFood(const std::string& name) {
  for (const FoodType& food : FoodCatalog()) {
    if (food.name == name) return &food;
  }
  return nullptr;
}

}  // namespace bitewise::sim
