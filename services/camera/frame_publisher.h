// FramePublisher: runs a FrameSource on its own thread and keeps the newest
// frame, so that a reader gets the latest picture of the plate at once,
// with its age, and never a stale one by accident. Counts frames captured
// and frames the source dropped (gaps in its counter). No gRPC; the
// CameraService (camera_service.h) serves it.
//
// Thread-safe.
#ifndef BITEWISE_SERVICES_CAMERA_FRAME_PUBLISHER_H_
#define BITEWISE_SERVICES_CAMERA_FRAME_PUBLISHER_H_

#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <thread>

#include "absl/base/thread_annotations.h"
#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/synchronization/mutex.h"
#include "services/camera/frame_source.h"
#include "services/domain/rgbd_frame.h"

namespace bitewise::camera {

struct PublishedFrame {
  domain::RgbdFrame frame;
  double age_s = 0.0;  // now - capture
  uint64_t frames_captured = 0;
  uint64_t frames_dropped = 0;
};

struct PublisherCounters {
  uint64_t frames_captured = 0;
  uint64_t frames_dropped = 0;
  double newest_age_s = -1.0;  // -1: no frame yet
  std::string last_error;      // the source's last error, "" if none
};

class FramePublisher {
 public:
  // Starts capturing at once.
  explicit FramePublisher(std::unique_ptr<FrameSource> source);
  ~FramePublisher();  // stops the thread

  // The newest frame. Errors: UNAVAILABLE before the first frame (with
  // the source's last error, if any); FAILED_PRECONDITION when
  // max_age_s > 0 and the newest frame is older, naming its age, the
  // limit, the source and its last error.
  absl::StatusOr<PublishedFrame> Newest(double max_age_s) const;

  PublisherCounters Counters() const;
  const std::string& source_name() const { return name_; }

 private:
  void Run();

  const std::unique_ptr<FrameSource> source_;
  const std::string name_;
  std::atomic<bool> stop_{false};
  mutable absl::Mutex mu_;
  std::shared_ptr<const domain::RgbdFrame> newest_ ABSL_GUARDED_BY(mu_);
  uint64_t captured_ ABSL_GUARDED_BY(mu_) = 0;
  uint64_t dropped_ ABSL_GUARDED_BY(mu_) = 0;
  std::string last_error_ ABSL_GUARDED_BY(mu_);
  std::thread thread_;
};

}  // namespace bitewise::camera

#endif  // BITEWISE_SERVICES_CAMERA_FRAME_PUBLISHER_H_
