// The wrist camera's output as every layer speaks of it: pinhole
// intrinsics and one RGB-D frame (RGB8 with depth aligned to it, in
// millimetres). Produced by the camera sources (services/camera: the D415
// through the RealSense SDK, recorded frames, the simulated camera),
// carried by the camera publisher, and returned by the RobotService's
// CaptureFrame; defined once here so the hardware path's frame type is
// not a simulator type.
#ifndef BITEWISE_SERVICES_DOMAIN_RGBD_FRAME_H_
#define BITEWISE_SERVICES_DOMAIN_RGBD_FRAME_H_

#include <cstdint>
#include <vector>

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
