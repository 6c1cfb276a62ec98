// Plates and their rendered ground truth: RandomPlate keeps items apart (or
// touching), CrowdedPlate lays slices partly on a neighbour and puts pieces
// of the same food side by side, and the truth says how much of each item
// shows.
#include <algorithm>
#include <random>
#include <vector>

#include "gtest/gtest.h"
#include "services/sim/food_catalog.h"
#include "services/sim/scene.h"

namespace bitewise::sim {
namespace {

std::vector<const FoodType*> Kiwis(int n) {
  return std::vector<const FoodType*>(n, FindFood("kiwi"));
}

TEST(PlateTest, ItemsApartShowTheirWholeFootprint) {
  std::mt19937_64 rng(3);
  const PlateScene scene = RandomPlate(Kiwis(3), /*allow_touching=*/false, rng);
  ASSERT_EQ(scene.items.size(), 3u);
  const RenderedFrame frame = RenderPlate(scene, D415Intrinsics(), 1);
  for (const ItemTruth& t : frame.truth) {
    EXPECT_GT(t.footprint_pixels, 100);
    EXPECT_EQ(t.visible_pixels, t.footprint_pixels);
  }
  for (const SceneItem& item : scene.items) EXPECT_EQ(item.base_m, 0.0);
}

TEST(PlateTest, ASliceLyingOnANeighbourHidesPartOfIt) {
  PlateCrowding crowding;
  crowding.overlap_probability = 1.0;
  int lying = 0, partly_hidden = 0;
  for (uint64_t seed = 1; seed <= 5; ++seed) {
    std::mt19937_64 rng(seed);
    const PlateScene scene = CrowdedPlate(Kiwis(4), crowding, rng);
    const RenderedFrame frame = RenderPlate(scene, D415Intrinsics(), seed);
    for (size_t i = 0; i < scene.items.size(); ++i) {
      const SceneItem& item = scene.items[i];
      const ItemTruth& t = frame.truth[i];
      EXPECT_LE(t.visible_pixels, t.footprint_pixels);
      if (item.base_m > 0.0) {
        ++lying;
        // It rests on a slice's top: a kiwi slice's thickness up.
        EXPECT_LE(item.base_m, FindFood("kiwi")->height_m[1]);
        // Nothing lies on it, so all of it shows.
        EXPECT_GE(t.visible_pixels, 0.99 * t.footprint_pixels);
      }
      partly_hidden += t.visible_pixels < 0.95 * t.footprint_pixels;
    }
  }
  EXPECT_GE(lying, 5);
  EXPECT_GE(partly_hidden, 5);  // the slices underneath
}

TEST(PlateTest, SameFoodTouchingPutsPiecesSideBySide) {
  PlateCrowding crowding;
  crowding.same_food_touch_probability = 1.0;
  crowding.touch_probability = 0.0;
  std::mt19937_64 rng(9);
  const std::vector<const FoodType*> foods = {
      FindFood("carrot"), FindFood("kiwi"), FindFood("carrot"),
      FindFood("kiwi")};
  const PlateScene scene = CrowdedPlate(foods, crowding, rng);
  ASSERT_EQ(scene.items.size(), 4u);
  // The second carrot and the second kiwi each lie against their first
  // (the closest other item is of its own food).
  for (size_t i = 2; i < 4; ++i) {
    size_t nearest = 0;
    double best = 1e9;
    for (size_t j = 0; j < scene.items.size(); ++j) {
      if (j == i) continue;
      const double d = std::hypot(scene.items[i].x_m - scene.items[j].x_m,
                                  scene.items[i].y_m - scene.items[j].y_m);
      if (d < best) best = d, nearest = j;
    }
    EXPECT_EQ(scene.items[nearest].food, scene.items[i].food) << i;
  }
}

TEST(PlateTest, PlatesRepeatWithTheirSeed) {
  PlateCrowding crowding;
  crowding.overlap_probability = 0.5;
  std::mt19937_64 a(21), b(21);
  const PlateScene first = CrowdedPlate(Kiwis(5), crowding, a);
  const PlateScene second = CrowdedPlate(Kiwis(5), crowding, b);
  ASSERT_EQ(first.items.size(), second.items.size());
  for (size_t i = 0; i < first.items.size(); ++i) {
    EXPECT_EQ(first.items[i].x_m, second.items[i].x_m);
    EXPECT_EQ(first.items[i].base_m, second.items[i].base_m);
  }
}

}  // namespace
}  // namespace bitewise::sim
