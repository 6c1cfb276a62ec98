// The simulated world's foods (services/sim/food_catalog.h): the paper's
// eight unseen foods in its order, nine seen ones apart from them, the
// paper's known best actions best in the success tables, and every number
// in its physical range.
#include "services/sim/food_catalog.h"

#include <algorithm>
#include <set>
#include <string>
#include <vector>

#include "gtest/gtest.h"

namespace bitewise::sim {
namespace {

int BestAction(const FoodType& food) {
  return static_cast<int>(
      std::max_element(food.success.begin(), food.success.end()) -
      food.success.begin());
}

TEST(FoodCatalogTest, UnseenAndSeenFoodsAreThePapersAndApart) {
  std::vector<std::string> unseen;
  for (const FoodType* f : UnseenFoods()) unseen.push_back(f->name);
  EXPECT_EQ(unseen, (std::vector<std::string>{"carrot", "celery", "strawberry",
                                              "cantaloupe", "banana", "kiwi",
                                              "cherry_tomato", "grape"}));
  const std::vector<const FoodType*> seen = SeenFoods();
  EXPECT_EQ(seen.size(), 9u);
  std::set<std::string> names;
  for (const FoodType& f : FoodCatalog()) {
    EXPECT_TRUE(names.insert(f.name).second) << "twice: " << f.name;
    EXPECT_EQ(FindFood(f.name), &f);
  }
  for (const FoodType* f : seen) {
    EXPECT_FALSE(f->unseen) << f->name;
    EXPECT_EQ(std::count(unseen.begin(), unseen.end(), f->name), 0);
  }
  EXPECT_EQ(names.size(), unseen.size() + seen.size());
  EXPECT_EQ(FindFood("pizza"), nullptr);
}

// The optima the paper reports (docs/robot.md): grape TV90; strawberry VS0
// or TV0; banana TA0 or TA90; carrot VS90.
TEST(FoodCatalogTest, ThePapersKnownOptimaAreBest) {
  EXPECT_EQ(BestAction(*FindFood("grape")), 3);  // TV90
  const int strawberry = BestAction(*FindFood("strawberry"));
  EXPECT_TRUE(strawberry == 0 || strawberry == 2) << strawberry;
  const int banana = BestAction(*FindFood("banana"));
  EXPECT_TRUE(banana == 4 || banana == 5) << banana;
  EXPECT_EQ(BestAction(*FindFood("carrot")), 1);  // VS90
}

TEST(FoodCatalogTest, EveryNumberInItsPhysicalRange) {
  for (const FoodType& f : FoodCatalog()) {
    SCOPED_TRACE(f.name);
    for (double p : f.success) {
      EXPECT_GE(p, 0.0);
      EXPECT_LE(p, 1.0);
    }
    for (double c : f.rgb) {
      EXPECT_GE(c, 0.0);
      EXPECT_LE(c, 1.0);
    }
    EXPECT_GE(f.rgb_spread, 0.0);
    for (const auto& range : {f.length_m, f.width_m, f.height_m}) {
      EXPECT_GT(range[0], 0.0);
      EXPECT_LE(range[0], range[1]);
      EXPECT_LT(range[1], 0.15);  // a bite-sized piece on a plate
    }
    EXPECT_GE(f.length_m[1], f.width_m[0]);  // the major axis is major
    const int category = static_cast<int>(f.category);
    EXPECT_GE(category, 0);
    EXPECT_LT(category, kHapticCategories);
  }
}

}  // namespace
}  // namespace bitewise::sim
