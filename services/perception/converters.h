// Proto <-> perception core conversions for the PerceptionService adapter,
// so that the core never sees a generated type.
#ifndef BITEWISE_SERVICES_PERCEPTION_CONVERTERS_H_
#define BITEWISE_SERVICES_PERCEPTION_CONVERTERS_H_

#include "absl/status/statusor.h"
#include "bitewise/v1/common.pb.h"
#include "bitewise/v1/perception.pb.h"
#include "services/perception/featurizer.h"
#include "services/perception/food_detector.h"
#include "services/perception/frame.h"

namespace bitewise::perception {

// Views into `frame`, which must outlive the result.
FrameBytes FrameBytesFromProto(const v1::Frame& frame);

PixelBox BoxFromProto(const v1::BoundingBox& box);

// UNSPECIFIED means isolated (SPANet's default). INVALID_ARGUMENT for a
// value this build does not know.
absl::StatusOr<FoodLocation> LocationFromProto(v1::FoodLocation location);

void FoodItemToProto(const DetectedFood& food, v1::FoodItem* item);

void FeaturesToProto(const Features& features, const std::string& featurizer,
                     v1::FeaturizeResponse* response);

}  // namespace bitewise::perception

#endif  // BITEWISE_SERVICES_PERCEPTION_CONVERTERS_H_
