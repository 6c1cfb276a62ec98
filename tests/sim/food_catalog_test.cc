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

std::string BestAction(const FoodType& food) {
  return std::max_element(food.success.begin(), food.success.end(),
                          [](const ActionSuccess& a, const ActionSuccess& b) {
                            return a.probability < b.probability;
                          })
      ->action;
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
  EXPECT_EQ(BestAction(*FindFood("grape")), "TV90");
  const std::string strawberry = BestAction(*FindFood("strawberry"));
  EXPECT_TRUE(strawberry == "VS0" || strawberry == "TV0") << strawberry;
  const std::string banana = BestAction(*FindFood("banana"));
  EXPECT_TRUE(banana == "TA0" || banana == "TA90") << banana;
  EXPECT_EQ(BestAction(*FindFood("carrot")), "VS90");
}

// Every food names every skewering action of the domain once, so the
// simulated world finds an action's probability by its name.
TEST(FoodCatalogTest, EveryFoodNamesEveryActionOnce) {
  for (const FoodType& f : FoodCatalog()) {
    SCOPED_TRACE(f.name);
    std::set<std::string> named;
    for (const ActionSuccess& entry : f.success) {
      EXPECT_NE(domain::FindSkeweringAction(entry.action), nullptr)
          << entry.action;
      EXPECT_TRUE(named.insert(entry.action).second)
          << "twice: " << entry.action;
      absl::StatusOr<double> p = SuccessProbability(f, entry.action);
      ASSERT_TRUE(p.ok()) << p.status();
      EXPECT_EQ(*p, entry.probability);
    }
    EXPECT_EQ(named.size(), static_cast<size_t>(domain::kNumActions));
  }
  const absl::Status missing =
      SuccessProbability(*FindFood("grape"), "VS45").status();
  EXPECT_EQ(missing.code(), absl::StatusCode::kNotFound);
  EXPECT_EQ(missing.message(),
            "the simulated food \"grape\" has no success probability for "
            "action \"VS45\"");
}

TEST(FoodCatalogTest, EveryNumberInItsPhysicalRange) {
  for (const FoodType& f : FoodCatalog()) {
    SCOPED_TRACE(f.name);
    for (const ActionSuccess& entry : f.success) {
      EXPECT_GE(entry.probability, 0.0);
      EXPECT_LE(entry.probability, 1.0);
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
