// HapticServiceImpl: the gRPC face of the HapticClassifier. Classify
// converts the samples, runs the classifier and converts the result; errors
// become gRPC statuses through the one mapping in services/common.
// Thread-safe (the classifier is).
#ifndef BITEWISE_SERVICES_HAPTIC_HAPTIC_SERVICE_H_
#define BITEWISE_SERVICES_HAPTIC_HAPTIC_SERVICE_H_

#include "bitewise/v1/haptic.grpc.pb.h"
#include "services/common/rpc_environment.h"
#include "services/haptic/core/haptic_classifier.h"

namespace bitewise::haptic {

constexpr char kHapticServiceName[] = "bitewise.v1.HapticService";

class HapticServiceImpl final : public v1::HapticService::Service {
 public:
  // `env` (what every call runs with: rpc_environment.h) and `classifier`
  // must outlive the service.
  HapticServiceImpl(const RpcEnvironment* env,
                    const HapticClassifier* classifier)
      : env_(env), classifier_(classifier) {}

  grpc::Status Classify(grpc::ServerContext* context,
                        const v1::ClassifyRequest* request,
                        v1::ClassifyResponse* response) override;

 private:
  const RpcEnvironment* const env_;
  const HapticClassifier* const classifier_;
};

}  // namespace bitewise::haptic

#endif  // BITEWISE_SERVICES_HAPTIC_HAPTIC_SERVICE_H_
