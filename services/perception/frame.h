// Camera frames as perception receives them: the D415's RGB image (raw or
// PNG/JPEG-encoded) with its aligned uint16 depth in millimetres and the
// colour camera's pinhole intrinsics. DecodeFrame checks every size, length
// and encoding and turns the bytes into OpenCV images once, so the detector
// and the featurizers work on validated pixels only.
#ifndef BITEWISE_SERVICES_PERCEPTION_FRAME_H_
#define BITEWISE_SERVICES_PERCEPTION_FRAME_H_

#include <cstdint>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "opencv2/core.hpp"
#include "services/domain/rgbd_frame.h"

namespace bitewise::perception {

// Pinhole intrinsics in pixels (pixel centres at integer coordinates): the
// vocabulary's type. In a DecodedFrame, width and height are the frame's.
using CameraIntrinsics = domain::CameraIntrinsics;

enum class ImageEncoding { kUnspecified, kRgb8, kPng, kJpeg };

// A frame as it arrives, before any checks. Views only: the bytes belong to
// the caller (usually a request proto) and must outlive the call.
struct FrameBytes {
  int64_t width = 0;
  int64_t height = 0;
  ImageEncoding encoding = ImageEncoding::kUnspecified;
  absl::string_view rgb;
  // width*height little-endian uint16 millimetres, 0 = no depth; may be
  // empty when the camera had no depth.
  absl::string_view depth_mm;
  // fx, fy, cx, cy as sent (checked by DecodeFrame); width and height are
  // the fields above.
  CameraIntrinsics intrinsics;
};

// A validated frame. rgb is CV_8UC3 in RGB order; depth_mm is CV_16UC1 of
// the same size, or empty when the frame carried no depth.
struct DecodedFrame {
  cv::Mat rgb;
  cv::Mat depth_mm;
  CameraIntrinsics intrinsics;

  int width() const { return rgb.cols; }
  int height() const { return rgb.rows; }
  bool has_depth() const { return !depth_mm.empty(); }
};

// Largest accepted side (the vocabulary's, shared with the camera link).
constexpr int64_t kMaxFrameSide = domain::kMaxFrameSide;
// Largest accepted frame in pixels (8.4 M: 4K UHD fits; the D415's largest
// colour mode is 1920x1080): bounds what one request can cost to decode,
// detect and featurize.
constexpr int64_t kMaxFramePixels = int64_t{1} << 23;

// Checks and decodes a frame. Errors (all INVALID_ARGUMENT, each naming the
// field): a non-positive or oversized width/height (per side or in
// pixels); a PNG/JPEG header declaring another size (checked before
// decoding, so a small file claiming a huge image costs nothing); an
// unspecified encoding; raw RGB of the wrong length; PNG/JPEG bytes that are
// not of the declared format, cannot be decoded, or decode to another size;
// depth of the wrong length; non-finite or non-positive focal lengths or a
// non-finite principal point.
absl::StatusOr<DecodedFrame> DecodeFrame(const FrameBytes& bytes);

// A DecodedFrame viewing pixels that are already in memory and need no
// checks (the simulated camera, experiments, benchmarks): `rgb` holds
// intrinsics.width * intrinsics.height RGB8 pixels, `depth_mm` as many
// millimetre values or nothing. No copy: the vectors must outlive the view.
DecodedFrame ViewFrame(const CameraIntrinsics& intrinsics,
                       std::vector<uint8_t>& rgb,
                       std::vector<uint16_t>& depth_mm);

// An axis-aligned pixel box: columns [x, x + width), rows [y, y + height).
struct PixelBox {
  int x = 0;
  int y = 0;
  int width = 0;
  int height = 0;
};

// INVALID_ARGUMENT when the box is empty (non-positive width or height) or
// does not lie entirely inside a frame of `frame_width` x `frame_height`;
// the message gives the box and the frame size.
absl::Status ValidateBox(const PixelBox& box, int frame_width,
                         int frame_height);

std::string BoxToString(const PixelBox& box);

}  // namespace bitewise::perception

#endif  // BITEWISE_SERVICES_PERCEPTION_FRAME_H_
