// CameraServiceImpl: the gRPC face of a FramePublisher (GetFrame returns
// the newest frame with its age and the drop counters). Thin: the
// publisher decides what is too old.
//
// Thread-safe.
#ifndef BITEWISE_SERVICES_CAMERA_CAMERA_SERVICE_H_
#define BITEWISE_SERVICES_CAMERA_CAMERA_SERVICE_H_

#include "bitewise/v1/camera.grpc.pb.h"
#include "services/camera/frame_publisher.h"
#include "services/common/rpc_environment.h"

namespace bitewise::camera {

class CameraServiceImpl final : public v1::CameraService::Service {
 public:
  // `env` (what every call runs with: rpc_environment.h) and `publisher`
  // must outlive the service.
  CameraServiceImpl(const RpcEnvironment* env, const FramePublisher* publisher)
      : env_(env), publisher_(publisher) {}

  grpc::Status GetFrame(grpc::ServerContext* context,
                        const v1::GetFrameRequest* request,
                        v1::CameraFrame* response) override;

 private:
  const RpcEnvironment* const env_;
  const FramePublisher* const publisher_;
};

}  // namespace bitewise::camera

#endif  // BITEWISE_SERVICES_CAMERA_CAMERA_SERVICE_H_
