// The blind plate renderer's own promises: a seed fixes the frame; the
// truth agrees with the label image; the geometry (plate at the camera's
// distance, food above it, shingled slices on their neighbours) shows in
// the depth; the arrangement respects its options; the D415 artefacts are
// where active stereo puts them.
#include "experiments/blind_plates.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <tuple>
#include <vector>

namespace bitewise::experiments {
namespace {

BlindPlateOptions Options(int min_items, int max_items, double overlap,
                          double same, double touch, bool artifacts) {
  BlindPlateOptions o;
  o.min_items = min_items;
  o.max_items = max_items;
  o.overlap_probability = overlap;
  o.same_food_touch_probability = same;
  o.touch_probability = touch;
  o.sensor_artifacts = artifacts;
  return o;
}

// Renders are slow-ish (a few hundred ms): each test's plates once.
const BlindPlate& Render(uint64_t seed, const BlindPlateOptions& o) {
  using Key = std::tuple<uint64_t, int, int, double, double, double, bool>;
  static auto* cache = new std::map<Key, std::unique_ptr<BlindPlate>>();
  const Key key{seed,
                o.min_items,
                o.max_items,
                o.overlap_probability,
                o.same_food_touch_probability,
                o.touch_probability,
                o.sensor_artifacts};
  auto it = cache->find(key);
  if (it == cache->end()) {
    it = cache
             ->emplace(key,
                       std::make_unique<BlindPlate>(RenderBlindPlate(seed, o)))
             .first;
  }
  return *it->second;
}

const BlindPlateOptions kDefaultClean = Options(2, 8, 0.3, 0.3, 0.3, false);
const BlindPlateOptions kDefault = Options(2, 8, 0.3, 0.3, 0.3, true);
const BlindPlateOptions kBareClean = Options(0, 0, 0.3, 0.3, 0.3, false);
const BlindPlateOptions kBare = Options(0, 0, 0.3, 0.3, 0.3, true);
const BlindPlateOptions kShingledClean = Options(6, 6, 1.0, 0.0, 0.0, false);

TEST(BlindPlatesTest, SameSeedSameBytesOtherSeedOther) {
  const BlindPlate a = RenderBlindPlate(11, kDefault);
  const BlindPlate b = RenderBlindPlate(11, kDefault);
  EXPECT_EQ(a.frame.rgb, b.frame.rgb);
  EXPECT_EQ(a.frame.depth_mm, b.frame.depth_mm);
  EXPECT_EQ(a.label, b.label);
  EXPECT_EQ(a.food, b.food);
  ASSERT_EQ(a.frame.truth.size(), b.frame.truth.size());
  for (size_t i = 0; i < a.frame.truth.size(); ++i) {
    EXPECT_EQ(a.frame.truth[i].visible_pixels, b.frame.truth[i].visible_pixels);
    EXPECT_EQ(a.frame.truth[i].footprint_pixels,
              b.frame.truth[i].footprint_pixels);
  }
  const BlindPlate& c = Render(12, kDefault);
  EXPECT_NE(a.frame.rgb, c.frame.rgb);
  EXPECT_NE(a.frame.depth_mm, c.frame.depth_mm);
}

TEST(BlindPlatesTest, FrameHasTheD415Layout) {
  const BlindPlate& p = Render(12, kDefault);
  const auto in = sim::D415Intrinsics();
  EXPECT_EQ(p.frame.intrinsics.width, in.width);
  EXPECT_EQ(p.frame.intrinsics.height, in.height);
  EXPECT_DOUBLE_EQ(p.frame.intrinsics.fx, in.fx);
  EXPECT_DOUBLE_EQ(p.frame.intrinsics.cx, in.cx);
  const size_t n = static_cast<size_t>(in.width) * in.height;
  EXPECT_EQ(p.frame.rgb.size(), 3 * n);
  EXPECT_EQ(p.frame.depth_mm.size(), n);
  EXPECT_EQ(p.label.size(), n);
  const size_t items = p.food.size();
  EXPECT_EQ(p.frame.truth.size(), items);
  EXPECT_EQ(p.lies_on_another.size(), items);
  EXPECT_EQ(p.lies_on_index.size(), items);
  EXPECT_EQ(p.size_mm.size(), items);
  EXPECT_GE(p.axis_distance_mm, 300.0);
  EXPECT_LE(p.axis_distance_mm, 400.0);
}

// visible_pixels, the box and the label image say the same thing, and an
// item never shows more than it covers alone.
TEST(BlindPlatesTest, TruthAgreesWithTheLabelImage) {
  int checked = 0, partly_hidden = 0;
  for (uint64_t seed = 20; seed < 26; ++seed) {
    const BlindPlate& p = Render(seed, kDefaultClean);
    const int w = p.frame.intrinsics.width, h = p.frame.intrinsics.height;
    const int n = static_cast<int>(p.food.size());
    std::vector<int> count(n, 0), x0(n, w), y0(n, h), x1(n, -1), y1(n, -1);
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        const int l = p.label[y * w + x];
        ASSERT_GE(l, -1);
        ASSERT_LT(l, n);
        if (l < 0) continue;
        ++count[l];
        x0[l] = std::min(x0[l], x);
        y0[l] = std::min(y0[l], y);
        x1[l] = std::max(x1[l], x);
        y1[l] = std::max(y1[l], y);
      }
    }
    for (int i = 0; i < n; ++i) {
      const sim::ItemTruth& t = p.frame.truth[i];
      SCOPED_TRACE("seed " + std::to_string(seed) + " item " +
                   std::to_string(i) + " " + p.food[i]);
      EXPECT_EQ(t.id, static_cast<uint32_t>(i));
      EXPECT_EQ(t.visible_pixels, count[i]);
      EXPECT_LE(t.visible_pixels, t.footprint_pixels);
      EXPECT_GT(t.footprint_pixels, 200);  // every piece is in view
      if (count[i] == 0) {
        EXPECT_EQ(t.width, 0);
        EXPECT_EQ(t.height, 0);
        continue;
      }
      EXPECT_EQ(t.x, x0[i]);
      EXPECT_EQ(t.y, y0[i]);
      EXPECT_EQ(t.width, x1[i] - x0[i] + 1);
      EXPECT_EQ(t.height, y1[i] - y0[i] + 1);
      if (t.visible_pixels < t.footprint_pixels) ++partly_hidden;
      ++checked;
    }
  }
  EXPECT_GT(checked, 12);
  EXPECT_GT(partly_hidden, 0);
}

