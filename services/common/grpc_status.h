// Conversion between absl::Status (used by every bitewise library) and
// grpc::Status (what goes on the wire). This is the one place in the tree
// where that conversion happens, so handlers never build grpc::Status by hand
// and clients never interpret raw gRPC codes themselves.
#ifndef BITEWISE_SERVICES_COMMON_GRPC_STATUS_H_
#define BITEWISE_SERVICES_COMMON_GRPC_STATUS_H_

#include <grpcpp/support/status.h>

#include "absl/status/status.h"

namespace bitewise {

// Maps the code 1:1 and keeps the message. Payloads are dropped: nothing in
// bitewise attaches them, and gRPC would need error_details to carry them.
grpc::Status ToGrpcStatus(const absl::Status& status);

// Inverse of ToGrpcStatus. Codes gRPC does not define map to kUnknown.
absl::Status FromGrpcStatus(const grpc::Status& status);

}  // namespace bitewise

#endif  // BITEWISE_SERVICES_COMMON_GRPC_STATUS_H_
