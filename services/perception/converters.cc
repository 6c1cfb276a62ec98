#include "services/perception/converters.h"

#include "absl/strings/str_cat.h"

namespace bitewise::perception {

FrameBytes FrameBytesFromProto(const v1::Frame& frame) {
  FrameBytes bytes;
  bytes.width = frame.width();
  bytes.height = frame.height();
  switch (frame.rgb_encoding()) {
    case v1::IMAGE_ENCODING_RGB8:
      bytes.encoding = ImageEncoding::kRgb8;
      break;
    case v1::IMAGE_ENCODING_PNG:
      bytes.encoding = ImageEncoding::kPng;
      break;
    case v1::IMAGE_ENCODING_JPEG:
      bytes.encoding = ImageEncoding::kJpeg;
      break;
    default:
      bytes.encoding = ImageEncoding::kUnspecified;
      break;
  }
  bytes.rgb = frame.rgb();
  bytes.depth_mm = frame.depth_mm();
  bytes.intrinsics.fx = frame.intrinsics().fx();
  bytes.intrinsics.fy = frame.intrinsics().fy();
  bytes.intrinsics.cx = frame.intrinsics().cx();
  bytes.intrinsics.cy = frame.intrinsics().cy();
  return bytes;
}

PixelBox BoxFromProto(const v1::BoundingBox& box) {
  return {box.x(), box.y(), box.width(), box.height()};
}

absl::StatusOr<FoodLocation> LocationFromProto(v1::FoodLocation location) {
  switch (location) {
    case v1::FOOD_LOCATION_UNSPECIFIED:
    case v1::FOOD_LOCATION_ISOLATED:
      return FoodLocation::kIsolated;
    case v1::FOOD_LOCATION_WALL:
      return FoodLocation::kWall;
    case v1::FOOD_LOCATION_LETTUCE:
      return FoodLocation::kLettuce;
    default:
      return absl::InvalidArgumentError(
          absl::StrCat("location: unknown FoodLocation value ", location));
  }
}

void FoodItemToProto(const DetectedFood& food, v1::FoodItem* item) {
  v1::BoundingBox* box = item->mutable_bbox();
  box->set_x(food.bbox.x);
  box->set_y(food.bbox.y);
  box->set_width(food.bbox.width);
  box->set_height(food.bbox.height);
  item->mutable_center_px()->set_u(food.center_u_px);
  item->mutable_center_px()->set_v(food.center_v_px);
  item->set_major_axis_angle_rad(food.major_axis_angle_rad);
  item->set_depth_m(food.depth_m);
  item->mutable_center_camera_m()->set_x(food.center_x_m);
  item->mutable_center_camera_m()->set_y(food.center_y_m);
  item->mutable_center_camera_m()->set_z(food.center_z_m);
  item->set_score(food.score);
}

void FeaturesToProto(const Features& features, const std::string& featurizer,
                     v1::FeaturizeResponse* response) {
  response->mutable_context()->Add(features.context.begin(),
                                   features.context.end());
  for (const CropPoint& p : features.skewer_points) {
    v1::Pixel* pixel = response->add_skewer_points();
    pixel->set_u(p.u);
    pixel->set_v(p.v);
  }
  response->mutable_action_scores()->Add(features.action_scores.begin(),
                                         features.action_scores.end());
  response->set_featurizer(featurizer);
}

}  // namespace bitewise::perception