TEST(BlindPlatesTest, ItemCountsStayWithinTheOptions) {
  for (uint64_t seed = 40; seed < 52; ++seed) {
    const BlindPlateOptions o = Options(3, 5, 0.3, 0.3, 0.3, false);
    const BlindPlate p = RenderBlindPlate(seed, o);
    EXPECT_GE(p.food.size(), 3u) << seed;
    EXPECT_LE(p.food.size(), 5u) << seed;
    for (const std::string& f : p.food) {
      EXPECT_NE(
          std::find(BlindPlateFoods().begin(), BlindPlateFoods().end(), f),
          BlindPlateFoods().end())
          << f;
    }
  }
  const BlindPlate one =
      RenderBlindPlate(3, Options(1, 1, 0.3, 0.3, 0.3, false));
  EXPECT_EQ(one.food.size(), 1u);
}

// With no items the view is plate and table; the optical axis meets the
// well at the camera's axis distance.
TEST(BlindPlatesTest, BarePlateLiesAtTheCameraDistance) {
  for (uint64_t seed : {5u, 6u, 7u}) {
    const BlindPlate& clean = Render(seed, kBareClean);
    EXPECT_TRUE(clean.food.empty());
    EXPECT_TRUE(clean.frame.truth.empty());
    EXPECT_TRUE(std::all_of(clean.label.begin(), clean.label.end(),
                            [](int16_t l) { return l == -1; }));
    const int w = clean.frame.intrinsics.width;
    const int centre = 240 * w + 320;
    EXPECT_NEAR(clean.frame.depth_mm[centre], clean.axis_distance_mm, 1.0);
    // Every pixel has depth, and it is the plate or the table beyond it.
    for (uint16_t d : clean.frame.depth_mm) {
      ASSERT_GT(d, clean.axis_distance_mm - 100.0);
      ASSERT_LT(d, clean.axis_distance_mm + 150.0);
    }
    // With the sensor's artefacts: the same distance through the noise.
    const BlindPlate& noisy = Render(seed, kBare);
    std::vector<int> around;
    for (int y = 235; y <= 245; ++y) {
      for (int x = 315; x <= 325; ++x) {
        if (noisy.frame.depth_mm[y * w + x] > 0) {
          around.push_back(noisy.frame.depth_mm[y * w + x]);
        }
      }
    }
    // (The IR projector's glint on the glaze may punch holes here.)
    ASSERT_GT(around.size(), 30u);
    std::nth_element(around.begin(), around.begin() + around.size() / 2,
                     around.end());
    EXPECT_NEAR(around[around.size() / 2], noisy.axis_distance_mm, 2.0);
  }
}

