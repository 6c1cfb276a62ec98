#include "services/robot/camera_client.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <utility>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "services/camera/frame_proto.h"
#include "services/common/grpc_status.h"
#include "services/common/status_macros.h"
#include "services/domain/steady_time.h"

namespace bitewise::robot {

absl::StatusOr<std::unique_ptr<CameraClient>> CameraClient::Create(
    const CameraClientOptions& options) {
  if (options.address.empty()) {
    return absl::InvalidArgumentError("camera address is empty");
  }
  if (!(options.max_frame_age_s > 0.0) || !(options.timeout_s > 0.0)) {
    return absl::InvalidArgumentError(
        absl::StrCat("camera max_frame_age_s and timeout_s must be > 0 (got ",
                     options.max_frame_age_s, ", ", options.timeout_s, ")"));
  }
  ASSIGN_OR_RETURN(std::shared_ptr<grpc::Channel> channel,
                   MakeChannel(options.address, options.channel));
  return std::unique_ptr<CameraClient>(
      new CameraClient(options, v1::CameraService::NewStub(channel)));
}

CameraClient::CameraClient(const CameraClientOptions& options,
                           std::unique_ptr<v1::CameraService::Stub> stub)
    : address_(options.address),
      max_age_s_(options.max_frame_age_s),
      timeout_s_(options.timeout_s),
      stub_(std::move(stub)) {}

absl::StatusOr<domain::RgbdFrame> CameraClient::Capture() {
  grpc::ClientContext context;
  context.set_deadline(
      std::chrono::system_clock::now() +
      std::chrono::microseconds(static_cast<int64_t>(timeout_s_ * 1e6)));
  v1::GetFrameRequest request;
  request.set_max_age_s(max_age_s_);
  v1::CameraFrame reply;
  const double sent_s = SteadyNowS();
  const grpc::Status status = stub_->GetFrame(&context, request, &reply);
  const double round_trip_s = SteadyNowS() - sent_s;
  if (!status.ok()) {
    const absl::Status s = FromGrpcStatus(status);
    return absl::Status(
        s.code(), absl::StrCat("camera at ", address_, ": ", s.message()));
  }
  // An age that is not a number, or negative, says nothing about how old
  // the frame is: never used.
  if (!(reply.age_s() >= 0.0 && std::isfinite(reply.age_s()))) {
    return absl::InternalError(
        absl::StrCat("camera at ", address_, " sent a frame whose age_s is ",
                     reply.age_s(), ": not used for a bite"));
  }
  const double age_s = reply.age_s() + round_trip_s;
  if (age_s > max_age_s_) {
    return absl::FailedPreconditionError(absl::StrFormat(
        "camera at %s: the frame is %.2f s old (%.2f s at the camera, %.2f s "
        "on the way; limit %.2f s): not used for a bite",
        address_, age_s, reply.age_s(), round_trip_s, max_age_s_));
  }
  absl::StatusOr<domain::RgbdFrame> decoded =
      camera::FrameFromProto(reply.frame());
  if (!decoded.ok()) {
    return absl::InternalError(
        absl::StrCat("camera at ", address_,
                     " sent a malformed frame: ", decoded.status().message()));
  }
  domain::RgbdFrame frame = *std::move(decoded);
  frame.sequence = reply.sequence();
  frame.capture_s = SteadyNowS() - age_s;  // on this process's clock
  absl::MutexLock lock(&mu_);
  if (have_last_ && reply.sequence() == last_sequence_) {
    return absl::FailedPreconditionError(absl::StrCat(
        "camera at ", address_, " returned frame ", reply.sequence(),
        " again: the camera has not captured since the last bite"));
  }
  if (reply.frames_dropped() > last_dropped_) {
    std::fprintf(stderr,
                 "bitewise-robot: camera at %s dropped %llu frames so far\n",
                 address_.c_str(),
                 static_cast<unsigned long long>(reply.frames_dropped()));
  }
  have_last_ = true;
  last_sequence_ = reply.sequence();
  last_dropped_ = reply.frames_dropped();
  return frame;
}

}  // namespace bitewise::robot
