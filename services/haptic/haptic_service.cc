#include "services/haptic/haptic_service.h"

#include <vector>

#include "services/common/grpc_status.h"
#include "services/haptic/converters.h"

namespace bitewise::haptic {

grpc::Status HapticServiceImpl::Classify(grpc::ServerContext*,
                                         const v1::ClassifyRequest* request,
                                         v1::ClassifyResponse* response) {
  const std::vector<WrenchSample> trace = TraceFromProto(*request);
  absl::StatusOr<HapticClassification> result = classifier_->Classify(trace);
  if (!result.ok()) return ToGrpcStatus(result.status());
  ClassificationToProto(*result, classifier_->net().fingerprint(), response);
  return grpc::Status::OK;
}

}  // namespace bitewise::haptic
