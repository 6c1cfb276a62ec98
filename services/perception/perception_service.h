// PerceptionServiceImpl: the gRPC face of the perception core. Each handler
// converts the request, decodes and validates the frame, calls the detector
// or the featurizer and converts the result; errors become gRPC statuses
// through the one mapping in services/common. Thread-safe (the detector and
// featurizers are).
#ifndef BITEWISE_SERVICES_PERCEPTION_PERCEPTION_SERVICE_H_
#define BITEWISE_SERVICES_PERCEPTION_PERCEPTION_SERVICE_H_

#include "bitewise/v1/perception.grpc.pb.h"
#include "services/common/rpc_environment.h"
#include "services/perception/featurizer.h"
#include "services/perception/food_detector.h"

namespace bitewise::perception {

class PerceptionServiceImpl final : public v1::PerceptionService::Service {
 public:
  // All three must outlive the service; `env` is what every call runs
  // with (rpc_environment.h).
  PerceptionServiceImpl(const RpcEnvironment* env, const FoodDetector* detector,
                        const Featurizer* featurizer);

  // INVALID_ARGUMENT for a missing or malformed frame (see DecodeFrame) or
  // a frame without depth; FAILED_PRECONDITION when no plate is found (no
  // flat surface in the depth image: a dead depth stream, a plate out of
  // view), which is not an empty plate.
  grpc::Status DetectFood(grpc::ServerContext* context,
                          const v1::DetectFoodRequest* request,
                          v1::DetectFoodResponse* response) override;
  // INVALID_ARGUMENT for a missing or malformed frame, a missing, empty or
  // out-of-frame bbox, an unknown location, or (the default featurizer) a
  // frame without depth; INTERNAL when SPANet gives outputs that are not
  // finite or scores outside [0, 1].
  grpc::Status Featurize(grpc::ServerContext* context,
                         const v1::FeaturizeRequest* request,
                         v1::FeaturizeResponse* response) override;

 private:
  const RpcEnvironment* const env_;
  const FoodDetector* const detector_;
  const Featurizer* const featurizer_;
};

}  // namespace bitewise::perception

#endif  // BITEWISE_SERVICES_PERCEPTION_PERCEPTION_SERVICE_H_
