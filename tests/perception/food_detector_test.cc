// The geometric detector on frames from the simulated D415: every item
// found once with a tight box (IoU >= 0.7 against the renderer's ground
// truth) on plates of up to eight foods, some touching; centre, angle and
// depth consistent with the scene; clean handling of frames without a
// plate or without depth.
#include "services/perception/food_detector.h"

#include <cmath>
#include <vector>

#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "services/perception/food_detector_stages.h"
#include "services/sim/food_catalog.h"
#include "tests/perception/test_frames.h"

namespace bitewise::perception {
namespace {

constexpr double kPi = 3.14159265358979323846;

// Greedy one-to-one matching by IoU: the best detection for each truth box.
struct Match {
  double iou = 0.0;
  int detection = -1;
};

std::vector<Match> MatchTruth(const std::vector<DetectedFood>& detected,
                              const std::vector<sim::ItemTruth>& truth) {
  std::vector<Match> matches(truth.size());
  for (size_t t = 0; t < truth.size(); ++t) {
    for (size_t d = 0; d < detected.size(); ++d) {
      const PixelBox& b = detected[d].bbox;
      const double iou =
          testing::BoxIoU(b.x, b.y, b.width, b.height, truth[t].x, truth[t].y,
                          truth[t].width, truth[t].height);
      if (iou > matches[t].iou) matches[t] = {iou, static_cast<int>(d)};
    }
  }
  return matches;
}

TEST(FoodDetectorTest, FindsEveryItemWithTightBoxesOnRenderedPlates) {
  const FoodDetector detector;
  int items = 0, touching_plates = 0;
  double worst = 1.0;
  for (uint64_t seed = 100; seed < 124; ++seed) {
    const int n_items = 1 + static_cast<int>(seed % 8);
    testing::TestScene scene =
        testing::RenderTestScene(seed, n_items, /*touching=*/true);
    absl::StatusOr<std::vector<DetectedFood>> detected =
        detector.Detect(testing::ToDecoded(scene.rendered));
    ASSERT_TRUE(detected.ok()) << detected.status();
    ASSERT_EQ(detected->size(), scene.plate.items.size()) << "seed " << seed;
    const std::vector<Match> matches =
        MatchTruth(*detected, scene.rendered.truth);
    std::vector<int> used(detected->size(), 0);
    for (size_t t = 0; t < matches.size(); ++t) {
      EXPECT_GE(matches[t].iou, 0.7) << "seed " << seed << " item " << t;
      ASSERT_GE(matches[t].detection, 0);
      EXPECT_EQ(used[matches[t].detection]++, 0) << "seed " << seed;
      worst = std::min(worst, matches[t].iou);
      ++items;
    }
    // Count plates where two items really touch (box overlap is a proxy
    // that the renderer placed them in contact).
    for (size_t a = 0; a < scene.rendered.truth.size(); ++a) {
      for (size_t b = a + 1; b < scene.rendered.truth.size(); ++b) {
        const auto& ta = scene.rendered.truth[a];
        const auto& tb = scene.rendered.truth[b];
        if (testing::BoxIoU(ta.x, ta.y, ta.width, ta.height, tb.x, tb.y,
                            tb.width, tb.height) > 0) {
          ++touching_plates;
        }
      }
    }
  }
  EXPECT_GE(items, 100);
  // The test is only meaningful if touching items were in it.
  EXPECT_GE(touching_plates, 5);
  RecordProperty("worst_iou", std::to_string(worst));
}

// Two pieces of the same food in contact, side by side and end to side:
// one colour, no edge between them, only the height valley where their
// rounded sides meet tells them apart.
TEST(FoodDetectorTest, SeparatesTouchingPiecesOfTheSameFood) {
  const FoodDetector detector;
  for (const char* name : {"carrot", "celery"}) {
    const sim::FoodType* food = sim::FindFood(name);
    ASSERT_NE(food, nullptr);
    for (const bool side_by_side : {true, false}) {
      sim::PlateScene scene;
      sim::SceneItem a;
      a.id = 1;
      a.food = food;
      a.length_m = 0.07;
      a.width_m = 0.014;
      a.height_m = 0.013;
      a.rgb = food->rgb;
      a.texture_seed = 3;
      sim::SceneItem b = a;
      b.id = 2;
      b.texture_seed = 4;
      if (side_by_side) {  // parallel, long sides touching
        a.y_m = -a.width_m / 2;
        b.y_m = a.width_m / 2;
      } else {  // an L: b's end against a's side
        b.yaw_rad = kPi / 2;
        b.x_m = 0.01;
        b.y_m = a.width_m / 2 + b.length_m / 2;
      }
      scene.items = {a, b};
      sim::RenderedFrame rendered =
          sim::RenderPlate(scene, sim::D415Intrinsics(), 5);
      absl::StatusOr<std::vector<DetectedFood>> detected =
          detector.Detect(testing::ToDecoded(rendered));
      ASSERT_TRUE(detected.ok()) << detected.status();
      ASSERT_EQ(detected->size(), 2u)
          << name << (side_by_side ? " side by side" : " end to side");
      for (const Match& m : MatchTruth(*detected, rendered.truth)) {
        EXPECT_GE(m.iou, 0.7) << name;
      }
    }
  }
}

TEST(FoodDetectorTest, CentreAngleAndDepthMatchTheScene) {
  const FoodDetector detector;
  testing::TestScene scene = testing::RenderTestScene(7, 8, false);
  absl::StatusOr<std::vector<DetectedFood>> detected =
      detector.Detect(testing::ToDecoded(scene.rendered));
  ASSERT_TRUE(detected.ok()) << detected.status();
  const std::vector<Match> matches =
      MatchTruth(*detected, scene.rendered.truth);
  const sim::PinholeIntrinsics k = scene.rendered.intrinsics;
  for (size_t i = 0; i < scene.plate.items.size(); ++i) {
    const sim::SceneItem& item = scene.plate.items[i];
    ASSERT_GE(matches[i].detection, 0);
    const DetectedFood& food = (*detected)[matches[i].detection];
    // The item's top: between the camera-to-plate distance and that less
    // the item's height.
    const double plate_m = scene.plate.camera_height_m;
    EXPECT_LT(food.depth_m, plate_m - 0.3 * item.height_m);
    EXPECT_GT(food.depth_m, plate_m - item.height_m - 0.003);
    // The 3D centre deprojects to the item's position on the plate, to
    // within a few millimetres (perspective of the item's top).
    EXPECT_NEAR(food.center_x_m, item.x_m, 0.006) << item.food->name;
    EXPECT_NEAR(food.center_y_m, item.y_m, 0.006) << item.food->name;
    EXPECT_NEAR(food.center_z_m, food.depth_m, 1e-12);
    EXPECT_NEAR(food.center_u_px, k.cx + food.center_x_m / food.depth_m * k.fx,
                1e-6);
    EXPECT_GT(food.score, 0.5);
    EXPECT_LE(food.score, 1.0);
    // Angles only mean something for elongated items; the minimum-area
    // rectangle of an ellipse is looser than that of a stick.
    const double aspect = item.length_m / item.width_m;
    if (aspect > 1.4) {
      const double diff =
          std::remainder(food.major_axis_angle_rad - item.yaw_rad, kPi);
      EXPECT_LT(std::abs(diff), aspect > 1.8 ? 0.1 : 0.35) << item.food->name;
    }
    EXPECT_GT(food.major_axis_angle_rad, -kPi / 2 - 1e-9);
    EXPECT_LE(food.major_axis_angle_rad, kPi / 2 + 1e-9);
  }
}

// The stages after FindEvidence on the whole plate box, uncropped: what
// Detect did before it cropped to the food.
std::vector<DetectedFood> DetectOnThePlateBox(const DecodedFrame& frame) {
  using namespace detection;  // NOLINT: the stages, in order
  const FoodDetectorOptions options;
  const std::optional<HeightMap> heights =
      MeasureHeight(frame.depth_mm, frame.intrinsics, options);
  if (!heights) return {};
  const std::optional<PlateRegion> plate = FindPlate(*heights, options);
  if (!plate) return {};
  const cv::Rect& roi = plate->roi;
  const cv::Mat rgb = frame.rgb(roi);
  const cv::Mat height_mm = heights->height_mm(roi);
  const cv::Mat valid = heights->valid(roi);
  const FoodEvidence evidence =
      FindEvidence(rgb, height_mm, valid, *plate, options);
  std::optional<Regions> regions = PlantSeeds(evidence, height_mm, options);
  if (!regions) return {};
  GrowRegions(rgb, evidence, plate->plate, *regions);
  MergeSplitItems(evidence, height_mm, valid, options, *regions);
  SplitAtWaists(options, *regions);
  return DescribeItems(*regions, evidence, frame.depth_mm(roi), roi,
                       heights->plane, frame.intrinsics, options);
}

TEST(FoodDetectorTest, CroppingToTheFoodChangesNothing) {
  // Detect runs the later stages on the food's box widened by FoodMargin;
  // every item must come out as it does on the whole plate box, to the bit.
  const FoodDetector detector;
  int cropped = 0, items = 0;
  for (uint64_t seed = 100; seed < 124; ++seed) {
    const int n_items = 1 + static_cast<int>(seed % 8);
    testing::TestScene scene =
        testing::RenderTestScene(seed, n_items, /*touching=*/true);
    const DecodedFrame frame = testing::ToDecoded(scene.rendered);
    absl::StatusOr<std::vector<DetectedFood>> detected = detector.Detect(frame);
    ASSERT_TRUE(detected.ok()) << detected.status();
    const std::vector<DetectedFood> whole = DetectOnThePlateBox(frame);
    ASSERT_EQ(detected->size(), whole.size()) << "seed " << seed;
    for (size_t i = 0; i < whole.size(); ++i) {
      const DetectedFood& a = (*detected)[i];
      const DetectedFood& b = whole[i];
      EXPECT_EQ(a.bbox.x, b.bbox.x) << "seed " << seed << " item " << i;
      EXPECT_EQ(a.bbox.y, b.bbox.y) << "seed " << seed << " item " << i;
      EXPECT_EQ(a.bbox.width, b.bbox.width) << "seed " << seed;
      EXPECT_EQ(a.bbox.height, b.bbox.height) << "seed " << seed;
      EXPECT_EQ(a.area_px, b.area_px) << "seed " << seed;
      EXPECT_EQ(a.center_u_px, b.center_u_px) << "seed " << seed;
      EXPECT_EQ(a.center_v_px, b.center_v_px) << "seed " << seed;
      EXPECT_EQ(a.major_axis_angle_rad, b.major_axis_angle_rad);
      EXPECT_EQ(a.depth_m, b.depth_m) << "seed " << seed;
      EXPECT_EQ(a.score, b.score) << "seed " << seed;
    }
    items += static_cast<int>(whole.size());
    // How often the crop is smaller than the plate box (else the test
    // shows nothing).
    const FoodDetectorOptions options;
    const auto heights =
        detection::MeasureHeight(frame.depth_mm, frame.intrinsics, options);
    ASSERT_TRUE(heights.has_value());
    const auto plate = detection::FindPlate(*heights, options);
    ASSERT_TRUE(plate.has_value());
    const cv::Rect& roi = plate->roi;
    const detection::FoodEvidence evidence =
        detection::FindEvidence(frame.rgb(roi), heights->height_mm(roi),
                                heights->valid(roi), *plate, options);
    cropped += detection::FoodBox(evidence, options).area() < roi.area();
  }
  EXPECT_GE(cropped, 12) << "the food's box should be smaller on most plates";
  EXPECT_EQ(detection::FoodMargin(FoodDetectorOptions()), 52);  // the docs'
  EXPECT_GE(items, 80);
}

TEST(FoodDetectorTest, EmptyPlateHasNoItems) {
  const FoodDetector detector;
  testing::TestScene scene = testing::RenderTestScene(3, 0, false);
  absl::StatusOr<std::vector<DetectedFood>> detected =
      detector.Detect(testing::ToDecoded(scene.rendered));
  ASSERT_TRUE(detected.ok()) << detected.status();
  EXPECT_TRUE(detected->empty());
}

// No plate is not an empty plate (the meal ends on an empty one): a dead
// depth stream or a scene with no flat surface is FAILED_PRECONDITION
// naming what was missing (both used to answer "no items").
TEST(FoodDetectorTest, AFrameWithoutAPlateIsFailedPrecondition) {
  DecodedFrame frame;
  frame.rgb = cv::Mat(480, 640, CV_8UC3, cv::Scalar(90, 120, 200));
  frame.depth_mm = cv::Mat(480, 640, CV_16UC1, cv::Scalar(0));  // all holes
  frame.intrinsics = CameraIntrinsics();  // the D415's at 640x480
  absl::StatusOr<std::vector<DetectedFood>> dead = FoodDetector().Detect(frame);
  EXPECT_EQ(dead.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(std::string(dead.status().message()),
              ::testing::AllOf(::testing::HasSubstr("no plate found"),
                               ::testing::HasSubstr("(0 of 307200 pixels have "
                                                    "depth)")));
  // Depth everywhere, but nothing flat: a jumble of distances.
  cv::randu(frame.depth_mm, cv::Scalar(300), cv::Scalar(2000));
  absl::StatusOr<std::vector<DetectedFood>> jumble =
      FoodDetector().Detect(frame);
  EXPECT_EQ(jumble.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(std::string(jumble.status().message()),
              ::testing::AllOf(::testing::HasSubstr("no plate found"),
                               ::testing::HasSubstr("(307200 of 307200")));
}

TEST(FoodDetectorTest, FrameWithoutDepthIsInvalidArgument) {
  testing::TestScene scene = testing::RenderTestScene(3, 2, false);
  DecodedFrame frame = testing::ToDecoded(scene.rendered);
  frame.depth_mm = cv::Mat();
  absl::StatusOr<std::vector<DetectedFood>> detected =
      FoodDetector().Detect(frame);
  EXPECT_EQ(detected.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(detected.status().message(),
              ::testing::HasSubstr("frame.depth_mm is empty"));
}

}  // namespace
}  // namespace bitewise::perception
