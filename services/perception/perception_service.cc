#include "services/perception/perception_service.h"

#include <vector>

#include "services/common/rpc_handler.h"
#include "services/common/rpc_methods.h"
#include "services/common/status_macros.h"
#include "services/perception/converters.h"

namespace bitewise::perception {
namespace {

absl::StatusOr<DecodedFrame> DecodeRequestFrame(bool has_frame,
                                                const v1::Frame& frame) {
  if (!has_frame) return absl::InvalidArgumentError("frame is required");
  return DecodeFrame(FrameBytesFromProto(frame));
}

}  // namespace

PerceptionServiceImpl::PerceptionServiceImpl(const RpcEnvironment* env,
                                             const FoodDetector* detector,
                                             const Featurizer* featurizer)
    : env_(env), detector_(detector), featurizer_(featurizer) {}

grpc::Status PerceptionServiceImpl::DetectFood(
    grpc::ServerContext* context, const v1::DetectFoodRequest* request,
    v1::DetectFoodResponse* response) {
  return RunRpc(*env_, BITEWISE_RPC_METHOD(v1::PerceptionService), context,
                [&]() -> absl::Status {
                  ASSIGN_OR_RETURN(const DecodedFrame frame,
                                   DecodeRequestFrame(request->has_frame(),
                                                      request->frame()));
                  ASSIGN_OR_RETURN(const std::vector<DetectedFood> items,
                                   detector_->Detect(frame));
                  for (const DetectedFood& food : items) {
                    FoodItemToProto(food, response->add_items());
                  }
                  return absl::OkStatus();
                });
}

grpc::Status PerceptionServiceImpl::Featurize(
    grpc::ServerContext* context, const v1::FeaturizeRequest* request,
    v1::FeaturizeResponse* response) {
  return RunRpc(
      *env_, BITEWISE_RPC_METHOD(v1::PerceptionService), context,
      [&]() -> absl::Status {
        if (!request->has_bbox()) {
          return absl::InvalidArgumentError("bbox is required");
        }
        ASSIGN_OR_RETURN(const FoodLocation location,
                         LocationFromProto(request->location()));
        ASSIGN_OR_RETURN(
            const DecodedFrame frame,
            DecodeRequestFrame(request->has_frame(), request->frame()));
        ASSIGN_OR_RETURN(const Features features,
                         featurizer_->Featurize(
                             frame, BoxFromProto(request->bbox()), location));
        FeaturesToProto(features, featurizer_->name(), response);
        response->set_context_mean_squared_norm(
            featurizer_->context_mean_squared_norm());
        return absl::OkStatus();
      });
}

}  // namespace bitewise::perception
