// CameraClient: the hardware backend's wrist camera, a FrameProvider that
// asks the camera publisher (bitewise-camera, CameraService) for its newest
// frame once per CaptureFrame and refuses a stale one. The frame's age is
// the publisher's (capture to reply, on its clock) plus this call's round
// trip, so no clock needs to agree with another.
//
// Thread-safe.
#ifndef BITEWISE_SERVICES_ROBOT_CAMERA_CLIENT_H_
#define BITEWISE_SERVICES_ROBOT_CAMERA_CLIENT_H_

#include <cstdint>
#include <memory>
#include <string>

#include "absl/base/thread_annotations.h"
#include "absl/status/statusor.h"
#include "absl/synchronization/mutex.h"
#include "bitewise/v1/camera.grpc.pb.h"
#include "services/common/channel.h"
#include "services/robot/backend.h"

namespace bitewise::robot {

struct CameraClientOptions {
  std::string address;  // host:port of bitewise-camera
  ChannelOptions channel;
  // A frame older than this is never returned (seconds).
  double max_frame_age_s = 0.5;
  // Deadline of one GetFrame call.
  double timeout_s = 2.0;
};

class CameraClient final : public FrameProvider {
 public:
  // INVALID_ARGUMENT for an empty address or non-positive limits; the
  // channel's errors. Does not wait for the camera: CaptureFrame says
  // when it is not there.
  static absl::StatusOr<std::unique_ptr<CameraClient>> Create(
      const CameraClientOptions& options);

  // Errors, each naming the camera's address: UNAVAILABLE when the
  // publisher cannot be reached or has no frame yet; DEADLINE_EXCEEDED
  // when it does not answer in timeout_s; FAILED_PRECONDITION naming the
  // age when the newest frame is older than max_frame_age_s, or when the
  // frame is the one the previous call returned; INTERNAL for a malformed
  // frame.
  absl::StatusOr<domain::RgbdFrame> Capture() override;
  std::string name() const override { return "camera at " + address_; }

 private:
  CameraClient(const CameraClientOptions& options,
               std::unique_ptr<v1::CameraService::Stub> stub);

  const std::string address_;
  const double max_age_s_;
  const double timeout_s_;
  const std::unique_ptr<v1::CameraService::Stub> stub_;
  absl::Mutex mu_;
  bool have_last_ ABSL_GUARDED_BY(mu_) = false;
  uint64_t last_sequence_ ABSL_GUARDED_BY(mu_) = 0;
  uint64_t last_dropped_ ABSL_GUARDED_BY(mu_) = 0;
};

}  // namespace bitewise::robot

#endif  // BITEWISE_SERVICES_ROBOT_CAMERA_CLIENT_H_
