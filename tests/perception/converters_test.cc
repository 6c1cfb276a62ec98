// The PerceptionService's proto conversions (services/perception/
// converters.h): frames become views of the request's bytes with their
// encoding, an unknown location is refused naming its value, and detections
// and features reach the response field by field.
#include "services/perception/converters.h"

#include <string>

#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace bitewise::perception {
namespace {

using ::testing::ElementsAre;
using ::testing::HasSubstr;

TEST(PerceptionConvertersTest, AFrameIsAViewOfTheRequestsBytes) {
  v1::Frame frame;
  frame.set_width(4);
  frame.set_height(3);
  frame.set_rgb(std::string(36, '\x7f'));
  frame.set_depth_mm(std::string(24, '\x01'));
  frame.mutable_intrinsics()->set_fx(610.0);
  frame.mutable_intrinsics()->set_fy(611.0);
  frame.mutable_intrinsics()->set_cx(1.5);
  frame.mutable_intrinsics()->set_cy(1.25);
  const std::pair<v1::ImageEncoding, ImageEncoding> encodings[] = {
      {v1::IMAGE_ENCODING_RGB8, ImageEncoding::kRgb8},
      {v1::IMAGE_ENCODING_PNG, ImageEncoding::kPng},
      {v1::IMAGE_ENCODING_JPEG, ImageEncoding::kJpeg},
      {v1::IMAGE_ENCODING_UNSPECIFIED, ImageEncoding::kUnspecified},
      {static_cast<v1::ImageEncoding>(99), ImageEncoding::kUnspecified}};
  for (const auto& [wire, core] : encodings) {
    frame.set_rgb_encoding(wire);
    const FrameBytes bytes = FrameBytesFromProto(frame);
    EXPECT_EQ(bytes.encoding, core) << wire;
    EXPECT_EQ(bytes.width, 4);
    EXPECT_EQ(bytes.height, 3);
    // Views, not copies: the same memory as the proto's.
    EXPECT_EQ(bytes.rgb.data(), frame.rgb().data());
    EXPECT_EQ(bytes.rgb.size(), 36u);
    EXPECT_EQ(bytes.depth_mm.data(), frame.depth_mm().data());
    EXPECT_EQ(bytes.depth_mm.size(), 24u);
    EXPECT_EQ(bytes.intrinsics.fx, 610.0);
    EXPECT_EQ(bytes.intrinsics.fy, 611.0);
    EXPECT_EQ(bytes.intrinsics.cx, 1.5);
    EXPECT_EQ(bytes.intrinsics.cy, 1.25);
  }
}

TEST(PerceptionConvertersTest, ABoxKeepsItsCornerAndSize) {
  v1::BoundingBox box;
  box.set_x(10);
  box.set_y(20);
  box.set_width(30);
  box.set_height(40);
  const PixelBox pixels = BoxFromProto(box);
  EXPECT_EQ(pixels.x, 10);
  EXPECT_EQ(pixels.y, 20);
  EXPECT_EQ(pixels.width, 30);
  EXPECT_EQ(pixels.height, 40);
}

TEST(PerceptionConvertersTest, UnspecifiedIsIsolatedAndAnUnknownValueIsNamed) {
  EXPECT_EQ(*LocationFromProto(v1::FOOD_LOCATION_UNSPECIFIED),
            FoodLocation::kIsolated);
  EXPECT_EQ(*LocationFromProto(v1::FOOD_LOCATION_ISOLATED),
            FoodLocation::kIsolated);
  EXPECT_EQ(*LocationFromProto(v1::FOOD_LOCATION_WALL), FoodLocation::kWall);
  EXPECT_EQ(*LocationFromProto(v1::FOOD_LOCATION_LETTUCE),
            FoodLocation::kLettuce);
  const absl::Status status =
      LocationFromProto(static_cast<v1::FoodLocation>(7)).status();
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(status.message(), HasSubstr("unknown FoodLocation value 7"));
}

TEST(PerceptionConvertersTest, ADetectionReachesItsItemFieldByField) {
  DetectedFood food;
  food.bbox = {12, 34, 56, 78};
  food.center_u_px = 40.5;
  food.center_v_px = 73.25;
  food.major_axis_angle_rad = -0.7;
  food.depth_m = 0.36;
  food.center_x_m = -0.01;
  food.center_y_m = 0.02;
  food.center_z_m = 0.355;
  food.score = 0.875;
  v1::FoodItem item;
  FoodItemToProto(food, &item);
  EXPECT_EQ(item.bbox().x(), 12);
  EXPECT_EQ(item.bbox().y(), 34);
  EXPECT_EQ(item.bbox().width(), 56);
  EXPECT_EQ(item.bbox().height(), 78);
  EXPECT_EQ(item.center_px().u(), 40.5);
  EXPECT_EQ(item.center_px().v(), 73.25);
  EXPECT_EQ(item.major_axis_angle_rad(), -0.7);
  EXPECT_EQ(item.depth_m(), 0.36);
  EXPECT_EQ(item.center_camera_m().x(), -0.01);
  EXPECT_EQ(item.center_camera_m().y(), 0.02);
  EXPECT_EQ(item.center_camera_m().z(), 0.355);
  EXPECT_EQ(item.score(), 0.875);
}

TEST(PerceptionConvertersTest, FeaturesReachTheResponseInOrder) {
  Features features;
  features.context = {0.5, 0.0, 2.0};
  features.skewer_points = {{0.25, 0.75}, {0.5, 0.125}};
  features.action_scores = {0.1, 0.2, 0.3, 0.4, 0.5, 0.6};
  v1::FeaturizeResponse response;
  FeaturesToProto(features, "spanet", &response);
  EXPECT_THAT(response.context(), ElementsAre(0.5, 0.0, 2.0));
  ASSERT_EQ(response.skewer_points_size(), 2);
  EXPECT_EQ(response.skewer_points(0).u(), 0.25);
  EXPECT_EQ(response.skewer_points(0).v(), 0.75);
  EXPECT_EQ(response.skewer_points(1).u(), 0.5);
  EXPECT_EQ(response.skewer_points(1).v(), 0.125);
  EXPECT_THAT(response.action_scores(),
              ElementsAre(0.1, 0.2, 0.3, 0.4, 0.5, 0.6));
  EXPECT_EQ(response.featurizer(), "spanet");

  // The default featurizer's: a context only.
  v1::FeaturizeResponse plain;
  FeaturesToProto(Features{{1.0}, {}, {}}, "default", &plain);
  EXPECT_THAT(plain.context(), ElementsAre(1.0));
  EXPECT_EQ(plain.skewer_points_size(), 0);
  EXPECT_EQ(plain.action_scores_size(), 0);
  EXPECT_EQ(plain.featurizer(), "default");
}

}  // namespace
}  // namespace bitewise::perception
