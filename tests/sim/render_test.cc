// The simulated D415 (services/sim/render.cc) against the scene's geometry
// worked out here: the plate's well and the mat lie at their depths, an
// item covers the pixels whose rays meet its outline and its top is at its
// height, a raised edge leaves a band without depth on its left, colours
// are the surfaces', and noise depends on the seed alone.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <utility>
#include <vector>

#include "gtest/gtest.h"
#include "services/sim/food_catalog.h"
#include "services/sim/scene.h"

namespace bitewise::sim {
namespace {

const PinholeIntrinsics kK = D415Intrinsics();

// Where the ray through pixel (u, v) meets height z above the plate, in
// plate coordinates (the camera looks straight down at the plate centre).
void RayAt(int u, int v, double z, const PlateScene& scene, double* x,
           double* y) {
  *x = (u - kK.cx) / kK.fx * (scene.camera_height_m - z);
  *y = (v - kK.cy) / kK.fy * (scene.camera_height_m - z);
}

uint16_t DepthAt(const RenderedFrame& frame, int u, int v) {
  return frame.depth_mm[static_cast<size_t>(v) * kK.width + u];
}

SceneItem Item(double x, double y, double yaw, double length, double width,
               double height) {
  SceneItem item;
  item.id = 1;
  item.food = FindFood("carrot");
  item.x_m = x;
  item.y_m = y;
  item.yaw_rad = yaw;
  item.length_m = length;
  item.width_m = width;
  item.height_m = height;
  return item;
}

TEST(RenderTest, ThePlatesWellAndTheMatLieAtTheirDepths) {
  const PlateScene scene;  // empty: 12 cm plate, camera 35 cm above it
  const RenderedFrame frame = RenderPlate(scene, kK, 1);
  ASSERT_EQ(frame.depth_mm.size(), static_cast<size_t>(kK.width * kK.height));
  ASSERT_EQ(frame.rgb.size(), frame.depth_mm.size() * 3);
  const double well_mm = scene.camera_height_m * 1000.0;
  // The mat is 14 mm below the plate's surface.
  const double mat_mm = well_mm + 14.0;
  int well = 0, well_holes = 0, mat = 0;
  double well_sum = 0.0, mat_sum = 0.0, worst = 0.0;
  for (int v = 0; v < kK.height; ++v) {
    for (int u = 0; u < kK.width; ++u) {
      double x, y;
      RayAt(u, v, 0.0, scene, &x, &y);
      const double r_well = std::hypot(x, y);
      // Mat: the ray passes outside the rim's top.
      RayAt(u, v, scene.rim_height_m, scene, &x, &y);
      const double r_mat = std::hypot(x, y);
      const uint16_t d = DepthAt(frame, u, v);
      // Well: inside 80 % of the radius, with a margin.
      if (r_well < 0.75 * scene.plate_radius_m) {
        ++well;
        if (d == 0) {
          ++well_holes;
          continue;
        }
        well_sum += d - well_mm;
        worst = std::max(worst, std::abs(d - well_mm));
      } else if (r_mat > 1.02 * scene.plate_radius_m && d != 0) {
        ++mat;
        mat_sum += d - mat_mm;
        worst = std::max(worst, std::abs(d - mat_mm));
      }
    }
  }
  ASSERT_GT(well, 50000);
  ASSERT_GT(mat, 10000);
  // 0.6 mm noise, 0.4 mm ripple and 1 mm steps: unbiased, never far off.
  EXPECT_NEAR(well_sum / (well - well_holes), 0.0, 0.2);
  EXPECT_NEAR(mat_sum / mat, 0.0, 0.2);
  EXPECT_LT(worst, 5.0);
  // Speckles and a few glints, no more.
  EXPECT_LT(well_holes, 0.02 * well);
}

TEST(RenderTest, AnItemCoversThePixelsWhoseRaysMeetItsOutline) {
  PlateScene scene;
  // An ellipse (aspect below a stick's), off centre and turned.
  scene.items = {Item(0.02, -0.01, 0.5, 0.04, 0.025, 0.015)};
  const RenderedFrame frame = RenderPlate(scene, kK, 2);
  ASSERT_EQ(frame.truth.size(), 1u);
  const ItemTruth& truth = frame.truth[0];
  const SceneItem& item = scene.items[0];
  // The outline on the plate, seen through each pixel's centre.
  int inside = 0, u0 = kK.width, u1 = -1, v0 = kK.height, v1 = -1;
  for (int v = 0; v < kK.height; ++v) {
    for (int u = 0; u < kK.width; ++u) {
      double x, y;
      RayAt(u, v, 0.0, scene, &x, &y);
      const double dx = x - item.x_m, dy = y - item.y_m;
      const double a =
          (dx * std::cos(item.yaw_rad) + dy * std::sin(item.yaw_rad)) /
          (item.length_m / 2);
      const double b =
          (-dx * std::sin(item.yaw_rad) + dy * std::cos(item.yaw_rad)) /
          (item.width_m / 2);
      if (a * a + b * b >= 1.0) continue;
      ++inside;
      u0 = std::min(u0, u), u1 = std::max(u1, u);
      v0 = std::min(v0, v), v1 = std::max(v1, v);
    }
  }
  // About pi a b f^2 / z^2 pixels: 1200 or so.
  ASSERT_GT(inside, 1000);
  EXPECT_EQ(truth.id, 1u);
  EXPECT_NEAR(truth.footprint_pixels, inside, 0.01 * inside);
  EXPECT_EQ(truth.visible_pixels, truth.footprint_pixels);  // nothing on it
  EXPECT_NEAR(truth.x, u0, 1);
  EXPECT_NEAR(truth.y, v0, 1);
  EXPECT_NEAR(truth.x + truth.width - 1, u1, 1);
  EXPECT_NEAR(truth.y + truth.height - 1, v1, 1);
}

// The median non-zero depth of the 5x5 pixels around the one that sees
// the item's centre at `top_m` above the plate.
double TopDepthMm(const RenderedFrame& frame, const PlateScene& scene,
                  const SceneItem& item, double top_m) {
  const double z = scene.camera_height_m - top_m;
  const int u = static_cast<int>(std::lround(kK.cx + kK.fx * item.x_m / z));
  const int v = static_cast<int>(std::lround(kK.cy + kK.fy * item.y_m / z));
  std::vector<double> depths;
  for (int dv = -2; dv <= 2; ++dv) {
    for (int du = -2; du <= 2; ++du) {
      const uint16_t d = DepthAt(frame, u + du, v + dv);
      if (d != 0) depths.push_back(d);
    }
  }
  EXPECT_GE(depths.size(), 10u);
  std::nth_element(depths.begin(), depths.begin() + depths.size() / 2,
                   depths.end());
  return depths[depths.size() / 2];
}

TEST(RenderTest, AnItemsTopIsAtItsHeightAndARaisedItemHigherStill) {
  PlateScene scene;
  scene.items = {Item(-0.03, 0.02, 0.0, 0.03, 0.028, 0.02)};
  scene.items.push_back(Item(0.04, 0.01, 1.0, 0.03, 0.028, 0.01));
  scene.items[1].id = 2;
  scene.items[1].base_m = 0.012;  // resting on something
  const RenderedFrame frame = RenderPlate(scene, kK, 3);
  const SceneItem& flat = scene.items[0];
  const SceneItem& raised = scene.items[1];
  // The dome's top is flat within a pixel or two of the centre.
  EXPECT_NEAR(TopDepthMm(frame, scene, flat, flat.height_m),
              (scene.camera_height_m - flat.height_m) * 1000.0, 1.5);
  EXPECT_NEAR(
      TopDepthMm(frame, scene, raised, raised.base_m + raised.height_m),
      (scene.camera_height_m - raised.base_m - raised.height_m) * 1000.0, 1.5);
}

TEST(RenderTest, ARaisedEdgeLeavesABandWithoutDepthOnItsLeftOnly) {
  PlateScene scene;
  // A tall stick along the image's rows: 4 cm high, so the stereo
  // disparity jump at its sides is several pixels.
  scene.items = {Item(0.0, 0.0, 0.0, 0.06, 0.02, 0.04)};
  const RenderedFrame frame = RenderPlate(scene, kK, 4);
  const int v_centre = static_cast<int>(kK.cy);
  int rows = 0, left_bands = 0, right_bands = 0;
  for (int v = v_centre - 5; v <= v_centre + 5; ++v) {
    // The item's first and last pixels along the row that are more than
    // 2 cm above the plate (the rim, further out, rises 12 mm).
    int first = -1, last = -1;
    for (int u = 0; u < kK.width; ++u) {
      const uint16_t d = DepthAt(frame, u, v);
      if (d != 0 && d < 330) {
        if (first < 0) first = u;
        last = u;
      }
    }
    ASSERT_GT(first, 12);
    ASSERT_LT(last, kK.width - 13);
    ++rows;
    int left_holes = 0, right_holes = 0;
    for (int k = 1; k <= 3; ++k) {
      left_holes += DepthAt(frame, first - k, v) == 0;
      right_holes += DepthAt(frame, last + k, v) == 0;
    }
    left_bands += left_holes == 3;
    right_bands += right_holes > 0;
  }
  EXPECT_EQ(left_bands, rows);
  EXPECT_LE(right_bands, 1);  // a speckle at most
}

TEST(RenderTest, ColoursAreThoseOfThePlateTheMatAndTheItem) {
  PlateScene scene;
  scene.items = {Item(0.0, 0.0, 0.0, 0.03, 0.028, 0.015)};
  scene.items[0].rgb = {0.8, 0.05, 0.02};
  const RenderedFrame frame = RenderPlate(scene, kK, 5);
  // Mean colour of a 5x5 patch around a pixel.
  auto mean = [&](int u, int v, int c) {
    double sum = 0.0;
    for (int dv = -2; dv <= 2; ++dv) {
      for (int du = -2; du <= 2; ++du) {
        sum +=
            frame
                .rgb[(static_cast<size_t>(v + dv) * kK.width + u + du) * 3 + c];
      }
    }
    return sum / 25;
  };
  const int cu = static_cast<int>(kK.cx), cv = static_cast<int>(kK.cy);
  // The item at the centre: red.
  EXPECT_GT(mean(cu, cv, 0), 2 * mean(cu, cv, 1));
  EXPECT_GT(mean(cu, cv, 0), 2 * mean(cu, cv, 2));
  // The plate's well (5 cm right of the item): near white, grey.
  const int pu = cu + static_cast<int>(kK.fx * 0.06 / 0.35);
  for (int c = 0; c < 3; ++c) EXPECT_GT(mean(pu, cv, c), 150) << c;
  EXPECT_NEAR(mean(pu, cv, 0), mean(pu, cv, 1), 10);
  // The mat in the corner: blue above red.
  EXPECT_GT(mean(10, 10, 2), mean(10, 10, 0) + 20);
}

TEST(RenderTest, TheNoiseSeedChangesTheNoiseAndNothingElse) {
  std::mt19937_64 rng(8);
  const PlateScene scene =
      RandomPlate({FindFood("carrot"), FindFood("kiwi")}, false, rng);
  const RenderedFrame a = RenderPlate(scene, kK, 11);
  const RenderedFrame again = RenderPlate(scene, kK, 11);
  const RenderedFrame b = RenderPlate(scene, kK, 12);
  EXPECT_EQ(a.rgb, again.rgb);
  EXPECT_EQ(a.depth_mm, again.depth_mm);
  EXPECT_NE(a.rgb, b.rgb);
  EXPECT_NE(a.depth_mm, b.depth_mm);
  ASSERT_EQ(a.truth.size(), b.truth.size());
  for (size_t i = 0; i < a.truth.size(); ++i) {
    EXPECT_EQ(a.truth[i].visible_pixels, b.truth[i].visible_pixels);
    EXPECT_EQ(a.truth[i].x, b.truth[i].x);
    EXPECT_EQ(a.truth[i].width, b.truth[i].width);
  }
  // Where both have depth, they differ by the noise only.
  int both = 0, close = 0;
  for (size_t i = 0; i < a.depth_mm.size(); ++i) {
    if (a.depth_mm[i] == 0 || b.depth_mm[i] == 0) continue;
    ++both;
    close += std::abs(a.depth_mm[i] - b.depth_mm[i]) <= 4;
  }
  EXPECT_GT(close, 0.999 * both);
}

TEST(RenderTest, ToRgbdFrameKeepsThePixelsAndStampsTheFrame) {
  const PlateScene scene;
  RenderedFrame rendered = RenderPlate(scene, kK, 6);
  const std::vector<uint8_t> rgb = rendered.rgb;
  const std::vector<uint16_t> depth = rendered.depth_mm;
  const domain::RgbdFrame frame = ToRgbdFrame(std::move(rendered), 42, 12.5);
  EXPECT_EQ(frame.rgb, rgb);
  EXPECT_EQ(frame.depth_mm, depth);
  EXPECT_EQ(frame.sequence, 42u);
  EXPECT_EQ(frame.capture_s, 12.5);
  EXPECT_EQ(frame.intrinsics.width, kK.width);
  EXPECT_EQ(frame.intrinsics.height, kK.height);
  EXPECT_EQ(frame.intrinsics.fx, kK.fx);
  EXPECT_EQ(frame.intrinsics.cy, kK.cy);
}

}  // namespace
}  // namespace bitewise::sim
