// A source of RGB-D frames for the camera publisher: the D415 through the
// RealSense SDK (realsense_source.h), a recording (recording.h) or the
// simulated camera (sim_source.h). No gRPC.
#ifndef BITEWISE_SERVICES_CAMERA_FRAME_SOURCE_H_
#define BITEWISE_SERVICES_CAMERA_FRAME_SOURCE_H_

#include <algorithm>
#include <string>

#include "absl/status/statusor.h"
#include "absl/time/clock.h"
#include "absl/time/time.h"
#include "services/domain/rgbd_frame.h"
#include "services/domain/steady_time.h"

namespace bitewise::camera {

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

// Paces a source at a fixed rate: Wait() returns at most once per period,
// at once the first time and after a stall (no burst to catch up).
class Pacer {
 public:
  explicit Pacer(double rate_hz) : period_s_(1.0 / rate_hz) {}
  void Wait() {
    const double now = SteadyNowS();
    if (next_s_ > now) absl::SleepFor(absl::Seconds(next_s_ - now));
    next_s_ = std::max(now, next_s_) + period_s_;
  }

 private:
  const double period_s_;
  double next_s_ = 0.0;
};

}  // namespace bitewise::camera

#endif  // BITEWISE_SERVICES_CAMERA_FRAME_SOURCE_H_
