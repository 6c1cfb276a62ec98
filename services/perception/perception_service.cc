#include "services/perception/perception_service.h"

#include <vector>

#include "services/common/grpc_status.h"
#include "services/perception/converters.h"

namespace bitewise::perception {
namespace {

grpc::Status Fail(const absl::Status& status) { return ToGrpcStatus(status); }

absl::StatusOr<DecodedFrame> DecodeRequestFrame(bool has_frame,
                                                const v1::Frame& frame) {
  if (!has_frame) return absl::InvalidArgumentError("frame is required");
  return DecodeFrame(FrameBytesFromProto(frame));
}

}  // namespace

PerceptionServiceImpl::PerceptionServiceImpl(const FoodDetector* detector,
                                             const Featurizer* featurizer)
    : detector_(detector), featurizer_(featurizer) {}

grpc::Status PerceptionServiceImpl::DetectFood(
    grpc::ServerContext*, const v1::DetectFoodRequest* request,
    v1::DetectFoodResponse* response) {
  absl::StatusOr<DecodedFrame> frame =
      DecodeRequestFrame(request->has_frame(), request->frame());
  if (!frame.ok()) return Fail(frame.status());
  absl::StatusOr<std::vector<DetectedFood>> items = detector_->Detect(*frame);
  if (!items.ok()) return Fail(items.status());
  for (const DetectedFood& food : *items) {
    FoodItemToProto(food, response->add_items());
  }
  return grpc::Status::OK;
}

grpc::Status PerceptionServiceImpl::Featurize(
    grpc::ServerContext*, const v1::FeaturizeRequest* request,
    v1::FeaturizeResponse* response) {
  if (!request->has_bbox()) {
    return Fail(absl::InvalidArgumentError("bbox is required"));
  }
  absl::StatusOr<FoodLocation> location =
      LocationFromProto(request->location());
  if (!location.ok()) return Fail(location.status());
  absl::StatusOr<DecodedFrame> frame =
      DecodeRequestFrame(request->has_frame(), request->frame());
  if (!frame.ok()) return Fail(frame.status());
  absl::StatusOr<Features> features =
      featurizer_->Featurize(*frame, BoxFromProto(request->bbox()), *location);
  if (!features.ok()) return Fail(features.status());
  FeaturesToProto(*features, featurizer_->name(), response);
  response->set_context_mean_squared_norm(
      featurizer_->context_mean_squared_norm());
  return grpc::Status::OK;
}

}  // namespace bitewise::perception
