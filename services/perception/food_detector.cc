#include "services/perception/food_detector.h"

#include <optional>
#include <vector>

#include "absl/status/status.h"
#include "services/perception/food_detector_stages.h"

namespace bitewise::perception {

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
  const std::optional<HeightMap> heights =
      MeasureHeight(frame.depth_mm, frame.intrinsics, options_);
  if (!heights) return std::vector<DetectedFood>();
  const std::optional<PlateRegion> plate = FindPlate(*heights, options_);
  if (!plate) return std::vector<DetectedFood>();
  // Everything below looks only at the plate's bounding box (about half
  // the frame); pixel coordinates are shifted back at the end.
  const cv::Rect& roi = plate->roi;
  const cv::Mat rgb = frame.rgb(roi);
  const cv::Mat height_mm = heights->height_mm(roi);
  const cv::Mat valid = heights->valid(roi);
  const FoodEvidence evidence =
      FindEvidence(rgb, height_mm, valid, *plate, options_);
  std::optional<Regions> regions = PlantSeeds(evidence, height_mm, options_);
  if (!regions) return std::vector<DetectedFood>();
  GrowRegions(rgb, evidence, plate->plate, *regions);
  MergeSplitItems(evidence, height_mm, valid, options_, *regions);
  SplitAtWaists(options_, *regions);
  return DescribeItems(*regions, evidence, frame.depth_mm(roi), roi,
                       heights->plane, frame.intrinsics, options_);
}

}  // namespace bitewise::perception
