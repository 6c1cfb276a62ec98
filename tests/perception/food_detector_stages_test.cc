// FoodDetector's stages one by one, on synthetic inputs whose answer is
// known by construction (the whole detector on rendered plates is
// food_detector_test.cc).
#include "services/perception/food_detector_stages.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <set>

#include "gtest/gtest.h"
#include "opencv2/imgproc.hpp"

namespace bitewise::perception::detection {
namespace {

constexpr int kW = 640, kH = 480;

// A fronto-parallel plate 400 mm from the camera with a 20 mm tall box on
// it (pixels [300, 340) x [220, 260)) and a 10x10 hole (no depth).
cv::Mat PlateWithBox() {
  cv::Mat depth(kH, kW, CV_16UC1, cv::Scalar(400));
  depth(cv::Rect(300, 220, 40, 40)).setTo(380);
  depth(cv::Rect(100, 100, 10, 10)).setTo(0);
  return depth;
}

TEST(DetectorStagesTest, MeasureHeightFindsThePlaneAndEachPixelsHeight) {
  const CameraIntrinsics k;
  const std::optional<HeightMap> map =
      MeasureHeight(PlateWithBox(), k, FoodDetectorOptions());
  ASSERT_TRUE(map.has_value());
  EXPECT_NEAR(std::abs(map->plane.n[2]), 1.0, 1e-9);
  EXPECT_NEAR(map->plane.d, 400.0, 1e-6);
  EXPECT_NEAR(map->height_mm.at<float>(240, 320), 20.0, 1e-3);
  EXPECT_NEAR(map->height_mm.at<float>(50, 50), 0.0, 1e-3);
  EXPECT_EQ(map->valid.at<uint8_t>(105, 105), 0);  // the hole
  EXPECT_EQ(map->valid.at<uint8_t>(50, 50), 255);

  const cv::Mat empty(kH, kW, CV_16UC1, cv::Scalar(0));
  EXPECT_FALSE(MeasureHeight(empty, k, FoodDetectorOptions()).has_value());
}

// Flat slices 5 mm thick across the middle of the image, where the plane is
// fitted (columns [192, 448) of 640): [192, 272) bare plate, [272, 352)
// slices, [352, 416) bare plate, [416, 448) a tall item. A plane rising to
// the right across the plate on the left and the slices holds both within
// the 3 mm tolerance (80 + 80 columns), more points than the plate's own
// plane holds (80 + 64; the tall item keeps the plate's share under the
// tilted plane's), and leaves the plate on the right well below it.
// Points well below a plane count against it
// (FoodDetectorOptions::ransac_below_weight): nothing in the middle of the
// image lies below the plate's well.
TEST(DetectorStagesTest, MeasureHeightIsNotTiltedThroughTheTopsOfSlices) {
  cv::Mat depth(kH, kW, CV_16UC1, cv::Scalar(400));
  depth(cv::Rect(272, 0, 80, kH)).setTo(395);
  depth(cv::Rect(416, 0, 32, kH)).setTo(370);
  const CameraIntrinsics k;
  FoodDetectorOptions inliers_only;
  inliers_only.ransac_below_weight = 0.0;
  const std::optional<HeightMap> tilted = MeasureHeight(depth, k, inliers_only);
  ASSERT_TRUE(tilted.has_value());
  EXPECT_LT(tilted->height_mm.at<float>(kH / 2, 380), -3.0f);

  const std::optional<HeightMap> map =
      MeasureHeight(depth, k, FoodDetectorOptions());
  ASSERT_TRUE(map.has_value());
  EXPECT_NEAR(std::abs(map->plane.n[2]), 1.0, 1e-9);
  EXPECT_NEAR(map->plane.d, 400.0, 1e-6);
  EXPECT_NEAR(map->height_mm.at<float>(kH / 2, 380), 0.0, 1e-3);
  EXPECT_NEAR(map->height_mm.at<float>(kH / 2, 230), 0.0, 1e-3);
  EXPECT_NEAR(map->height_mm.at<float>(kH / 2, 310), 5.0, 1e-3);
}

TEST(DetectorStagesTest, FindPlateIsTheLargeFlatRegionOrNothing) {
  const std::optional<HeightMap> map =
      MeasureHeight(PlateWithBox(), CameraIntrinsics(), FoodDetectorOptions());
  ASSERT_TRUE(map.has_value());
  const std::optional<PlateRegion> plate =
      FindPlate(*map, FoodDetectorOptions());
  ASSERT_TRUE(plate.has_value());
  EXPECT_EQ(plate->roi, cv::Rect(0, 0, kW, kH));
  // Closed over its food: the box is inside the plate, not its surface.
  EXPECT_EQ(plate->plate.at<uint8_t>(240, 320), 255);
  EXPECT_EQ(plate->surface.at<uint8_t>(240, 320), 0);
  EXPECT_EQ(plate->surface.at<uint8_t>(240, 200), 255);

  // Flat only in a small patch: not a plate.
  HeightMap bumpy = *map;
  bumpy.height_mm.setTo(50.0f);
  bumpy.height_mm(cv::Rect(0, 0, 100, 100)).setTo(0.0f);
  EXPECT_FALSE(FindPlate(bumpy, FoodDetectorOptions()).has_value());
}

// A white plate covering the frame with one red item whose height map the
// test chooses; evidence from FindEvidence.
struct Scene {
  cv::Mat rgb;
  cv::Mat height_mm;
  cv::Mat valid;
  PlateRegion plate;
  FoodEvidence evidence;
};

Scene MakeScene(const cv::Mat& height_mm, const cv::Mat& item_mask) {
  Scene scene;
  scene.height_mm = height_mm;
  scene.valid = cv::Mat(kH, kW, CV_8UC1, cv::Scalar(255));
  scene.rgb = cv::Mat(kH, kW, CV_8UC3, cv::Scalar(230, 230, 230));
  scene.rgb.setTo(cv::Scalar(200, 60, 50), item_mask);
  scene.plate.roi = cv::Rect(0, 0, kW, kH);
  scene.plate.plate = cv::Mat(kH, kW, CV_8UC1, cv::Scalar(255));
  scene.plate.surface = ~item_mask;
  scene.evidence = FindEvidence(scene.rgb, scene.height_mm, scene.valid,
                                scene.plate, FoodDetectorOptions());
  return scene;
}

// Domes of radius 30 px and 20 mm at the given centres (the higher wins
// where they overlap).
cv::Mat Domes(const std::vector<cv::Point>& centres, cv::Mat* mask) {
  cv::Mat height(kH, kW, CV_32FC1, cv::Scalar(0));
  for (int v = 0; v < kH; ++v) {
    for (int u = 0; u < kW; ++u) {
      for (const cv::Point& c : centres) {
        const double r2 = (u - c.x) * (u - c.x) + (v - c.y) * (v - c.y);
        if (r2 < 900.0) {
          height.at<float>(v, u) =
              std::max(height.at<float>(v, u),
                       static_cast<float>(20.0 * std::sqrt(1.0 - r2 / 900.0)));
        }
      }
    }
  }
  *mask = height > 0.0f;
  return height;
}

int ItemLabels(const Regions& regions) {
  std::set<int> labels;
  for (int v = 0; v < regions.markers.rows; ++v) {
    for (int u = 0; u < regions.markers.cols; ++u) {
      const int m = regions.markers.at<int>(v, u);
      if (m > 0 && m < regions.background) labels.insert(m);
    }
  }
  return static_cast<int>(labels.size());
}

TEST(DetectorStagesTest, CloseByRowsIsOpenCvsClosingToTheBit) {
  cv::RNG rng(20261203);
  for (const cv::Size size : {cv::Size(97, 61), cv::Size(40, 300)}) {
    cv::Mat image(size, CV_32FC1);
    rng.fill(image, cv::RNG::UNIFORM, -5.0, 30.0);
    image(cv::Rect(3, 5, 20, 20)).setTo(0.0f);  // a flat patch, as a plate
    for (const int width : {1, 3, 6, 7, 31}) {
      for (const int shape : {cv::MORPH_ELLIPSE, cv::MORPH_RECT}) {
        const cv::Mat element =
            cv::getStructuringElement(shape, {width, width});
        cv::Mat expected;
        cv::morphologyEx(image, expected, cv::MORPH_CLOSE, element);
        const cv::Mat got = CloseByRows(image, element);
        EXPECT_EQ(cv::norm(expected, got, cv::NORM_INF), 0.0)
            << "width " << width << " shape " << shape << " size " << size;
      }
    }
  }
}

TEST(DetectorStagesTest, FindEvidenceSeesTheItemByHeightAndByColour) {
  cv::Mat mask;
  const Scene scene = MakeScene(Domes({{320, 240}}, &mask), mask);
  EXPECT_EQ(scene.evidence.above.at<uint8_t>(240, 320), 255);
  EXPECT_EQ(scene.evidence.colour.at<uint8_t>(240, 320), 255);
  EXPECT_EQ(scene.evidence.above.at<uint8_t>(100, 100), 0);
  EXPECT_EQ(scene.evidence.colour.at<uint8_t>(100, 100), 0);
}

TEST(DetectorStagesTest, PlantSeedsCutsTwoTouchingDomesOfOneColourApart) {
  // 45 px apart: the seam is 13 mm high, above half of their 20 mm tops, so
  // only the height-valley cut separates them.
  cv::Mat mask;
  const Scene touching =
      MakeScene(Domes({{300, 240}, {345, 240}}, &mask), mask);
  std::optional<Regions> seeds =
      PlantSeeds(touching.evidence, touching.height_mm, FoodDetectorOptions());
  ASSERT_TRUE(seeds.has_value());
  EXPECT_EQ(seeds->background, 3);  // two seeds
  FoodDetectorOptions no_cut;
  no_cut.min_valley_mm = 100.0;  // no valley deep enough
  seeds = PlantSeeds(touching.evidence, touching.height_mm, no_cut);
  ASSERT_TRUE(seeds.has_value());
  EXPECT_EQ(seeds->background, 2);  // one seed for both

  const Scene single = MakeScene(Domes({{320, 240}}, &mask), mask);
  seeds = PlantSeeds(single.evidence, single.height_mm, FoodDetectorOptions());
  ASSERT_TRUE(seeds.has_value());
  EXPECT_EQ(seeds->background, 2);

  const cv::Mat flat(kH, kW, CV_32FC1, cv::Scalar(0));
  const Scene empty = MakeScene(flat, flat > 1.0f);
  EXPECT_FALSE(
      PlantSeeds(empty.evidence, empty.height_mm, FoodDetectorOptions())
          .has_value());
}

// One flat 10 mm region, `left` colour (RGB) up to u = 320 and `right` from
// there, the colour changing over `ramp_px` (a shaded rim), so no pixel's
// gradient reaches min_edge_strength and there is no valley or step. The
// number of seeds PlantSeeds makes of it with `options`, and whether the two
// ends got different seeds.
struct RampSeeds {
  int seeds = 0;
  bool apart = false;
};
RampSeeds SeedsAcrossAColourRamp(const cv::Scalar& left,
                                 const cv::Scalar& right, int ramp_px,
                                 const FoodDetectorOptions& options) {
  cv::Mat height(kH, kW, CV_32FC1, cv::Scalar(0));
  const cv::Rect region(260, 220, 120, 40);
  height(region).setTo(10.0f);
  Scene scene = MakeScene(height, height > 0.0f);
  for (int u = 260; u < 380; ++u) {
    const double t =
        std::clamp((u - 320) / static_cast<double>(ramp_px), 0.0, 1.0);
    scene.rgb(cv::Rect(u, 220, 1, 40)).setTo(left * (1.0 - t) + right * t);
  }
  scene.evidence = FindEvidence(scene.rgb, scene.height_mm, scene.valid,
                                scene.plate, FoodDetectorOptions());
  const std::optional<Regions> seeds =
      PlantSeeds(scene.evidence, scene.height_mm, options);
  if (!seeds.has_value()) return {};
  return {seeds->background - 1,
          seeds->markers.at<int>(240, 290) != seeds->markers.at<int>(240, 350)};
}

// The CIELAB distance between two RGB colours, as FindEvidence converts them.
double LabDistance(const cv::Scalar& a, const cv::Scalar& b) {
  cv::Mat rgb(1, 2, CV_8UC3);
  rgb.at<cv::Vec3b>(0, 0) = cv::Vec3b(a[0], a[1], a[2]);
  rgb.at<cv::Vec3b>(0, 1) = cv::Vec3b(b[0], b[1], b[2]);
  cv::Mat f, lab;
  rgb.convertTo(f, CV_32FC3, 1.0 / 255);
  cv::cvtColor(f, lab, cv::COLOR_RGB2Lab);
  return cv::norm(lab.at<cv::Vec3f>(0, 0) - lab.at<cv::Vec3f>(0, 1));
}

TEST(DetectorStagesTest, PlantSeedsCutsAtASoftColourEdge) {
  // Red and orange, changing over 6 px.
  const cv::Scalar red(200, 60, 50), orange(200, 130, 40);
  FoodDetectorOptions no_soft;
  no_soft.min_soft_edge_distance = 0;
  RampSeeds seeds = SeedsAcrossAColourRamp(red, orange, 6, no_soft);
  EXPECT_EQ(seeds.seeds, 1);  // the 6 px ramp's gradient is no edge
  seeds = SeedsAcrossAColourRamp(red, orange, 6, FoodDetectorOptions());
  EXPECT_EQ(seeds.seeds, 2);
  EXPECT_TRUE(seeds.apart);
}

TEST(DetectorStagesTest, PlantSeedsCutsBetweenAPaleCoinAndAPaleGreenWall) {
  // A banana coin's lit face and a celery stick's lit wall, as pale as on
  // the blind plates, at one height, changing over 3 px. Their colours are
  // 19-20 CIELAB units apart; across the ramp, after PlantSeeds' 3x3 blur,
  // the largest difference 4 px apart is about 0.92 of that (about 17.8),
  // and no pixel's gradient is near min_edge_strength. So the soft edge
  // cuts them at 16 and did not at 20.
  const cv::Scalar coin(232, 222, 170), wall(166, 184, 140);
  const double apart = LabDistance(coin, wall);
  EXPECT_GT(apart, 19.0);
  EXPECT_LT(apart, 20.0);
  RampSeeds seeds =
      SeedsAcrossAColourRamp(coin, wall, 3, FoodDetectorOptions());
  EXPECT_EQ(seeds.seeds, 2);
  EXPECT_TRUE(seeds.apart);
  FoodDetectorOptions old_soft;
  old_soft.min_soft_edge_distance = 20;
  seeds = SeedsAcrossAColourRamp(coin, wall, 3, old_soft);
  EXPECT_EQ(seeds.seeds, 1);
}

TEST(DetectorStagesTest, GrowAndMergeJoinOneItemSeededTwice) {
  // One flat-topped item (15 mm) seeded at both ends by hand.
  cv::Mat height(kH, kW, CV_32FC1, cv::Scalar(0));
  const cv::Rect item(260, 220, 120, 40);
  height(item).setTo(15.0f);
  const Scene scene = MakeScene(height, height > 0.0f);
  Regions regions;
  regions.markers = cv::Mat(kH, kW, CV_32SC1, cv::Scalar(0));
  regions.markers(cv::Rect(270, 230, 10, 20)).setTo(1);
  regions.markers(cv::Rect(360, 230, 10, 20)).setTo(2);
  regions.background = 3;
  regions.valley_mm = cv::Mat(kH, kW, CV_32FC1, cv::Scalar(0));
  GrowRegions(scene.rgb, scene.evidence, scene.plate.plate, regions);
  EXPECT_EQ(ItemLabels(regions), 2);
  EXPECT_EQ(regions.markers.at<int>(240, 300), 1);
  EXPECT_EQ(regions.markers.at<int>(240, 350), 2);
  EXPECT_EQ(regions.markers.at<int>(100, 100), regions.background);
  MergeSplitItems(scene.evidence, scene.height_mm, scene.valid,
                  FoodDetectorOptions(), regions);
  EXPECT_EQ(ItemLabels(regions), 1);
}

TEST(DetectorStagesTest, GrowStopsAtBarePlateInAShadow) {
  // A pale item, found by its height, its colour within a few units of the
  // plate's; beside it a shadow 6 px wide: plate, darker, and closer in
  // colour to the item than to the lit plate beyond. Flooded from the
  // item's seed, the shadow joins the item unless bare plate (depth on the
  // plate, the plate's colour) is background.
  cv::Mat height(kH, kW, CV_32FC1, cv::Scalar(0));
  const cv::Rect item(260, 220, 60, 40);
  height(item).setTo(12.0f);
  Scene scene = MakeScene(height, height > 0.0f);
  scene.rgb.setTo(cv::Scalar(200, 200, 195), height > 0.0f);
  const cv::Rect shadow(item.br().x, item.y, 6, item.height);
  scene.rgb(shadow).setTo(cv::Scalar(200, 200, 200));
  const auto grown_box = [&scene](const FoodDetectorOptions& options) {
    scene.evidence = FindEvidence(scene.rgb, scene.height_mm, scene.valid,
                                  scene.plate, options);
    Regions regions;
    regions.markers = cv::Mat(kH, kW, CV_32SC1, cv::Scalar(0));
    regions.markers(cv::Rect(280, 230, 20, 20)).setTo(1);
    regions.background = 2;
    regions.valley_mm = cv::Mat(kH, kW, CV_32FC1, cv::Scalar(0));
    GrowRegions(scene.rgb, scene.evidence, scene.plate.plate, regions);
    return cv::boundingRect(regions.markers == 1);
  };
  FoodDetectorOptions off;
  off.max_bare_plate_mm = 0;
  const cv::Rect without = grown_box(off);
  EXPECT_GE(without.br().x, shadow.br().x - 1) << "the shadow joined";
  const cv::Rect with = grown_box(FoodDetectorOptions());
  EXPECT_LE(with.br().x, item.br().x);
  EXPECT_GE(with.br().x, item.br().x - 2);
  EXPECT_GE(with.width, item.width - 3);
  EXPECT_GE(with.height, item.height - 3);
}

TEST(DetectorStagesTest, FindEvidenceTakesAShadowOnThePlateForPlate) {
  // A red item, and beside it on the plate a band in its shadow: the
  // plate's grey at half the light (about 24 CIELAB units darker, the same
  // chroma). Beside that, a flat stain of the same lightness but another
  // chroma (a smear of sauce) stays food-like.
  cv::Mat height(kH, kW, CV_32FC1, cv::Scalar(0));
  height(cv::Rect(260, 220, 60, 40)).setTo(12.0f);
  Scene scene = MakeScene(height, height > 0.0f);
  const cv::Rect shadow(320, 220, 30, 40), stain(360, 220, 30, 40);
  scene.rgb(shadow).setTo(cv::Scalar(160, 160, 160));
  scene.rgb(stain).setTo(cv::Scalar(175, 150, 120));
  const auto evidence = [&scene](const FoodDetectorOptions& options) {
    return FindEvidence(scene.rgb, scene.height_mm, scene.valid, scene.plate,
                        options);
  };
  FoodDetectorOptions off;
  off.max_shadow_chroma = 0.0;
  const FoodEvidence without = evidence(off);
  EXPECT_EQ(without.colour.at<uint8_t>(240, 335), 255) << "darker than 14";
  const FoodEvidence with = evidence(FoodDetectorOptions());
  EXPECT_EQ(with.colour.at<uint8_t>(240, 335), 0);
  EXPECT_EQ(with.bare.at<uint8_t>(240, 335), 255);
  EXPECT_EQ(with.colour.at<uint8_t>(240, 375), 255);
  EXPECT_EQ(with.colour.at<uint8_t>(240, 290), 255);
  // Raised, the same dark grey is an item, not a shadow.
  scene.height_mm(shadow).setTo(8.0f);
  EXPECT_EQ(evidence(FoodDetectorOptions()).colour.at<uint8_t>(240, 335), 255);
}

// Grows and merges regions from seeds 1..n (the boxes, in order); the
// closing's lift is `valley_mm` (none when empty).
Regions GrowAndMerge(const Scene& scene, const std::vector<cv::Rect>& seeds,
                     const FoodDetectorOptions& options,
                     const cv::Mat& valley_mm = cv::Mat()) {
  Regions regions;
  regions.markers = cv::Mat(kH, kW, CV_32SC1, cv::Scalar(0));
  for (size_t i = 0; i < seeds.size(); ++i) {
    regions.markers(seeds[i]).setTo(static_cast<int>(i) + 1);
  }
  regions.background = static_cast<int>(seeds.size()) + 1;
  regions.valley_mm =
      valley_mm.empty() ? cv::Mat(kH, kW, CV_32FC1, cv::Scalar(0)) : valley_mm;
  GrowRegions(scene.rgb, scene.evidence, scene.plate.plate, regions);
  MergeSplitItems(scene.evidence, scene.height_mm, scene.valid, options,
                  regions);
  return regions;
}

// Flat discs 10 mm high ({u, v, radius} in pixels) on the plate, their
// colours painted by `paint` over the scene's RGB.
Scene FlatDiscs(const std::vector<cv::Vec3i>& discs,
                const std::function<void(cv::Mat&)>& paint) {
  cv::Mat height(kH, kW, CV_32FC1, cv::Scalar(0));
  for (const cv::Vec3i& d : discs) {
    cv::circle(height, {d[0], d[1]}, d[2], cv::Scalar(10.0), cv::FILLED);
  }
  Scene scene = MakeScene(height, height > 0.0f);
  paint(scene.rgb);
  scene.evidence = FindEvidence(scene.rgb, scene.height_mm, scene.valid,
                                scene.plate, FoodDetectorOptions());
  return scene;
}

TEST(DetectorStagesTest, MergeJoinsAPartOfAnotherColourInsideAnItem) {
  // A flat green slice (10 mm) with a pale core of its own colour seeded
  // apart (a kiwi slice's core), and a red slice touching it outside. The
  // core is joined to the slice; the red slice, whose boundary is mostly
  // with the plate, stays apart.
  const Scene scene =
      FlatDiscs({{300, 240, 40}, {370, 240, 30}}, [](cv::Mat& rgb) {
        cv::circle(rgb, {300, 240}, 40, cv::Scalar(90, 170, 60), cv::FILLED);
        cv::circle(rgb, {300, 240}, 12, cv::Scalar(230, 225, 170), cv::FILLED);
      });
  const auto items = [&scene](const FoodDetectorOptions& options) {
    return GrowAndMerge(scene,
                        {cv::Rect(270, 230, 8, 20),    // flesh
                         cv::Rect(296, 236, 8, 8),     // core
                         cv::Rect(370, 230, 10, 20)},  // the red slice
                        options);
  };
  FoodDetectorOptions off;
  off.min_enclosed_share = 2.0;
  EXPECT_EQ(ItemLabels(items(off)), 3) << "the core is an item of its own";
  const Regions with = items(FoodDetectorOptions());
  EXPECT_EQ(ItemLabels(with), 2);
  EXPECT_EQ(with.markers.at<int>(240, 300), with.markers.at<int>(240, 275));
  EXPECT_NE(with.markers.at<int>(240, 375), with.markers.at<int>(240, 275));
}

// A green slice with an orange coin over its right edge, all 10 mm high,
// and between them an arc of the slice's green, a little lighter (a sliver
// of the slice beside the coin).
Scene CoinOverASlice() {
  return FlatDiscs({{300, 240, 40}, {348, 240, 20}}, [](cv::Mat& rgb) {
    cv::circle(rgb, {300, 240}, 40, cv::Scalar(90, 170, 60), cv::FILLED);
    for (int v = 226; v <= 254; ++v) {
      for (int u = 300; u < 348; ++u) {
        const double r = std::hypot(u - 348.0, v - 240.0);
        if (r >= 20.0 && r < 24.0)
          rgb.at<cv::Vec3b>(v, u) = cv::Vec3b(105, 178, 72);
      }
    }
    cv::circle(rgb, {348, 240}, 20, cv::Scalar(230, 120, 40), cv::FILLED);
  });
}

// CoinOverASlice's regions grown and merged from seeds on the slice (in two
// halves, so that the sliver's longest seam is with the coin), the sliver
// and the coin.
Regions MergeSliceSliverCoin(const Scene& scene,
                             const FoodDetectorOptions& options) {
  return GrowAndMerge(scene,
                      {cv::Rect(280, 215, 10, 10),   // the slice, upper
                       cv::Rect(280, 255, 10, 10),   // the slice, lower
                       cv::Rect(325, 236, 2, 8),     // the sliver
                       cv::Rect(345, 235, 10, 10)},  // the coin
                      options);
}

TEST(DetectorStagesTest, MergeLeavesASliverOfAnItemWithItsOwnKin) {
  // The sliver lies inside food, and its longest seam is with the coin. It
  // is part of the slice (a larger region of its colour, open to the
  // plate, no dip between), not of the coin: two items. Without that test
  // the sliver is taken as a part of the coin inside it and chains coin and
  // slice into one.
  const Scene scene = CoinOverASlice();
  const Regions with = MergeSliceSliverCoin(scene, FoodDetectorOptions());
  EXPECT_EQ(ItemLabels(with), 2);
  EXPECT_EQ(with.markers.at<int>(240, 326), with.markers.at<int>(220, 285));
  EXPECT_NE(with.markers.at<int>(240, 350), with.markers.at<int>(220, 285));
  FoodDetectorOptions no_kin;
  no_kin.enclosed_kin = false;
  EXPECT_EQ(ItemLabels(MergeSliceSliverCoin(scene, no_kin)), 1);
}

TEST(DetectorStagesTest, MergeLeavesARegionAtTheFootOfACoinOnAnItemApart) {
  // The coin stands 20 mm high on the slice (10 mm), and the sliver's
  // pixels next to the coin are raised to 14.5 mm (depth mixed at the
  // coin's edge), so that the sliver's top (90th percentile) is within
  // max_merge_top_ratio of the coin's and of the slice's. It lies inside
  // food and its longest seam is with the coin; with the kin test off (the
  // slice is its kin), the inside rule would take it for a part of the
  // coin, and the colour test joins it to the slice: coin and slice one
  // item. Its median height, the slice's, is half the coin's: it is not
  // joined to the coin.
  Scene scene = CoinOverASlice();
  const cv::Vec3b sliver(105, 178, 72);
  for (int v = 200; v <= 280; ++v) {
    for (int u = 300; u < 380; ++u) {
      const double r = std::hypot(u - 348.0, v - 240.0);
      if (r < 20.0) {
        scene.height_mm.at<float>(v, u) = 20.0f;
      } else if (r < 21.0 && scene.rgb.at<cv::Vec3b>(v, u) == sliver &&
                 scene.height_mm.at<float>(v, u) > 0.0f) {
        scene.height_mm.at<float>(v, u) = 14.5f;
      }
    }
  }
  scene.evidence = FindEvidence(scene.rgb, scene.height_mm, scene.valid,
                                scene.plate, FoodDetectorOptions());
  FoodDetectorOptions no_kin;
  no_kin.enclosed_kin = false;
  const Regions with = MergeSliceSliverCoin(scene, no_kin);
  EXPECT_NE(with.markers.at<int>(240, 350), with.markers.at<int>(220, 285));
  EXPECT_EQ(with.markers.at<int>(240, 326), with.markers.at<int>(220, 285));
  FoodDetectorOptions off = no_kin;
  off.max_enclosed_median_ratio = 0.0;
  const Regions without = MergeSliceSliverCoin(scene, off);
  EXPECT_EQ(without.markers.at<int>(240, 350),
            without.markers.at<int>(220, 285));
}

TEST(DetectorStagesTest, MergeJoinsAHighlightToTheItemItLiesOn) {
  // A red cone (a whole strawberry, 20 mm high) whose side towards the lamp
  // shines, seeded in two halves: the skin and the shining side. Where the
  // shining side's colour is a highlight (the lamp's white added to the red:
  // lighter, about as light as the plate, the same hue, a quarter of the
  // chroma) the two are one item. Their seam runs over the cone's tip and
  // down to the plate, lower on average than 0.8 of either half's top, with
  // no valley: the merge's height test would keep them apart, the closing's
  // lift joins them. A side of another hue, of more than half the skin's
  // chroma or much darker than the plate stays apart.
  cv::Mat height(kH, kW, CV_32FC1, cv::Scalar(0));
  for (int v = 210; v < 270; ++v) {
    for (int u = 290; u < 350; ++u) {
      const double r2 = (u - 320) * (u - 320) + (v - 240) * (v - 240);
      if (r2 < 900.0) {
        height.at<float>(v, u) =
            static_cast<float>(20.0 * (1.0 - std::sqrt(r2) / 30.0));
      }
    }
  }
  const cv::Mat mask = height > 0.0f;
  const auto items = [&](const cv::Scalar& side,
                         const FoodDetectorOptions& options) {
    Scene scene = MakeScene(height, mask);
    cv::Mat lit(kH, kW, CV_8UC1, cv::Scalar(0));
    lit(cv::Rect(320, 0, kW - 320, kH)).setTo(255);
    scene.rgb.setTo(side, lit & mask);
    scene.evidence = FindEvidence(scene.rgb, scene.height_mm, scene.valid,
                                  scene.plate, FoodDetectorOptions());
    return ItemLabels(GrowAndMerge(scene,
                                   {cv::Rect(300, 236, 8, 8),   // skin
                                    cv::Rect(332, 236, 8, 8)},  // shining
                                   options));
  };
  // CIELAB: the skin (200, 60, 50) is L 47, chroma 67, hue 35 degrees; the
  // plate L 91.
  const cv::Scalar highlight(240, 200, 195);  // L 84, chroma 16, hue 30
  EXPECT_EQ(items(highlight, FoodDetectorOptions()), 1);
  FoodDetectorOptions off;
  off.max_highlight_hue_deg = 0.0;
  EXPECT_EQ(items(highlight, off), 2) << "the rule is what joins them";
  EXPECT_EQ(items(cv::Scalar(240, 235, 190), FoodDetectorOptions()), 2)
      << "pale yellow: L 92, chroma 23, but hue 104 degrees";
  EXPECT_EQ(items(cv::Scalar(255, 170, 150), FoodDetectorOptions()), 2)
      << "L 77, hue 39 degrees, but chroma 37, more than half the skin's";
  EXPECT_EQ(items(cv::Scalar(150, 110, 105), FoodDetectorOptions()), 2)
      << "chroma 18, hue 31 degrees, but L 50, far darker than the plate";
}

TEST(DetectorStagesTest, MergeKeepsApartTwoItemsWithAShadedCreaseBetween) {
  // Two red slabs (15 mm) side by side, seeded at their far ends: nothing in
  // height or colour tells them from one slab seeded twice. Where two items
  // touch, each hides part of the light from the crease between them, so a
  // dark line 4 px wide marks it: the two stay apart. A line about as dark as
  // the slabs (a seam inside one item) does not keep them apart.
  cv::Mat height(kH, kW, CV_32FC1, cv::Scalar(0));
  height(cv::Rect(260, 220, 120, 40)).setTo(15.0f);
  Scene scene = MakeScene(height, height > 0.0f);
  const auto items = [&scene](const cv::Scalar& crease,
                              const FoodDetectorOptions& options) {
    scene.rgb(cv::Rect(318, 220, 4, 40)).setTo(crease);
    scene.evidence = FindEvidence(scene.rgb, scene.height_mm, scene.valid,
                                  scene.plate, FoodDetectorOptions());
    return ItemLabels(GrowAndMerge(
        scene, {cv::Rect(270, 230, 10, 20), cv::Rect(360, 230, 10, 20)},
        options));
  };
  // CIELAB L: the slabs (200, 60, 50) 47, the shaded crease 32, the faint one
  // 45.
  const cv::Scalar shaded(140, 40, 35), faint(192, 57, 48);
  EXPECT_EQ(items(shaded, FoodDetectorOptions()), 2);
  FoodDetectorOptions off;
  off.min_crease_shade_l = 0.0;
  EXPECT_EQ(items(shaded, off), 1) << "the rule is what keeps them apart";
  EXPECT_EQ(items(faint, FoodDetectorOptions()), 1);
}

// Items after seeding `seeds` on a scene of `height` (every item one colour,
// then `paint`, if given, over the RGB) and growing and merging, with the
// valley lift PlantSeeds measures.
int MergedItems(const cv::Mat& height, const std::vector<cv::Rect>& seeds,
                const FoodDetectorOptions& options,
                const std::function<void(cv::Mat&)>& paint = nullptr) {
  Scene scene = MakeScene(height, height > 0.0f);
  if (paint) {
    paint(scene.rgb);
    scene.evidence = FindEvidence(scene.rgb, scene.height_mm, scene.valid,
                                  scene.plate, FoodDetectorOptions());
  }
  const std::optional<Regions> planted =
      PlantSeeds(scene.evidence, scene.height_mm, options);
  EXPECT_TRUE(planted.has_value());
  return ItemLabels(GrowAndMerge(scene, seeds, options, planted->valley_mm));
}

// `height` seeded with `seeds` (painted by `paint`, if given, as in
// MergedItems) makes `with_defaults` items with the default options and
// `with_changed` with `changed` (one rule's option changed).
void ExpectItemsWithAndWithout(
    const cv::Mat& height, const std::vector<cv::Rect>& seeds,
    int with_defaults, const FoodDetectorOptions& changed, int with_changed,
    const std::function<void(cv::Mat&)>& paint = nullptr) {
  EXPECT_EQ(MergedItems(height, seeds, FoodDetectorOptions(), paint),
            with_defaults);
  EXPECT_EQ(MergedItems(height, seeds, changed, paint), with_changed)
      << "with the rule's option changed";
}

// A celery-like stick: a U channel 160 px long, walls 8 px wide and 12 mm
// high either side of a floor 24 px wide at 6 mm.
cv::Mat UChannel() {
  cv::Mat channel(kH, kW, CV_32FC1, cv::Scalar(0));
  channel(cv::Rect(240, 220, 160, 40)).setTo(12.0f);
  channel(cv::Rect(240, 228, 160, 24)).setTo(6.0f);
  return channel;
}

// Rods 40 px wide and 160 px long along x (u 240-399), centred on the rows
// `centres`, 12 mm high at the crest and `profile(d)` of that at d (0-1) of
// the half width from it (the higher wins where two overlap).
cv::Mat RodsAlongX(const std::vector<double>& centres,
                   double (*profile)(double)) {
  cv::Mat rods(kH, kW, CV_32FC1, cv::Scalar(0));
  for (int v = 0; v < kH; ++v) {
    double height = 0.0;
    for (const double centre : centres) {
      const double across = std::fabs(centre - v) / 20.0;
      if (across < 1.0) height = std::max(height, 12.0 * profile(across));
    }
    if (height > 0.0) {
      rods(cv::Rect(240, v, 160, 1)).setTo(static_cast<float>(height));
    }
  }
  return rods;
}
double RoundProfile(double d) { return std::sqrt(1.0 - d * d); }
double SlopingProfile(double d) { return 1.0 - d * d; }
// Seeds for two rods side by side (centres 220.5 and 259.5), one each.
std::vector<cv::Rect> RodsSideBySideSeeds() {
  return {cv::Rect(250, 215, 140, 10), cv::Rect(250, 255, 140, 10)};
}

TEST(DetectorStagesTest,
     MergeJoinsAChannelOrRodCutCrosswiseNotTwoTouchingRods) {
  // Each shape lies along x, seeded at its two ends: one item, and two with
  // the rule that joins it turned off. The U channel: the seam between the
  // two halves crosses the floor, which the closing lifts all along the
  // channel, so the valley runs across the seam. A rod whose sides slope (a
  // parabola across: its mean height is 2/3 of its crest, under the 0.8 of
  // the lower region's top that a seam must reach): the seam runs across
  // that profile, and so do the flanks beside it, as high as the seam, with
  // no dip anywhere.
  FoodDetectorOptions no_valley_across;
  no_valley_across.min_valley_flank_share = 0.0;
  ExpectItemsWithAndWithout(
      UChannel(), {cv::Rect(245, 222, 10, 36), cv::Rect(385, 222, 10, 36)}, 1,
      no_valley_across, 2);
  FoodDetectorOptions no_seam_as_high;
  no_seam_as_high.min_seam_flank_height_share = 0.0;
  ExpectItemsWithAndWithout(
      RodsAlongX({239.5}, SlopingProfile),
      {cv::Rect(245, 225, 10, 30), cv::Rect(385, 225, 10, 30)}, 1,
      no_seam_as_high, 2);
  // Two wedges along x meeting at their thin edges in a trough (2 mm on the
  // seam, row 240, rising 0.085 mm/px to 5 mm at their outer edges): the
  // closing lifts the seam 1.2 mm, under the 1.5 mm limit, so no dip; the
  // seam is under 0.8 of the top, and the flanks 5 px away are 1.2 times
  // as high as it. Two, and one when a seam at half its flanks' height
  // would do.
  cv::Mat wedges(kH, kW, CV_32FC1, cv::Scalar(0));
  for (int v = 205; v < 276; ++v) {
    wedges(cv::Rect(240, v, 160, 1))
        .setTo(static_cast<float>(2.0 + 0.085 * std::fabs(v - 239.5)));
  }
  FoodDetectorOptions half_as_high;
  half_as_high.min_seam_flank_height_share = 0.5;
  ExpectItemsWithAndWithout(
      wedges, {cv::Rect(250, 208, 140, 10), cv::Rect(250, 262, 140, 10)}, 2,
      half_as_high, 1);
  // Two rods touching side by side, round or sloping, seeded one each, meet
  // in a crease that the lift follows and their flanks rise from: two.
  for (const auto profile : {RoundProfile, SlopingProfile}) {
    EXPECT_EQ(MergedItems(RodsAlongX({220.5, 259.5}, profile),
                          RodsSideBySideSeeds(), FoodDetectorOptions()),
              2);
  }
}

TEST(DetectorStagesTest, MergeKeepsTwoDiscsTouchingAtAShortContactApart) {
  // Two flat-topped discs (radius 28 px, 10 mm high, like banana coins)
  // whose centres are 54 px apart touch along a chord of about 15 px: no
  // valley, no step, one colour, so only the short contact says they are
  // two. Seeded one each: two, and one without the rule. One disc seeded at
  // both sides is cut by the watershed along its whole width (a seam of
  // about 53 px against half discs of about 1,100 px: 1.6): one.
  const auto discs = [](const std::vector<cv::Point>& centres, int radius) {
    cv::Mat height(kH, kW, CV_32FC1, cv::Scalar(0));
    for (const cv::Point& centre : centres) {
      cv::circle(height, centre, radius, cv::Scalar(10.0), cv::FILLED);
    }
    return height;
  };
  FoodDetectorOptions off;
  off.min_contact_seam_share = 0.0;
  ExpectItemsWithAndWithout(
      discs({{290, 240}, {344, 240}}, 28),
      {cv::Rect(275, 230, 10, 20), cv::Rect(349, 230, 10, 20)}, 2, off, 1);
  ExpectItemsWithAndWithout(
      discs({{317, 240}}, 28),
      {cv::Rect(295, 230, 10, 20), cv::Rect(329, 230, 10, 20)}, 1, off, 1);
  // Regions under min_contact_part_px are not held to it: two small discs
  // (radius 11 px, about 330 px each once the outline is ridge) touching
  // along a chord of about 7 px, well under half their square root, are
  // one item by colour, and two when parts from 100 px count.
  FoodDetectorOptions small_parts;
  small_parts.min_contact_part_px = 100;
  ExpectItemsWithAndWithout(
      discs({{310, 240}, {331, 240}}, 11),
      {cv::Rect(302, 238, 4, 4), cv::Rect(335, 238, 4, 4)}, 1, small_parts, 2);
}

TEST(DetectorStagesTest, MergeMeasuresAShortContactAlongTheSeam) {
  // A flat stick 120 x 20 px (10 mm high) seeded at both ends, lying along
  // the image's rows and at 45 degrees: its halves (about 1,100 px) meet
  // across its width, about 18 px, 0.55-0.6 of their square root, so the
  // colour test merges them: one. At 45 degrees the watershed draws that
  // seam with only about 14 pixels (one per step along its main axis); read
  // as a length that would be 0.42 and keep the halves apart. With the
  // share at 0.7 both are two. The straight-band rule and the stick join,
  // which could rejoin two halves of a stick, are off.
  const auto stick = [](double angle_deg) {
    cv::Mat height(kH, kW, CV_32FC1, cv::Scalar(0));
    const cv::RotatedRect rect({320.0f, 240.0f}, {120.0f, 20.0f},
                               static_cast<float>(angle_deg));
    cv::Point2f corners[4];
    rect.points(corners);
    const std::vector<cv::Point> polygon(corners, corners + 4);
    cv::fillConvexPoly(height, polygon, cv::Scalar(10.0));
    // Seeds 6 x 6 px, 12 px in from either end along the axis.
    const double c = std::cos(angle_deg * CV_PI / 180.0);
    const double s = std::sin(angle_deg * CV_PI / 180.0);
    const std::vector<cv::Rect> seeds = {
        cv::Rect(cvRound(320 - 48 * c) - 3, cvRound(240 - 48 * s) - 3, 6, 6),
        cv::Rect(cvRound(320 + 48 * c) - 3, cvRound(240 + 48 * s) - 3, 6, 6)};
    return std::make_pair(height, seeds);
  };
  FoodDetectorOptions no_stick_rules;
  no_stick_rules.min_stick_seed_elongation = 0.0;
  no_stick_rules.min_join_fill = 2.0;
  FoodDetectorOptions stricter = no_stick_rules;
  stricter.min_contact_seam_share = 0.7;
  for (const double angle : {0.0, 45.0}) {
    const auto [height, seeds] = stick(angle);
    EXPECT_EQ(MergedItems(height, seeds, no_stick_rules), 1)
        << "at " << angle << " degrees";
    EXPECT_EQ(MergedItems(height, seeds, stricter), 2)
        << "at " << angle << " degrees, share 0.7";
  }
}

TEST(DetectorStagesTest, MergeJoinsAStickCutLengthwiseNotASliceAtItsEnd) {
  // The U channel above seeded along its length, wall, floor, wall: the
  // floor stands 6 mm below the walls (a step, one part's top twice the
  // other's) and the closing lifts it (a dip), so the merge keeps the three
  // apart; together they make one straight band. A dome of the same colour
  // touching the stick's end fills the rectangle around both as well, but
  // it is not long: it stays apart. Two long strips side by side and
  // staggered leave much of their rectangle empty: they stay apart. A
  // floor of another colour is not joined; one in the walls' shade is.
  const cv::Mat channel = UChannel();
  const std::vector<cv::Rect> lengthwise = {cv::Rect(245, 221, 150, 5),
                                            cv::Rect(245, 232, 150, 16),
                                            cv::Rect(245, 254, 150, 5)};
  FoodDetectorOptions off;
  off.min_stick_seed_elongation = 0.0;
  ExpectItemsWithAndWithout(channel, lengthwise, 1, off, 3);
  // The channel's floor painted `colour`.
  const auto floor_in = [](const cv::Scalar& colour) {
    return [colour](cv::Mat& rgb) {
      rgb(cv::Rect(240, 228, 160, 24)).setTo(colour);
    };
  };
  // The floor in another colour: three items, however they line up.
  FoodDetectorOptions any_colour;
  any_colour.min_colour_distance = 1000.0;
  ExpectItemsWithAndWithout(channel, lengthwise, 3, any_colour, 1,
                            floor_in(cv::Scalar(60, 170, 60)));
  // The floor in the walls' shade, (146, 41, 34), their colour in half the
  // light (linear RGB): CIELAB L 34 against 47, 19 units from the walls'
  // colour, but 0.3 from it in other light (5-7 if the 16 in L + 16 were
  // left out). One item; three when only the colour distance counts.
  FoodDetectorOptions distance_only;
  distance_only.max_stick_shade_distance = 0.0;
  ExpectItemsWithAndWithout(channel, lengthwise, 1, distance_only, 3,
                            floor_in(cv::Scalar(146, 41, 34)));
  // A pale floor of the walls' hue, (215, 150, 140): L 68, hue 33 degrees
  // against 35, but chroma 28 against 67, which more light does not do: 62
  // units from the walls' colour in other light. Three items.
  const auto pale_floor = floor_in(cv::Scalar(215, 150, 140));
  EXPECT_EQ(MergedItems(channel, lengthwise, FoodDetectorOptions(), pale_floor),
            3);
  // A dome of radius 20 px (12 mm high) against the channel's right end.
  cv::Mat with_dome = channel.clone();
  for (int v = 220; v < 260; ++v) {
    for (int u = 400; u < 440; ++u) {
      const double r = std::hypot(u - 419.5, v - 239.5) / 20.0;
      if (r < 1.0) {
        with_dome.at<float>(v, u) =
            static_cast<float>(12.0 * std::sqrt(1.0 - r * r));
      }
    }
  }
  std::vector<cv::Rect> with_dome_seeds = lengthwise;
  with_dome_seeds.push_back(cv::Rect(412, 232, 16, 16));
  EXPECT_EQ(MergedItems(with_dome, with_dome_seeds, FoodDetectorOptions()), 2);
  FoodDetectorOptions any_part;
  any_part.min_stick_part_elongation = 0.0;
  EXPECT_EQ(MergedItems(with_dome, with_dome_seeds, any_part), 1);
  // Two long strips, one lying on the other's half-length (12 and 6 mm, a
  // step), each seeded along its length as PlantSeeds seeds them (cut at
  // the step): both long and in line, but together they fill 0.67 of the
  // rectangle around them.
  cv::Mat staggered(kH, kW, CV_32FC1, cv::Scalar(0));
  staggered(cv::Rect(240, 232, 160, 12)).setTo(6.0f);
  staggered(cv::Rect(320, 220, 160, 12)).setTo(12.0f);
  FoodDetectorOptions any_fill;
  any_fill.min_stick_fill = 0.0;
  ExpectItemsWithAndWithout(
      staggered, {cv::Rect(245, 235, 150, 6), cv::Rect(325, 223, 150, 6)}, 2,
      any_fill, 1);
}

TEST(DetectorStagesTest, MergeTakesAPaleStickFloorInShadeNotAGreyOne) {
  // A pale beige stick, (200, 195, 185), CIELAB chroma 6, cut lengthwise:
  // walls 16 px wide (12 mm) either side of a floor 12 px wide (6 mm), so
  // a wall starts the band. Its floor in half the light, (146, 143, 135),
  // is 0.4-0.5 units from the walls' colour in other light: one item. A
  // grey floor, (70, 70, 70), is 2.7 units from it one way (the walls'
  // colour scaled down to the grey's lightness keeps little chroma) and 5.6
  // the other (the grey scaled up has none): three items.
  cv::Mat channel(kH, kW, CV_32FC1, cv::Scalar(0));
  channel(cv::Rect(240, 220, 160, 44)).setTo(12.0f);
  channel(cv::Rect(240, 236, 160, 12)).setTo(6.0f);
  const std::vector<cv::Rect> seeds = {cv::Rect(245, 222, 150, 10),
                                       cv::Rect(245, 239, 150, 6),
                                       cv::Rect(245, 251, 150, 10)};
  const auto floor_in = [](const cv::Scalar& colour) {
    return [colour](cv::Mat& rgb) {
      rgb(cv::Rect(240, 220, 160, 44)).setTo(cv::Scalar(200, 195, 185));
      rgb(cv::Rect(240, 236, 160, 12)).setTo(colour);
    };
  };
  EXPECT_EQ(MergedItems(channel, seeds, FoodDetectorOptions(),
                        floor_in(cv::Scalar(146, 143, 135))),
            1);
  EXPECT_EQ(MergedItems(channel, seeds, FoodDetectorOptions(),
                        floor_in(cv::Scalar(70, 70, 70))),
            3);
}

TEST(DetectorStagesTest, MergeJoinsAStickWhoseFloorWanders) {
  // A U channel as above, but 44 px wide, whose floor (24 px wide, 6 mm)
  // wanders 6 px either side of the stick's axis between walls 4-16 px wide
  // (12 mm), seeded wall, floor, wall. The rectangle around the floor and
  // either wall takes in the far wall where the floor swings towards it, so
  // the floor and a wall fill it only when the far wall, which the band may
  // take next, counts.
  cv::Mat channel(kH, kW, CV_32FC1, cv::Scalar(0));
  channel(cv::Rect(240, 220, 160, 44)).setTo(12.0f);
  for (int u = 240; u < 400; ++u) {
    const int centre =
        cvRound(242.0 + 6.0 * std::sin(CV_PI * (u - 240) / 20.0));
    channel(cv::Rect(u, centre - 12, 1, 24)).setTo(6.0f);
  }
  const std::vector<cv::Rect> seeds = {cv::Rect(245, 221, 150, 3),
                                       cv::Rect(245, 238, 150, 8),
                                       cv::Rect(245, 260, 150, 3)};
  // The floor a shade darker (CIELAB distance 4), so the parts end where
  // the floor does.
  const auto shade_floor = [&channel](cv::Mat& rgb) {
    rgb.setTo(cv::Scalar(188, 56, 47), channel == 6.0f);
  };
  EXPECT_EQ(MergedItems(channel, seeds, FoodDetectorOptions(), shade_floor), 1);
  FoodDetectorOptions own_parts_only;
  own_parts_only.stick_fill_counts_long_parts = false;
  EXPECT_EQ(MergedItems(channel, seeds, own_parts_only, shade_floor), 3);
}

TEST(DetectorStagesTest, MergeJoinsABandAcrossAnItemNotAnItemBetweenTwo) {
  // A halved strawberry cut face up: a flat red oval (12 mm) with a pale
  // core running its length, from outline to outline, seeded as flesh,
  // core, flesh. The core is not inside food (its ends meet the plate) and
  // its colour is far from the flesh's, but it is a band between two parts
  // of one colour: one item (but not when the band is darker than both: a
  // shaded crease). A pale disc touching two red discs in a row
  // shares only short seams with them: three items. A pale sliver smaller
  // than a seed between two red slabs does not join them.
  const auto items = [](const cv::Mat& height,
                        const std::function<void(cv::Mat&)>& paint,
                        const std::vector<cv::Rect>& seeds,
                        const FoodDetectorOptions& options) {
    Scene scene = MakeScene(height, height > 0.0f);
    paint(scene.rgb);
    scene.evidence = FindEvidence(scene.rgb, scene.height_mm, scene.valid,
                                  scene.plate, FoodDetectorOptions());
    return ItemLabels(GrowAndMerge(scene, seeds, options));
  };
  // CIELAB: the flesh (200, 60, 50) is L 47, hue 35 degrees; the core L 89,
  // chroma 14, hue 67 degrees, too far round to be a highlight on it.
  const cv::Scalar pale(245, 220, 200);
  FoodDetectorOptions off;
  off.min_sandwich_share = 0.0;

  cv::Mat oval(kH, kW, CV_32FC1, cv::Scalar(0));
  cv::ellipse(oval, {320, 240}, {50, 28}, 0, 0, 360, cv::Scalar(12.0),
              cv::FILLED);
  const auto core = [&](cv::Mat& rgb) {
    rgb(cv::Rect(260, 234, 120, 12))
        .setTo(pale, oval(cv::Rect(260, 234, 120, 12)) > 0.0f);
  };
  const std::vector<cv::Rect> strips = {cv::Rect(300, 218, 40, 6),
                                        cv::Rect(300, 237, 40, 6),
                                        cv::Rect(300, 256, 40, 6)};
  EXPECT_EQ(items(oval, core, strips, FoodDetectorOptions()), 1);
  EXPECT_EQ(items(oval, core, strips, off), 3)
      << "without the rule, colour keeps the core apart";
  // A valley along the core's seams (the closing lifts them 5 mm) keeps
  // the parts apart; so do two strips of different colours.
  {
    Scene scene = MakeScene(oval, oval > 0.0f);
    core(scene.rgb);
    scene.evidence = FindEvidence(scene.rgb, scene.height_mm, scene.valid,
                                  scene.plate, FoodDetectorOptions());
    cv::Mat lifted(kH, kW, CV_32FC1, cv::Scalar(0));
    lifted(cv::Rect(260, 230, 120, 20)).setTo(5.0f);
    EXPECT_EQ(
        ItemLabels(GrowAndMerge(scene, strips, FoodDetectorOptions(), lifted)),
        3);
  }
  // A core that stops short of the left end, where the two strips touch
  // each other: joined, unless the strips' own seam there has a valley
  // (lifted 5 mm), which makes them two items whatever lies between them.
  // (The inside rule is off: a core open at one end only is nearly inside.)
  {
    FoodDetectorOptions no_inside;
    no_inside.min_enclosed_share = 2.0;
    const auto short_core = [&](cv::Mat& rgb) {
      rgb(cv::Rect(286, 234, 94, 12))
          .setTo(pale, oval(cv::Rect(286, 234, 94, 12)) > 0.0f);
    };
    const auto joined = [&](const cv::Mat& lift) {
      Scene scene = MakeScene(oval, oval > 0.0f);
      short_core(scene.rgb);
      scene.evidence = FindEvidence(scene.rgb, scene.height_mm, scene.valid,
                                    scene.plate, FoodDetectorOptions());
      return ItemLabels(GrowAndMerge(scene, strips, no_inside, lift));
    };
    cv::Mat lift(kH, kW, CV_32FC1, cv::Scalar(0));
    EXPECT_EQ(joined(lift), 1);
    lift(cv::Rect(266, 235, 18, 10)).setTo(5.0f);
    EXPECT_EQ(joined(lift), 3);
    // So does a step: the lower strip 16 mm high, the core 13 mm, the upper
    // strip 10 mm. Each seam of the core is flush enough (13 / 10, 16 / 13,
    // under 1.5), but where the strips meet one stands 1.6 times the other.
    cv::Mat steps = oval.clone();
    steps.rowRange(0, 234).setTo(10.0f, oval.rowRange(0, 234) > 0.0f);
    steps.rowRange(246, kH).setTo(16.0f, oval.rowRange(246, kH) > 0.0f);
    steps.rowRange(234, 246).colRange(0, 286).setTo(
        16.0f, oval.rowRange(234, 246).colRange(0, 286) > 0.0f);
    steps.rowRange(234, 246).colRange(286, kW).setTo(
        13.0f, oval.rowRange(234, 246).colRange(286, kW) > 0.0f);
    Scene stepped = MakeScene(steps, steps > 0.0f);
    short_core(stepped.rgb);
    stepped.evidence =
        FindEvidence(stepped.rgb, stepped.height_mm, stepped.valid,
                     stepped.plate, FoodDetectorOptions());
    EXPECT_EQ(ItemLabels(GrowAndMerge(stepped, strips, no_inside)), 3);
  }
  const auto green_below = [&](cv::Mat& rgb) {
    core(rgb);
    rgb(cv::Rect(260, 246, 120, 30))
        .setTo(cv::Scalar(90, 170, 60),
               oval(cv::Rect(260, 246, 120, 30)) > 0.0f);
  };
  EXPECT_EQ(items(oval, green_below, strips, FoodDetectorOptions()), 3);
  // The same band, dark (L 25 against the flesh's 47): the shaded crease
  // between two touching items grown into a region of its own.
  const auto crease = [&](cv::Mat& rgb) {
    rgb(cv::Rect(260, 234, 120, 12))
        .setTo(cv::Scalar(110, 30, 28),
               oval(cv::Rect(260, 234, 120, 12)) > 0.0f);
  };
  EXPECT_EQ(items(oval, crease, strips, FoodDetectorOptions()), 3);
  FoodDetectorOptions unshaded;
  unshaded.min_crease_shade_l = 0.0;
  EXPECT_EQ(items(oval, crease, strips, unshaded), 1)
      << "only its shade keeps the dark band from joining";

  cv::Mat row(kH, kW, CV_32FC1, cv::Scalar(0));
  for (const int u : {262, 320, 378}) {
    cv::circle(row, {u, 240}, 30, cv::Scalar(12.0), cv::FILLED);
  }
  const auto middle = [&](cv::Mat& rgb) {
    cv::circle(rgb, {320, 240}, 30, pale, cv::FILLED);
  };
  const std::vector<cv::Rect> discs = {cv::Rect(257, 235, 10, 10),
                                       cv::Rect(315, 235, 10, 10),
                                       cv::Rect(373, 235, 10, 10)};
  EXPECT_EQ(items(row, middle, discs, FoodDetectorOptions()), 3);
  FoodDetectorOptions loose;  // the two seams are 30 of its 168 ridge pixels
  loose.min_sandwich_share = 0.15;
  EXPECT_EQ(items(row, middle, discs, loose), 1)
      << "only the seams' share keeps the discs apart";

  cv::Mat slabs(kH, kW, CV_32FC1, cv::Scalar(0));
  slabs(cv::Rect(260, 220, 58, 40)).setTo(12.0f);
  slabs(cv::Rect(323, 220, 58, 40)).setTo(12.0f);
  slabs(cv::Rect(318, 238, 5, 5)).setTo(12.0f);  // 25 px, under a seed's 30
  const auto sliver = [&](cv::Mat& rgb) {
    rgb(cv::Rect(318, 238, 5, 5)).setTo(pale);
  };
  const std::vector<cv::Rect> two_and_sliver = {cv::Rect(270, 230, 10, 20),
                                                cv::Rect(319, 239, 3, 3),
                                                cv::Rect(360, 230, 10, 20)};
  EXPECT_EQ(items(slabs, sliver, two_and_sliver, FoodDetectorOptions()), 3);
  FoodDetectorOptions any_band;
  any_band.min_seed_px = 0;
  EXPECT_EQ(items(slabs, sliver, two_and_sliver, any_band), 1)
      << "the sliver is what would join them";
}

// Two flat items of one colour, the second partly lying on the first: the
// lower one shows as a strip [240, 240 + shown) x [220, 260) of
// `lower_mm`, the upper one [240 + shown, 340) x [220, 260) stands
// `upper_mm` high. A rounded rim of `rim_px` rises from the one to the
// other over the upper item's first columns.
Scene Overlapping(int shown, float lower_mm, float upper_mm, int rim_px = 0) {
  cv::Mat height(kH, kW, CV_32FC1, cv::Scalar(0));
  height(cv::Rect(240, 220, shown, 40)).setTo(lower_mm);
  height(cv::Rect(240 + shown, 220, 100 - shown, 40)).setTo(upper_mm);
  for (int i = 0; i < rim_px; ++i) {
    height(cv::Rect(240 + shown + i, 220, 1, 40))
        .setTo(lower_mm + (upper_mm - lower_mm) * (i + 1) / (rim_px + 1));
  }
  return MakeScene(height, height > 0.0f);
}

// PlantSeeds on an Overlapping scene: with the default options the strip
// (x 250) and the item on it (x 320) get a seed each; with `without`, the
// rule under test switched off or narrowed, one seed covers both.
void ExpectTheStripCutOnlyByDefault(const Scene& scene,
                                    const FoodDetectorOptions& without) {
  std::optional<Regions> seeds =
      PlantSeeds(scene.evidence, scene.height_mm, FoodDetectorOptions());
  ASSERT_TRUE(seeds.has_value());
  EXPECT_EQ(seeds->background, 3);
  EXPECT_NE(seeds->markers.at<int>(240, 250), seeds->markers.at<int>(240, 320));
  seeds = PlantSeeds(scene.evidence, scene.height_mm, without);
  ASSERT_TRUE(seeds.has_value());
  EXPECT_EQ(seeds->background, 2);
}

TEST(DetectorStagesTest, PlantSeedsCutsAtTheStepOfAnItemLyingOnAnother) {
  // The lower item's strip (10 mm) is above half the upper one's top
  // (16 mm), so it joins the upper seed; only the step cut parts them.
  FoodDetectorOptions no_step;
  no_step.cliff_window_px = 0;
  ExpectTheStripCutOnlyByDefault(Overlapping(30, 10.0f, 16.0f), no_step);
}

TEST(DetectorStagesTest, PlantSeedsCutsAtTheRoundedRimOfAnItemLyingOnAnother) {
  // A slice's rounded rim spreads its 11 mm step over 8 px (1.4 mm per px):
  // a 5 px window sees 2.7 mm of it, under the 3.25 mm a 13 mm strip needs;
  // the 7 px window sees 4.1 mm.
  FoodDetectorOptions narrow;
  narrow.cliff_window_px = 5;
  ExpectTheStripCutOnlyByDefault(Overlapping(30, 13.0f, 24.0f, 7), narrow);
}

TEST(DetectorStagesTest, PlantSeedsSeedsATerraceBelowHalfTheItemOnIt) {
  // A 10 px strip of 6 mm beside a 16 mm item: below half of the local top
  // everywhere, so only the terrace rule seeds it.
  const Scene scene = Overlapping(10, 6.0f, 16.0f);
  std::optional<Regions> seeds =
      PlantSeeds(scene.evidence, scene.height_mm, FoodDetectorOptions());
  ASSERT_TRUE(seeds.has_value());
  EXPECT_EQ(seeds->background, 3);
  EXPECT_GT(seeds->markers.at<int>(240, 243), 0);
  EXPECT_NE(seeds->markers.at<int>(240, 243), seeds->markers.at<int>(240, 320));
  FoodDetectorOptions no_terraces;
  no_terraces.min_terrace_px = 0;
  seeds = PlantSeeds(scene.evidence, scene.height_mm, no_terraces);
  ASSERT_TRUE(seeds.has_value());
  EXPECT_EQ(seeds->background, 2);
  // A single flat item has no terrace: its rim is too thin to seed.
  cv::Mat mask;
  const Scene single = MakeScene(Domes({{320, 240}}, &mask), mask);
  seeds = PlantSeeds(single.evidence, single.height_mm, FoodDetectorOptions());
  ASSERT_TRUE(seeds.has_value());
  EXPECT_EQ(seeds->background, 2);
}

TEST(DetectorStagesTest, MergeKeepsAnItemApartFromTheOneLyingOnIt) {
  // Same colour, no valley between them: only the ratio of their tops
  // (16 / 10) says that one lies on the other. The upper item's edge is
  // shaded darker (as rendered), so the watershed's ridge follows it.
  Scene scene = Overlapping(30, 10.0f, 16.0f);
  scene.rgb(cv::Rect(270, 220, 2, 40)).setTo(cv::Scalar(150, 45, 38));
  auto grow = [&] {
    Regions regions;
    regions.markers = cv::Mat(kH, kW, CV_32SC1, cv::Scalar(0));
    regions.markers(cv::Rect(245, 230, 15, 20)).setTo(1);
    regions.markers(cv::Rect(300, 230, 20, 20)).setTo(2);
    regions.background = 3;
    regions.valley_mm = cv::Mat(kH, kW, CV_32FC1, cv::Scalar(0));
    GrowRegions(scene.rgb, scene.evidence, scene.plate.plate, regions);
    return regions;
  };
  Regions regions = grow();
  MergeSplitItems(scene.evidence, scene.height_mm, scene.valid,
                  FoodDetectorOptions(), regions);
  EXPECT_EQ(ItemLabels(regions), 2);
  FoodDetectorOptions any_ratio;
  any_ratio.max_merge_top_ratio = 1e9;
  regions = grow();
  MergeSplitItems(scene.evidence, scene.height_mm, scene.valid, any_ratio,
                  regions);
  EXPECT_EQ(ItemLabels(regions), 1);
}

// A red stick (10 mm) with a green item lying across its middle (24 mm):
// the stick shows as two parts, one on each side.
Scene StickUnderAnItem(int right_part_shift_v) {
  cv::Mat height(kH, kW, CV_32FC1, cv::Scalar(0));
  height(cv::Rect(200, 230, 100, 20)).setTo(10.0f);
  height(cv::Rect(340, 230 + right_part_shift_v, 100, 20)).setTo(10.0f);
  const cv::Rect across(300, 200, 40, 80);
  height(across).setTo(24.0f);
  Scene scene = MakeScene(height, height > 0.0f);
  scene.rgb(across).setTo(cv::Scalar(60, 170, 60));
  scene.evidence = FindEvidence(scene.rgb, scene.height_mm, scene.valid,
                                scene.plate, FoodDetectorOptions());
  return scene;
}

Regions GrowThree(const Scene& scene, int right_part_shift_v) {
  Regions regions;
  regions.markers = cv::Mat(kH, kW, CV_32SC1, cv::Scalar(0));
  regions.markers(cv::Rect(220, 235, 20, 10)).setTo(1);
  regions.markers(cv::Rect(400, 235 + right_part_shift_v, 20, 10)).setTo(2);
  regions.markers(cv::Rect(310, 220, 20, 40)).setTo(3);
  regions.background = 4;
  regions.valley_mm = cv::Mat(kH, kW, CV_32FC1, cv::Scalar(0));
  GrowRegions(scene.rgb, scene.evidence, scene.plate.plate, regions);
  return regions;
}

TEST(DetectorStagesTest, MergeJoinsTheTwoPartsOfAStickUnderAnItem) {
  const Scene scene = StickUnderAnItem(0);
  Regions regions = GrowThree(scene, 0);
  ASSERT_EQ(ItemLabels(regions), 3);
  MergeSplitItems(scene.evidence, scene.height_mm, scene.valid,
                  FoodDetectorOptions(), regions);
  EXPECT_EQ(ItemLabels(regions), 2);
  EXPECT_EQ(regions.markers.at<int>(240, 210),
            regions.markers.at<int>(240, 430));
  EXPECT_NE(regions.markers.at<int>(240, 210),
            regions.markers.at<int>(240, 320));

  FoodDetectorOptions never;
  never.min_join_fill = 2;
  regions = GrowThree(scene, 0);
  MergeSplitItems(scene.evidence, scene.height_mm, scene.valid, never, regions);
  EXPECT_EQ(ItemLabels(regions), 3);

  // Two sticks that do not line up (the line between them crosses the
  // plate below the item) stay two.
  const Scene apart = StickUnderAnItem(45);
  regions = GrowThree(apart, 45);
  MergeSplitItems(apart.evidence, apart.height_mm, apart.valid,
                  FoodDetectorOptions(), regions);
  EXPECT_EQ(ItemLabels(regions), 3);
}

// Red parts (10 mm: rectangles and discs (x, y, radius)) under a green item
// 24 mm high lying across them ([300, 340) x [200, 280)).
Scene PartsUnderAnItem(const std::vector<cv::Rect>& rects,
                       const std::vector<cv::Vec3i>& discs) {
  cv::Mat height(kH, kW, CV_32FC1, cv::Scalar(0));
  for (const cv::Rect& r : rects) height(r).setTo(10.0f);
  for (const cv::Vec3i& d : discs) {
    cv::circle(height, {d[0], d[1]}, d[2], cv::Scalar(10.0), cv::FILLED);
  }
  const cv::Rect across(300, 200, 40, 80);
  height(across).setTo(24.0f);
  Scene scene = MakeScene(height, height > 0.0f);
  scene.rgb(across).setTo(cv::Scalar(60, 170, 60));
  scene.evidence = FindEvidence(scene.rgb, scene.height_mm, scene.valid,
                                scene.plate, FoodDetectorOptions());
  return scene;
}

TEST(DetectorStagesTest, MergeJoinsTheShortStubsOfAStickUnderAnItem) {
  // A 20 px wide stick shows 30 px on each side of the item on it: neither
  // stub is elongated along the stick (axis ratio 1.5), and the left one is
  // seeded in two pieces.
  const Scene scene = PartsUnderAnItem(
      {cv::Rect(270, 230, 30, 20), cv::Rect(340, 230, 30, 20)}, {});
  const std::vector<cv::Rect> seeds = {
      cv::Rect(273, 235, 8, 10), cv::Rect(287, 235, 8, 10),
      cv::Rect(350, 235, 10, 10), cv::Rect(310, 220, 20, 40)};
  Regions regions = GrowAndMerge(scene, seeds, FoodDetectorOptions());
  EXPECT_EQ(ItemLabels(regions), 2);
  EXPECT_EQ(regions.markers.at<int>(240, 275),
            regions.markers.at<int>(240, 365));
  EXPECT_NE(regions.markers.at<int>(240, 275),
            regions.markers.at<int>(240, 320));
  FoodDetectorOptions never;
  never.min_join_fill = 2;
  regions = GrowAndMerge(scene, seeds, never);
  EXPECT_EQ(ItemLabels(regions), 3);  // the left stub's pieces are one
}

TEST(DetectorStagesTest, MergeJoinsAStubWhoseHighestPixelsAreTheItemsFlank) {
  // The stick's right stub (10 mm) has the flank of the item on it (18 mm)
  // along its inner 4 px, 13 % of it: its 90th percentile is the flank, so
  // by that the item (24 mm) would not stand 1.5 times above it.
  Scene scene = PartsUnderAnItem(
      {cv::Rect(250, 230, 50, 20), cv::Rect(340, 230, 30, 20)}, {});
  scene.height_mm(cv::Rect(340, 230, 4, 20)).setTo(18.0f);
  scene.evidence = FindEvidence(scene.rgb, scene.height_mm, scene.valid,
                                scene.plate, FoodDetectorOptions());
  const std::vector<cv::Rect> seeds = {cv::Rect(260, 235, 20, 10),
                                       cv::Rect(350, 235, 10, 10),
                                       cv::Rect(310, 220, 20, 40)};
  Regions regions = GrowAndMerge(scene, seeds, FoodDetectorOptions());
  EXPECT_EQ(ItemLabels(regions), 2);
  EXPECT_EQ(regions.markers.at<int>(240, 255),
            regions.markers.at<int>(240, 365));
  FoodDetectorOptions highest;
  highest.join_top_quantile = 0.9;
  regions = GrowAndMerge(scene, seeds, highest);
  EXPECT_EQ(ItemLabels(regions), 3);
}

TEST(DetectorStagesTest, MergeKeepsARoundSliceApartFromAStickUnderAnItem) {
  // A stick on the left of the item and a round slice partly under its
  // right side, in line: the rectangle around both holds plate above and
  // below the stick.
  const Scene scene =
      PartsUnderAnItem({cv::Rect(200, 230, 100, 20)}, {{352, 240, 18}});
  const std::vector<cv::Rect> seeds = {cv::Rect(220, 235, 20, 10),
                                       cv::Rect(350, 235, 10, 10),
                                       cv::Rect(310, 220, 20, 40)};
  Regions regions = GrowAndMerge(scene, seeds, FoodDetectorOptions());
  EXPECT_EQ(ItemLabels(regions), 3);
  FoodDetectorOptions any_fill;
  any_fill.min_join_fill = 0;
  regions = GrowAndMerge(scene, seeds, any_fill);
  EXPECT_EQ(ItemLabels(regions), 2);
}

TEST(DetectorStagesTest, MergeKeepsTwoRoundSlicesEitherSideOfAnItemApart) {
  // Two round slices partly under a tall item, in line: they fill the
  // rectangle around them as a stick would, but neither is elongated.
  const Scene scene = PartsUnderAnItem({}, {{288, 240, 18}, {352, 240, 18}});
  const std::vector<cv::Rect> seeds = {cv::Rect(280, 235, 10, 10),
                                       cv::Rect(350, 235, 10, 10),
                                       cv::Rect(310, 220, 20, 40)};
  Regions regions = GrowAndMerge(scene, seeds, FoodDetectorOptions());
  EXPECT_EQ(ItemLabels(regions), 3);
  FoodDetectorOptions round_too;
  round_too.min_join_elongation = 0;
  regions = GrowAndMerge(scene, seeds, round_too);
  EXPECT_EQ(ItemLabels(regions), 2);
}

// One region (label 1) drawn by `draw` on a 160x120 background (label 2).
Regions OneRegion(const std::function<void(cv::Mat&)>& draw) {
  cv::Mat mask(120, 160, CV_8UC1, cv::Scalar(0));
  draw(mask);
  Regions regions;
  regions.background = 2;
  regions.markers = cv::Mat(mask.size(), CV_32SC1, cv::Scalar(2));
  regions.markers.setTo(1, mask);
  return regions;
}

// Items after SplitAtWaists with `options` on the region `draw` draws.
int ItemsAfterSplit(const std::function<void(cv::Mat&)>& draw,
                    const FoodDetectorOptions& options) {
  Regions regions = OneRegion(draw);
  SplitAtWaists(options, regions);
  return ItemLabels(regions);
}

TEST(DetectorStagesTest, SplitAtWaistsCutsTwoTouchingDiscsApart) {
  // Two round slices of one food, one partly on the other, that grew as one
  // region: a waist between two convex lobes.
  const auto discs = [](cv::Mat& mask) {
    cv::circle(mask, {60, 60}, 22, cv::Scalar(255), cv::FILLED);
    cv::circle(mask, {96, 60}, 18, cv::Scalar(255), cv::FILLED);
  };
  Regions regions = OneRegion(discs);
  SplitAtWaists(FoodDetectorOptions(), regions);
  ASSERT_EQ(ItemLabels(regions), 2);
  EXPECT_EQ(regions.background, 3);
  const int left = regions.markers.at<int>(60, 50);
  const int right = regions.markers.at<int>(60, 105);
  EXPECT_NE(left, right);
  EXPECT_GT(left, 0);
  EXPECT_GT(right, 0);
  EXPECT_LT(std::max(left, right), regions.background);
  EXPECT_EQ(regions.markers.at<int>(5, 5), regions.background);
  // The cut runs across the waist, about where the two circles meet.
  int cut_u = -1;
  for (int u = 60; u < 96; ++u) {
    if (regions.markers.at<int>(60, u) == -1) cut_u = u;
  }
  EXPECT_NEAR(cut_u, 79, 3);

  FoodDetectorOptions off;
  off.max_waist_solidity = 0;
  EXPECT_EQ(ItemsAfterSplit(discs, off), 1);
}

TEST(DetectorStagesTest, SplitAtWaistsReadsARegionsInnerSeamsAsItsOwn) {
  // Two touching discs that grew as one region, the right one merged from
  // three parts whose seams (ridge pixels, -1) still run inside it: a V
  // from its outline to a point inside and back out. The seams are the
  // item's own. Read as notches, they cut a wedge off the right disc, and
  // what is left of it is not convex enough to be cut off at the waist.
  const auto seamed_discs = [] {
    Regions regions = OneRegion([](cv::Mat& m) {
      cv::circle(m, {60, 60}, 22, cv::Scalar(255), cv::FILLED);
      cv::circle(m, {102, 60}, 22, cv::Scalar(255), cv::FILLED);
    });
    cv::Mat seam(regions.markers.size(), CV_8UC1, cv::Scalar(0));
    cv::line(seam, {98, 36}, {110, 60}, cv::Scalar(255), 1);
    cv::line(seam, {110, 60}, {126, 56}, cv::Scalar(255), 1);
    regions.markers.setTo(-1, seam & (regions.markers == 1));
    return regions;
  };
  Regions regions = seamed_discs();
  SplitAtWaists(FoodDetectorOptions(), regions);
  ASSERT_EQ(ItemLabels(regions), 2);
  EXPECT_NE(regions.markers.at<int>(60, 50), regions.markers.at<int>(60, 100));
  EXPECT_EQ(regions.markers.at<int>(45, 112), regions.markers.at<int>(60, 100))
      << "the wedge is the right disc's";

  FoodDetectorOptions notches;
  notches.waist_fills_inner_seams = false;
  regions = seamed_discs();
  SplitAtWaists(notches, regions);
  EXPECT_EQ(ItemLabels(regions), 1);

  // A seam with another item (label 2, below the discs, across a ridge row
  // at v = 83, under flat bottoms so that the row touches nothing but the
  // discs above it and the item below) is not the region's own: it stays a
  // ridge.
  regions = seamed_discs();
  regions.markers(cv::Rect(52, 76, 17, 7)).setTo(1);
  regions.markers(cv::Rect(94, 76, 17, 7)).setTo(1);
  regions.markers.setTo(3, regions.markers == 2);
  regions.background = 3;
  regions.markers(cv::Rect(30, 83, 100, 1)).setTo(-1);
  regions.markers(cv::Rect(30, 84, 100, 6)).setTo(2);
  SplitAtWaists(FoodDetectorOptions(), regions);
  EXPECT_EQ(ItemLabels(regions), 3);
  EXPECT_EQ(cv::countNonZero(regions.markers(cv::Rect(30, 83, 100, 1)) != -1),
            0);
}

TEST(DetectorStagesTest, SplitAtWaistsReadsACrumbInARegionAsItsOwn) {
  // Two touching discs that grew as one region (label 1), as in the first
  // waist test, and a crumb of the right one (label 2: its shaded side or
  // its calyx, left on its own by the merge) at its right edge, a ridge
  // around it. Read as a notch, the crumb leaves the right disc under
  // min_waist_solidity, and the discs are not cut apart.
  const auto crumbed = [](cv::Point crumb_at, bool beside_another) {
    Regions regions = OneRegion([](cv::Mat& m) {
      cv::circle(m, {60, 60}, 22, cv::Scalar(255), cv::FILLED);
      cv::circle(m, {96, 60}, 18, cv::Scalar(255), cv::FILLED);
    });
    regions.markers.setTo(4, regions.markers == 2);
    regions.background = 4;
    cv::Mat crumb(regions.markers.size(), CV_8UC1, cv::Scalar(0));
    crumb(cv::Rect(crumb_at, cv::Size(14, 16))).setTo(255);
    crumb &= regions.markers == 1;
    cv::Mat ring;
    cv::dilate(crumb, ring, cv::Mat());
    regions.markers.setTo(-1, ring & ~crumb);
    regions.markers.setTo(2, crumb);
    if (beside_another) {
      // Another item (label 3) right of the crumb, across the ridge.
      regions.markers(cv::Rect(crumb_at.x + 12, 44, 20, 32)).setTo(3);
    }
    return regions;
  };
  // The item labels after the split (and a check that the crumb keeps its
  // pixels and its label).
  const auto split = [](Regions regions, const FoodDetectorOptions& options) {
    const int crumb_px = cv::countNonZero(regions.markers == 2);
    SplitAtWaists(options, regions);
    EXPECT_EQ(cv::countNonZero(regions.markers == 2), crumb_px)
        << "the crumb keeps its label and its pixels";
    return ItemLabels(regions);
  };
  const cv::Point at(104, 52);
  EXPECT_EQ(split(crumbed(at, false), FoodDetectorOptions()), 3)
      << "the two discs and the crumb";
  FoodDetectorOptions off;
  off.max_waist_crumb_px = 0;
  EXPECT_EQ(split(crumbed(at, false), off), 2) << "a notch: not cut";
  FoodDetectorOptions tiny;
  tiny.max_waist_crumb_px = 50;
  EXPECT_EQ(split(crumbed(at, false), tiny), 2) << "too large to be a crumb";
  EXPECT_EQ(split(crumbed(at, true), FoodDetectorOptions()), 3)
      << "it borders another item: not a crumb, the discs stay one "
         "(with the crumb and the other item, three labels)";
}

TEST(DetectorStagesTest, SplitAtWaistsLeavesABentStickWhole) {
  // A stick 24 px wide, bent in the middle (its inner side a concavity 12
  // px deep), with a notch 4 px deep on its outer side: the segment between
  // the two concavities leaves two straight, convex halves, but it is 20 px
  // long, most of the stick's width, across a region long for its width. A
  // waist between two items is narrower than both: one item; two without
  // the test.
  const auto bent = [](cv::Mat& m) {
    cv::line(m, {20, 72}, {80, 60}, cv::Scalar(255), 24);
    cv::line(m, {80, 60}, {140, 72}, cv::Scalar(255), 24);
    const std::vector<cv::Point> notch = {{74, 48}, {86, 48}, {80, 52}};
    cv::fillConvexPoly(m, notch, cv::Scalar(0));
  };
  EXPECT_EQ(ItemsAfterSplit(bent, FoodDetectorOptions()), 1);
  FoodDetectorOptions off;
  off.max_waist_cut_share = 0.0;
  EXPECT_EQ(ItemsAfterSplit(bent, off), 2);
}

TEST(DetectorStagesTest, SplitAtWaistsCutsAThinStripOffARoundItem) {
  // A disc (radius 22 px) with a bent strip 6 px wide along its lower side
  // and beyond (a banana coin that took the lit wall of the celery stick
  // beside it): the strip is not convex, so no waist cut passes, but the
  // cut along the disc leaves a convex body and a thin strip, long for its
  // width: two items; one without the strip cut.
  const auto coin_and_strip = [](cv::Mat& m) {
    cv::circle(m, {60, 50}, 22, cv::Scalar(255), cv::FILLED);
    cv::line(m, {30, 75}, {100, 75}, cv::Scalar(255), 6);
    cv::line(m, {100, 75}, {140, 45}, cv::Scalar(255), 6);
  };
  Regions regions = OneRegion(coin_and_strip);
  SplitAtWaists(FoodDetectorOptions(), regions);
  EXPECT_EQ(ItemLabels(regions), 2);
  EXPECT_NE(regions.markers.at<int>(50, 60), regions.markers.at<int>(75, 90));
  FoodDetectorOptions off;
  off.max_tail_width_px = 0.0;
  EXPECT_EQ(ItemsAfterSplit(coin_and_strip, off), 1);
  // The strip averages about 7 px wide: not thin enough for a limit of 5.
  FoodDetectorOptions narrow;
  narrow.max_tail_width_px = 5.0;
  EXPECT_EQ(ItemsAfterSplit(coin_and_strip, narrow), 1);
  // An upright oval body 1.8 times as long as wide is compact enough for the
  // default 2, not for 1.5.
  const auto oval_and_strip = [](cv::Mat& m) {
    cv::ellipse(m, {60, 47}, {15, 27}, 0, 0, 360, cv::Scalar(255), cv::FILLED);
    cv::line(m, {30, 75}, {100, 75}, cv::Scalar(255), 6);
    cv::line(m, {100, 75}, {140, 45}, cv::Scalar(255), 6);
  };
  EXPECT_EQ(ItemsAfterSplit(oval_and_strip, FoodDetectorOptions()), 2);
  FoodDetectorOptions round;
  round.max_tail_body_elongation = 1.5;
  EXPECT_EQ(ItemsAfterSplit(oval_and_strip, round), 1);
}

TEST(DetectorStagesTest, SplitAtWaistsLeavesConvexItemsAndCrescentsWhole) {
  // An oval slice, a stick, and what shows of a slice half under another
  // (a crescent: one concavity, no waist) are one item each.
  const std::vector<std::function<void(cv::Mat&)>> shapes = {
      [](cv::Mat& m) {
        cv::ellipse(m, {80, 60}, {35, 18}, 30, 0, 360, cv::Scalar(255),
                    cv::FILLED);
      },
      [](cv::Mat& m) {
        cv::rectangle(m, cv::Rect(20, 52, 120, 16), cv::Scalar(255),
                      cv::FILLED);
      },
      [](cv::Mat& m) {
        cv::circle(m, {80, 60}, 25, cv::Scalar(255), cv::FILLED);
        cv::circle(m, {80, 35}, 22, cv::Scalar(0), cv::FILLED);
      },
  };
  for (size_t i = 0; i < shapes.size(); ++i) {
    Regions regions = OneRegion(shapes[i]);
    SplitAtWaists(FoodDetectorOptions(), regions);
    EXPECT_EQ(ItemLabels(regions), 1) << "shape " << i;
    EXPECT_EQ(regions.background, 2) << "shape " << i;
  }
}

// What DescribeItems reads: a 20 mm item `food` on a plate 400 mm from the
// camera, square on (its top at 380 mm).
struct FlatPlate {
  Scene scene;
  cv::Mat raw_depth;
  Plane plane;
};

FlatPlate ItemOnAFlatPlate(const cv::Rect& food) {
  FlatPlate flat;
  cv::Mat height(kH, kW, CV_32FC1, cv::Scalar(0));
  height(food).setTo(20.0f);
  flat.scene = MakeScene(height, height > 0.0f);
  flat.raw_depth = cv::Mat(kH, kW, CV_16UC1, cv::Scalar(400));
  flat.raw_depth(food).setTo(380);
  flat.plane.n = cv::Vec3d(0, 0, -1);
  flat.plane.d = 400.0;
  return flat;
}

TEST(DetectorStagesTest, DescribeItemsGivesBoxCentreAndDepth) {
  const cv::Rect item(300, 220, 40, 20);
  const FlatPlate flat = ItemOnAFlatPlate(item);
  const Scene& scene = flat.scene;
  const cv::Mat& raw_depth = flat.raw_depth;
  const Plane& plane = flat.plane;
  Regions regions;
  regions.markers = cv::Mat(kH, kW, CV_32SC1, cv::Scalar(2));
  regions.markers(item).setTo(1);
  regions.background = 2;
  const CameraIntrinsics k;
  const std::vector<DetectedFood> foods =
      DescribeItems(regions, scene.evidence, raw_depth, scene.plate.roi, plane,
                    k, FoodDetectorOptions());
  ASSERT_EQ(foods.size(), 1u);
  EXPECT_EQ(foods[0].bbox.x, 300);
  EXPECT_EQ(foods[0].bbox.y, 220);
  EXPECT_EQ(foods[0].bbox.width, 40);
  EXPECT_EQ(foods[0].bbox.height, 20);
  EXPECT_EQ(foods[0].area_px, 800);
  EXPECT_DOUBLE_EQ(foods[0].center_u_px, 319.5);
  EXPECT_DOUBLE_EQ(foods[0].center_v_px, 229.5);
  EXPECT_DOUBLE_EQ(foods[0].depth_m, 0.38);
  EXPECT_NEAR(foods[0].center_x_m, (319.5 - k.cx) * 0.38 / k.fx, 1e-12);
  EXPECT_NEAR(std::abs(foods[0].major_axis_angle_rad), 0.0, 1e-6);
  // Height and colour agree on all but the corners (opened masks).
  EXPECT_GT(foods[0].score, 0.99);

  // Below min_item_area_m2 (a 3x3 crumb at 0.38 m is 0.03 cm^2): dropped.
  regions.markers.setTo(2);
  regions.markers(cv::Rect(300, 220, 3, 3)).setTo(1);
  EXPECT_TRUE(DescribeItems(regions, scene.evidence, raw_depth, scene.plate.roi,
                            plane, k, FoodDetectorOptions())
                  .empty());
}

TEST(DetectorStagesTest, DescribeItemsAimsAnItemInPiecesAtItsLargestPiece) {
  // A stick seen on both sides of an item lying across it (joined by the
  // merge): the centroid of all its pixels lies on the item across it, so
  // the centre is that of its larger stub. The box spans both.
  const FlatPlate flat = ItemOnAFlatPlate(cv::Rect(260, 220, 110, 20));
  Regions regions;
  regions.markers = cv::Mat(kH, kW, CV_32SC1, cv::Scalar(2));
  regions.markers(cv::Rect(260, 220, 30, 20)).setTo(1);
  regions.markers(cv::Rect(350, 220, 20, 20)).setTo(1);
  regions.background = 2;
  const std::vector<DetectedFood> foods = DescribeItems(
      regions, flat.scene.evidence, flat.raw_depth, flat.scene.plate.roi,
      flat.plane, CameraIntrinsics(), FoodDetectorOptions());
  ASSERT_EQ(foods.size(), 1u);
  EXPECT_EQ(foods[0].bbox.x, 260);
  EXPECT_EQ(foods[0].bbox.width, 110);
  EXPECT_EQ(foods[0].area_px, 1000);
  EXPECT_DOUBLE_EQ(foods[0].center_u_px, 274.5);
  EXPECT_DOUBLE_EQ(foods[0].center_v_px, 229.5);
}

TEST(DetectorStagesTest, DescribeItemsSizesAnItemByItsOwnPixels) {
  // A square region just below min_item_area_m2, ringed by watershed ridge
  // pixels that look like food and so join it: with the ring it would be
  // large enough. The size test counts the region's own pixels only.
  const FlatPlate flat = ItemOnAFlatPlate(cv::Rect(300, 200, 60, 60));
  const CameraIntrinsics k;
  const FoodDetectorOptions options;
  const double pixel_m2 = (0.38 / k.fx) * (0.38 / k.fy);
  const int threshold_px =
      static_cast<int>(std::ceil(options.min_item_area_m2 / pixel_m2));
  const auto describe = [&](int side) {
    Regions regions;
    regions.background = 2;
    regions.markers = cv::Mat(kH, kW, CV_32SC1, cv::Scalar(2));
    regions.markers(cv::Rect(310, 210, side + 2, side + 2)).setTo(-1);
    regions.markers(cv::Rect(311, 211, side, side)).setTo(1);
    return DescribeItems(regions, flat.scene.evidence, flat.raw_depth,
                         flat.scene.plate.roi, flat.plane, k, options);
  };
  const int below = static_cast<int>(std::sqrt(threshold_px - 1.0));
  ASSERT_LT(below * below, threshold_px);
  // The ring's corners touch the square only diagonally and stay out.
  ASSERT_GE(below * below + 4 * below, threshold_px);
  ASSERT_LE(below + 2, 48);  // inside the food
  EXPECT_TRUE(describe(below).empty());
  const std::vector<DetectedFood> kept = describe(below + 1);
  ASSERT_EQ(kept.size(), 1u);
  const int side = below + 1;
  EXPECT_EQ(kept[0].area_px, side * side + 4 * side);  // with its ridge
}

}  // namespace
}  // namespace bitewise::perception::detection
