// RGB-D frames to and from the API's Frame message (common.proto), for the
// camera publisher, its client in the RobotService and CaptureFrame.
#ifndef BITEWISE_SERVICES_CAMERA_FRAME_PROTO_H_
#define BITEWISE_SERVICES_CAMERA_FRAME_PROTO_H_

#include <string>

#include "absl/status/statusor.h"
#include "bitewise/v1/common.pb.h"
#include "services/domain/rgbd_frame.h"

namespace bitewise::camera {

// RGB8 bytes, little-endian depth, intrinsics; timestamp_s and frame_id as
// given.
void FrameToProto(const domain::RgbdFrame& frame, double timestamp_s,
                  const std::string& frame_id, v1::Frame* proto);

// The inverse, for RGB8 frames only (what the publisher sends).
// INVALID_ARGUMENT naming the field: another encoding, sizes that are zero
// or over 8192, RGB or depth of the wrong length, non-positive or
// non-finite focal lengths.
absl::StatusOr<domain::RgbdFrame> FrameFromProto(const v1::Frame& proto);

}  // namespace bitewise::camera

#endif  // BITEWISE_SERVICES_CAMERA_FRAME_PROTO_H_