// The plate and camera depend on the seed only, so the bare plate of the
// same seed is the ground under the food: food is nearer than it, by about
// the piece's height, and nothing else changes.
TEST(BlindPlatesTest, ItemsRiseAboveThePlate) {
  int tall_enough = 0, items_seen = 0;
  for (uint64_t seed = 20; seed < 26; ++seed) {
    const BlindPlate& p = Render(seed, kDefaultClean);
    const BlindPlate& bare = Render(seed, kBareClean);
    ASSERT_DOUBLE_EQ(p.axis_distance_mm, bare.axis_distance_mm);
    const int n = static_cast<int>(p.food.size());
    std::vector<int> rise(n, 0);
    for (size_t k = 0; k < p.label.size(); ++k) {
      const int l = p.label[k];
      if (l < 0) {
        ASSERT_EQ(p.frame.depth_mm[k], bare.frame.depth_mm[k]) << seed;
        continue;
      }
      ASSERT_LE(p.frame.depth_mm[k], bare.frame.depth_mm[k]) << seed;
      rise[l] = std::max(rise[l], bare.frame.depth_mm[k] - p.frame.depth_mm[k]);
    }
    for (int i = 0; i < n; ++i) {
      const sim::ItemTruth& t = p.frame.truth[i];
      if (t.visible_pixels < 0.9 * t.footprint_pixels) continue;
      ++items_seen;
      // Seen from up to ~35 deg off the vertical, the top of a piece
      // stands at least 75 % of its height over the plate.
      EXPECT_GE(rise[i], 0.75 * p.size_mm[i][2] - 1.0)
          << "seed " << seed << " " << p.food[i];
      if (rise[i] >= p.size_mm[i][2] - 2.0) ++tall_enough;
    }
  }
  EXPECT_GT(items_seen, 10);
  EXPECT_GT(tall_enough, items_seen / 2);
}

