#include "services/haptic/haptic_service.h"

#include <vector>

#include "services/common/rpc_handler.h"
#include "services/common/rpc_methods.h"
#include "services/common/status_macros.h"
#include "services/haptic/converters.h"

namespace bitewise::haptic {

grpc::Status HapticServiceImpl::Classify(grpc::ServerContext* context,
                                         const v1::ClassifyRequest* request,
                                         v1::ClassifyResponse* response) {
  return RunRpc(*env_, BITEWISE_RPC_METHOD(v1::HapticService), context,
                [&]() -> absl::Status {
                  ASSIGN_OR_RETURN(
                      const HapticClassification result,
                      classifier_->Classify(TraceFromProto(*request)));
                  ClassificationToProto(
                      result, classifier_->net().fingerprint(), response);
                  return absl::OkStatus();
                });
}

}  // namespace bitewise::haptic
