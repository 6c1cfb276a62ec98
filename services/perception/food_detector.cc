#include "services/perception/food_detector.h"

#include <optional>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"
#include "opencv2/core.hpp"
#include "opencv2/imgproc.hpp"
#include "services/perception/food_detector_stages.h"

namespace bitewise::perception {

void PrepareColourConversions() {
  // The conversions DetectFood and the default featurizer make: float RGB
  // to CIELAB (the tables are built on the first call).
  const cv::Mat pixel(1, 1, CV_32FC3, cv::Scalar(0.5, 0.5, 0.5));
  cv::Mat lab;
  cv::cvtColor(pixel, lab, cv::COLOR_RGB2Lab);
}

FoodDetector::FoodDetector(const FoodDetectorOptions& options)
    : options_(options) {}

absl::StatusOr<std::vector<DetectedFood>> FoodDetector::Detect(
    const DecodedFrame& frame) const {
  if (!frame.has_depth()) {
    return absl::InvalidArgumentError(
        "frame.depth_mm is empty: DetectFood finds food by its height above "
        "the plate and needs the aligned depth image");
  }
  using namespace detection;  // NOLINT: the stages, in order
  // No plate is not an empty plate: a dead depth stream, a camera that
  // does not see the plate, or a covered lens must not end a meal as "the
  // plate is empty".
  const auto no_plate = [&frame](absl::string_view what) {
    const int pixels = frame.depth_mm.rows * frame.depth_mm.cols;
    return absl::FailedPreconditionError(absl::StrCat(
        "no plate found: ", what, " (", cv::countNonZero(frame.depth_mm),
        " of ", pixels,
        " pixels have depth); is the plate in view and the depth stream "
        "working?"));
  };
  const std::optional<HeightMap> heights =
      MeasureHeight(frame.depth_mm, frame.intrinsics, options_);
  if (!heights) return no_plate("no flat surface in the depth image");
  const std::optional<PlateRegion> plate = FindPlate(*heights, options_);
  if (!plate) {
    return no_plate("no flat region covers a tenth of the frame");
  }
  // Everything below looks only at the plate's bounding box (about half
  // the frame); pixel coordinates are shifted back at the end.
  const cv::Rect& roi = plate->roi;
  const cv::Mat rgb = frame.rgb(roi);
  const cv::Mat height_mm = heights->height_mm(roi);
  const cv::Mat valid = heights->valid(roi);
  const FoodEvidence evidence =
      FindEvidence(rgb, height_mm, valid, *plate, options_);
  // The later stages look only at the food's bounding box, widened by
  // FoodMargin, which leaves every result as it would be over the whole
  // plate box (tested), at a median 89 % of its pixels on the blind plates
  // (docs/perception.md).
  const cv::Rect box = FoodBox(evidence, options_);
  if (box.empty()) return std::vector<DetectedFood>();
  const FoodEvidence food = CropEvidence(evidence, box);
  const cv::Mat food_height = height_mm(box);
  std::optional<Regions> regions = PlantSeeds(food, food_height, options_);
  if (!regions) return std::vector<DetectedFood>();
  GrowRegions(rgb(box), food, plate->plate(box), *regions);
  MergeSplitItems(food, food_height, valid(box), options_, *regions);
  SplitAtWaists(options_, *regions);
  const cv::Rect in_frame = box + roi.tl();
  return DescribeItems(*regions, food, frame.depth_mm(in_frame), in_frame,
                       heights->plane, frame.intrinsics, options_);
}

}  // namespace bitewise::perception