// Shingling: a flat piece placed on another flat one hides part of it and
// stands higher than its own thickness.
TEST(BlindPlatesTest, ShingledSlicePartlyHidesTheOneUnderIt) {
  const std::vector<std::string> flat_foods = {"carrot", "celery", "strawberry",
                                               "banana", "kiwi"};
  int plates_with_stacks = 0, stacks = 0;
  for (uint64_t seed = 60; seed < 66; ++seed) {
    const BlindPlate& p = Render(seed, kShingledClean);
    const BlindPlate& bare = Render(seed, kBareClean);
    bool any = false;
    for (size_t i = 0; i < p.food.size(); ++i) {
      SCOPED_TRACE("seed " + std::to_string(seed) + " item " +
                   std::to_string(i));
      if (!p.lies_on_another[i]) {
        EXPECT_EQ(p.lies_on_index[i], -1);
        continue;
      }
      any = true;
      ++stacks;
      const int j = p.lies_on_index[i];
      ASSERT_GE(j, 0);
      ASSERT_LT(j, static_cast<int>(i));  // on an item placed before it
      EXPECT_NE(std::find(flat_foods.begin(), flat_foods.end(), p.food[i]),
                flat_foods.end());
      EXPECT_NE(std::find(flat_foods.begin(), flat_foods.end(), p.food[j]),
                flat_foods.end());
      EXPECT_LT(p.frame.truth[j].visible_pixels,
                p.frame.truth[j].footprint_pixels);
      EXPECT_GT(p.frame.truth[i].visible_pixels, 0);
      int rise = 0;
      for (size_t k = 0; k < p.label.size(); ++k) {
        if (p.label[k] != static_cast<int>(i)) continue;
        rise = std::max(rise, bare.frame.depth_mm[k] - p.frame.depth_mm[k]);
      }
      EXPECT_GT(rise, p.size_mm[i][2] + 1.0)
          << p.food[i] << " on " << p.food[j];
    }
    if (any) ++plates_with_stacks;
  }
  // About half the pieces are flat, so most plates of six have a stack.
  EXPECT_GE(plates_with_stacks, 3);
  EXPECT_GE(stacks, 4);
  // Without the overlap option nothing is stacked.
  for (uint64_t seed = 20; seed < 23; ++seed) {
    const BlindPlate& p = Render(seed, Options(2, 8, 0.0, 0.3, 0.3, false));
    for (size_t i = 0; i < p.food.size(); ++i) {
      EXPECT_FALSE(p.lies_on_another[i]);
      EXPECT_EQ(p.lies_on_index[i], -1);
    }
  }
}

// With touch_probability 1 the second piece touches the first: their
// silhouettes meet in the image.
TEST(BlindPlatesTest, TouchingPiecesMeetInTheImage) {
  int met = 0;
  const int plates = 6;
  for (uint64_t seed = 80; seed < 80 + plates; ++seed) {
    const BlindPlate& p = Render(seed, Options(2, 2, 0.0, 0.0, 1.0, false));
    ASSERT_EQ(p.food.size(), 2u);
    const int w = p.frame.intrinsics.width, h = p.frame.intrinsics.height;
    bool adjacent = false;
    for (int y = 1; y < h - 1 && !adjacent; ++y) {
      for (int x = 1; x < w - 1 && !adjacent; ++x) {
        if (p.label[y * w + x] != 0) continue;
        for (int dy = -1; dy <= 1; ++dy) {
          for (int dx = -1; dx <= 1; ++dx) {
            if (p.label[(y + dy) * w + x + dx] == 1) adjacent = true;
          }
        }
      }
    }
    if (adjacent) ++met;
  }
  EXPECT_EQ(met, plates);
}

