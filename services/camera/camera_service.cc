#include "services/camera/camera_service.h"

#include <cmath>

#include "absl/strings/str_cat.h"
#include "services/camera/frame_proto.h"
#include "services/common/rpc_handler.h"
#include "services/common/rpc_methods.h"
#include "services/common/status_macros.h"

namespace bitewise::camera {

grpc::Status CameraServiceImpl::GetFrame(grpc::ServerContext* context,
                                         const v1::GetFrameRequest* request,
                                         v1::CameraFrame* response) {
  return RunRpc(
      *env_, BITEWISE_RPC_METHOD(v1::CameraService), context,
      [&]() -> absl::Status {
        const double max_age_s = request->max_age_s();
        if (!std::isfinite(max_age_s) || max_age_s < 0.0) {
          return absl::InvalidArgumentError(absl::StrCat(
              "max_age_s must be finite and >= 0 (got ", max_age_s, ")"));
        }
        ASSIGN_OR_RETURN(PublishedFrame newest, publisher_->Newest(max_age_s));
        FrameToProto(newest.frame, newest.frame.capture_s,
                     absl::StrCat("camera-", newest.frame.sequence),
                     response->mutable_frame());
        response->set_sequence(newest.frame.sequence);
        response->set_age_s(newest.age_s);
        response->set_frames_dropped(newest.frames_dropped);
        response->set_frames_captured(newest.frames_captured);
        response->set_source(publisher_->source_name());
        return absl::OkStatus();
      });
}

}  // namespace bitewise::camera
