// A source of RGB-D frames for the camera publisher: the D415 through the
// RealSense SDK (realsense_source.h), a recording (replay_source.h) or the
// simulated camera (sim_source.h). No gRPC.
#ifndef BITEWISE_SERVICES_CAMERA_FRAME_SOURCE_H_
#define BITEWISE_SERVICES_CAMERA_FRAME_SOURCE_H_

#include <chrono>
#include <string>

#include "absl/status/statusor.h"
#include "services/domain/rgbd_frame.h"

namespace bitewise::camera {

// Seconds on std::chrono::steady_clock: the camera process's time base for
// capture times and ages.
inline double CameraNowS() {
  return std::chrono::duration<double>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

// Not thread-safe: one publisher thread calls Next.
class FrameSource {
 public:
  virtual ~FrameSource() = default;
  // Blocks until the next frame (capture_s set on this process's steady
  // clock). Errors: UNAVAILABLE when the device gives nothing in its
  // timeout (the publisher keeps trying); OUT_OF_RANGE when a finite
  // source has ended; others are the device's, naming it.
  virtual absl::StatusOr<domain::RgbdFrame> Next() = 0;
  // "realsense:<library>", "replay:<dir>", "sim:seed=<n>".
  virtual std::string name() const = 0;
};

}  // namespace bitewise::camera

#endif  // BITEWISE_SERVICES_CAMERA_FRAME_SOURCE_H_