// The D415's artefacts: none on the clean render; with them, depth holes
// crowd the raised edges, mostly on the image-left side (the right imager,
// 40 mm to the right of the colour camera, cannot see there); noise of
// about a millimetre on the plate.
TEST(BlindPlatesTest, StereoArtefactsSitWhereActiveStereoPutsThem) {
  long left_holes = 0, right_holes = 0, edge_pixels = 0, edge_holes = 0;
  long holes = 0, pixels = 0;
  double sq = 0.0;
  long compared = 0;
  for (uint64_t seed = 20; seed < 24; ++seed) {
    const BlindPlate& clean = Render(seed, kDefaultClean);
    const BlindPlate& noisy = Render(seed, kDefault);
    ASSERT_EQ(clean.label, noisy.label);  // same scene either way
    EXPECT_EQ(
        std::count(clean.frame.depth_mm.begin(), clean.frame.depth_mm.end(), 0),
        0);
    const int w = clean.frame.intrinsics.width,
              h = clean.frame.intrinsics.height;
    for (int y = 4; y < h - 4; ++y) {
      for (int x = 4; x < w - 4; ++x) {
        const int k = y * w + x;
        ++pixels;
        if (noisy.frame.depth_mm[k] == 0) ++holes;
        // Left and right edges of an item's silhouette, in this row.
        const int l = clean.label[k];
        if (l >= 0 && clean.label[k - 1] != l && clean.label[k - 1] == -1) {
          for (int s = 1; s <= 3; ++s) {
            ++edge_pixels;
            if (noisy.frame.depth_mm[k - s] == 0) ++left_holes, ++edge_holes;
          }
        }
        if (l >= 0 && clean.label[k + 1] != l && clean.label[k + 1] == -1) {
          for (int s = 1; s <= 3; ++s) {
            if (noisy.frame.depth_mm[k + s] == 0) ++right_holes;
          }
        }
        // Noise on the plate away from items.
        if (l == -1 && noisy.frame.depth_mm[k] > 0 &&
            std::abs(clean.frame.depth_mm[k] -
                     static_cast<int>(noisy.axis_distance_mm)) < 30) {
          bool near_item = false;
          for (int dy = -4; dy <= 4 && !near_item; dy += 4)
            for (int dx = -4; dx <= 4 && !near_item; dx += 4)
              if (clean.label[k + dy * w + dx] >= 0) near_item = true;
          if (!near_item) {
            const double e = static_cast<double>(noisy.frame.depth_mm[k]) -
                             clean.frame.depth_mm[k];
            sq += e * e;
            ++compared;
          }
        }
      }
    }
  }
  ASSERT_GT(edge_pixels, 300);
  const double hole_rate = static_cast<double>(holes) / pixels;
  const double edge_rate = static_cast<double>(edge_holes) / edge_pixels;
  EXPECT_GT(hole_rate, 0.001);
  EXPECT_LT(hole_rate, 0.08);
  EXPECT_GT(edge_rate, 5.0 * hole_rate);
  EXPECT_GT(left_holes, 2 * right_holes);
  ASSERT_GT(compared, 10000);
  const double rms = std::sqrt(sq / compared);
  EXPECT_GT(rms, 0.25);
  EXPECT_LT(rms, 2.5);
}

// Colour: each food shows its own hue (the mean over its visible pixels).
TEST(BlindPlatesTest, FoodsShowTheirColours) {
  std::map<std::string, int> seen;
  for (uint64_t seed = 20; seed < 32; ++seed) {
    const BlindPlate& p = Render(seed, kDefaultClean);
    const int n = static_cast<int>(p.food.size());
    std::vector<double> r(n, 0), g(n, 0), b(n, 0);
    std::vector<int> c(n, 0);
    for (size_t k = 0; k < p.label.size(); ++k) {
      const int l = p.label[k];
      if (l < 0) continue;
      r[l] += p.frame.rgb[3 * k];
      g[l] += p.frame.rgb[3 * k + 1];
      b[l] += p.frame.rgb[3 * k + 2];
      ++c[l];
    }
    for (int i = 0; i < n; ++i) {
      if (c[i] < 300) continue;
      const double R = r[i] / c[i], G = g[i] / c[i], B = b[i] / c[i];
      const std::string& f = p.food[i];
      SCOPED_TRACE("seed " + std::to_string(seed) + " " + f);
      ++seen[f];
      if (f == "cherry_tomato") {
        EXPECT_GT(R, 1.5 * G);
        EXPECT_GT(R, 1.5 * B);
      } else if (f == "strawberry") {  // a pale pith or a green cap
        EXPECT_GT(R, 1.15 * G);
        EXPECT_GT(R, 1.15 * B);
      } else if (f == "carrot" || f == "cantaloupe") {
        EXPECT_GT(R, G);
        EXPECT_GT(G, B);
      } else if (f == "celery") {
        EXPECT_GT(G, R);
        EXPECT_GT(G, B);
      } else if (f == "banana") {
        EXPECT_GT(R, B);
        EXPECT_GT(G, B);
      } else if (f == "kiwi") {
        EXPECT_GT(G, B);
      }
    }
  }
  EXPECT_GE(seen.size(), 5u);
}

}  // namespace
}  // namespace bitewise::experiments
