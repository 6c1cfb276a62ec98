// The wrist camera's output as every layer speaks of it: pinhole
// intrinsics and one RGB-D frame (RGB8 with depth aligned to it, in
// millimetres). Produced by the camera sources (services/camera: the D415
// through the RealSense SDK, recorded frames, the simulated camera),
// carried by the camera publisher, and returned by the RobotService's
// CaptureFrame; defined once here so the hardware path's frame type is
// not a simulator type.
#ifndef BITEWISE_SERVICES_DOMAIN_RGBD_FRAME_H_
#define BITEWISE_SERVICES_DOMAIN_RGBD_FRAME_H_

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"

namespace bitewise::domain {

// Pinhole intrinsics of the colour image, in pixels (pixel centres at
// integer coordinates). Defaults: the D415's colour stream at 640x480.
struct CameraIntrinsics {
  int width = 640;
  int height = 480;
  double fx = 615.0;
  double fy = 615.0;
  double cx = 320.0;
  double cy = 240.0;
};

// Largest accepted frame side in pixels, far above any depth camera's, so a
// corrupt size cannot make a service allocate gigabytes.
constexpr int kMaxFrameSide = 8192;

// Intrinsics a frame can be used with: each side in [1, kMaxFrameSide];
// focal lengths of 1 to 10^6 pixels (a D415 has about 615 at 640x480; any
// lens is inside it, and outside it a featurizer's metres per pixel
// overflow); the principal point within a frame's width and height of the
// image's centre. INVALID_ARGUMENT naming `what` (as "what.fx and fy
// must be ...") and the values otherwise.
// One rule for the camera, its recordings, the robot's link and perception.
inline absl::Status ValidateIntrinsics(const CameraIntrinsics& k,
                                       absl::string_view what) {
  if (k.width < 1 || k.height < 1 || k.width > kMaxFrameSide ||
      k.height > kMaxFrameSide) {
    return absl::InvalidArgumentError(
        absl::StrCat(what, ".width and .height: ", k.width, "x", k.height,
                     ": each side must be in [1, ", kMaxFrameSide, "]"));
  }
  constexpr double kMinFocalPx = 1.0;
  constexpr double kMaxFocalPx = 1e6;
  if (!(k.fx >= kMinFocalPx && k.fx <= kMaxFocalPx && k.fy >= kMinFocalPx &&
        k.fy <= kMaxFocalPx)) {
    return absl::InvalidArgumentError(absl::StrCat(
        what, ".fx and fy must be focal lengths of ", kMinFocalPx, " to ",
        kMaxFocalPx, " pixels (got fx=", k.fx, ", fy=", k.fy, ")"));
  }
  if (!(std::abs(k.cx - k.width / 2.0) <= k.width &&
        std::abs(k.cy - k.height / 2.0) <= k.height)) {
    return absl::InvalidArgumentError(absl::StrCat(
        what,
        ".cx and cy must be finite and within a frame's width and height "
        "of its centre (got cx=",
        k.cx, ", cy=", k.cy, " for ", k.width, "x", k.height, ")"));
  }
  return absl::OkStatus();
}

struct RgbdFrame {
  CameraIntrinsics intrinsics;
  std::vector<uint8_t> rgb;        // width*height*3, row-major RGB8
  std::vector<uint16_t> depth_mm;  // width*height aligned to rgb, 0 = none
  // The source's frame counter: consecutive frames differ by one, so a gap
  // is frames the source dropped.
  uint64_t sequence = 0;
  // Capture time on the capturing process's steady clock (seconds).
  double capture_s = 0.0;
};

}  // namespace bitewise::domain

#endif  // BITEWISE_SERVICES_DOMAIN_RGBD_FRAME_H_
