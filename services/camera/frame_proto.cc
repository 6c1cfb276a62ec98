#include "services/camera/frame_proto.h"

#include <cmath>

#include "absl/strings/str_cat.h"

namespace bitewise::camera {

void FrameToProto(const domain::RgbdFrame& frame, double timestamp_s,
                  const std::string& frame_id, v1::Frame* proto) {
  proto->set_width(frame.intrinsics.width);
  proto->set_height(frame.intrinsics.height);
  proto->set_rgb_encoding(v1::IMAGE_ENCODING_RGB8);
  proto->set_rgb(frame.rgb.data(), frame.rgb.size());
  std::string depth(frame.depth_mm.size() * 2, '\0');
  for (size_t i = 0; i < frame.depth_mm.size(); ++i) {
    // Little-endian, as common.proto specifies, whatever the host.
    depth[2 * i] = static_cast<char>(frame.depth_mm[i] & 0xff);
    depth[2 * i + 1] = static_cast<char>(frame.depth_mm[i] >> 8);
  }
  proto->set_depth_mm(std::move(depth));
  v1::CameraIntrinsics* k = proto->mutable_intrinsics();
  k->set_fx(frame.intrinsics.fx);
  k->set_fy(frame.intrinsics.fy);
  k->set_cx(frame.intrinsics.cx);
  k->set_cy(frame.intrinsics.cy);
  proto->set_timestamp_s(timestamp_s);
  proto->set_frame_id(frame_id);
}

absl::StatusOr<domain::RgbdFrame> FrameFromProto(const v1::Frame& proto) {
  if (proto.rgb_encoding() != v1::IMAGE_ENCODING_RGB8) {
    return absl::InvalidArgumentError(
        absl::StrCat("frame.rgb_encoding: expected IMAGE_ENCODING_RGB8, got ",
                     v1::ImageEncoding_Name(proto.rgb_encoding())));
  }
  constexpr uint32_t kMaxSide = domain::kMaxFrameSide;
  if (proto.width() == 0 || proto.height() == 0 || proto.width() > kMaxSide ||
      proto.height() > kMaxSide) {
    return absl::InvalidArgumentError(
        absl::StrCat("frame size ", proto.width(), "x", proto.height(),
                     ": each side must be in [1, ", kMaxSide, "]"));
  }
  const size_t pixels = static_cast<size_t>(proto.width()) * proto.height();
  if (proto.rgb().size() != pixels * 3) {
    return absl::InvalidArgumentError(absl::StrCat(
        "frame.rgb: ", proto.rgb().size(), " bytes for ", proto.width(), "x",
        proto.height(), " RGB8 (expected ", pixels * 3, ")"));
  }
  if (proto.depth_mm().size() != pixels * 2) {
    return absl::InvalidArgumentError(
        absl::StrCat("frame.depth_mm: ", proto.depth_mm().size(),
                     " bytes (expected ", pixels * 2, ")"));
  }
  const v1::CameraIntrinsics& k = proto.intrinsics();
  domain::RgbdFrame frame;
  frame.intrinsics = {static_cast<int>(proto.width()),
                      static_cast<int>(proto.height()),
                      k.fx(),
                      k.fy(),
                      k.cx(),
                      k.cy()};
  // Perception's own rule: a frame it would refuse is refused here, at
  // the camera link, naming the camera's values.
  if (absl::Status valid =
          domain::ValidateIntrinsics(frame.intrinsics, "frame.intrinsics");
      !valid.ok()) {
    return valid;
  }
  frame.rgb.assign(proto.rgb().begin(), proto.rgb().end());
  frame.depth_mm.resize(pixels);
  const std::string& depth = proto.depth_mm();
  for (size_t i = 0; i < pixels; ++i) {
    frame.depth_mm[i] =
        static_cast<uint16_t>(static_cast<uint8_t>(depth[2 * i]) |
                              (static_cast<uint8_t>(depth[2 * i + 1]) << 8));
  }
  return frame;
}

}  // namespace bitewise::camera
