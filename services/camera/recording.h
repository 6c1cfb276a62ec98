// Recorded RGB-D frames on disk, and a FrameSource that replays them: for
// development without the camera, for checking perception on frames from
// the real plate, and for tests of everything downstream of the camera.
//
// A recording is a directory:
//   camera.txt           "version 1", "width W", "height H", "fx ..", "fy ..",
//                        "cx ..", "cy ..", "rate_hz R" (one per line)
//   NNNNNN.rgb.png       colour, 8-bit, W x H
//   NNNNNN.depth.png     depth aligned to colour, 16-bit one channel, mm
// with NNNNNN = 000000, 000001, ... (bitewise-camera --record writes it).
#ifndef BITEWISE_SERVICES_CAMERA_RECORDING_H_
#define BITEWISE_SERVICES_CAMERA_RECORDING_H_

#include <cstdint>
#include <memory>
#include <string>
#include <utility>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "services/camera/frame_source.h"
#include "services/domain/rgbd_frame.h"

namespace bitewise::camera {

// Writes camera.txt. FAILED_PRECONDITION naming the file if it cannot.
absl::Status WriteRecordingHeader(const std::string& dir,
                                  const domain::CameraIntrinsics& intrinsics,
                                  double rate_hz);
// Writes frame `index` (both images). INVALID_ARGUMENT for a frame whose
// buffers do not match its intrinsics; FAILED_PRECONDITION naming a file
// that cannot be written.
absl::Status WriteRecordedFrame(const std::string& dir, int64_t index,
                                const domain::RgbdFrame& frame);

struct ReplayOptions {
  // Start again after the last frame (the counter keeps counting); without
  // it the source ends (OUT_OF_RANGE) and its last frame ages.
  bool loop = false;
  // Frames per second; 0 uses the recording's rate_hz.
  double rate_hz = 0.0;
};

class ReplaySource final : public FrameSource {
 public:
  // Reads camera.txt and counts the frames. Errors: NOT_FOUND when the
  // directory or camera.txt is missing; INVALID_ARGUMENT naming the line
  // of a malformed camera.txt; FAILED_PRECONDITION when there are no
  // frames.
  static absl::StatusOr<std::unique_ptr<ReplaySource>> Open(
      const std::string& dir, const ReplayOptions& options);

  // Paced at the rate. Errors: OUT_OF_RANGE at the end (no loop);
  // FAILED_PRECONDITION naming a frame file that is missing, unreadable or
  // of the wrong size or type.
  absl::StatusOr<domain::RgbdFrame> Next() override;
  std::string name() const override { return "replay:" + dir_; }
  const domain::CameraIntrinsics& intrinsics() const { return intrinsics_; }

 private:
  ReplaySource(std::string dir, domain::CameraIntrinsics intrinsics,
               int64_t count, double rate_hz, bool loop);

  const std::string dir_;
  const domain::CameraIntrinsics intrinsics_;
  const int64_t count_;
  const bool loop_;
  Pacer pacer_;
  uint64_t sequence_ = 0;
};

// Passes another source's frames on and writes each into a recording (the
// camera.txt header with the first frame's intrinsics and `rate_hz`), so
// that a session at the table can be replayed. Recording is a side line
// of feeding: a frame that cannot be written (a full disk) ends the
// recording there, whole up to the frame before (no holes, which would
// replay as dropped frames), says so on stderr once, and the camera goes
// on serving frames.
class RecordingSource final : public FrameSource {
 public:
  RecordingSource(std::unique_ptr<FrameSource> inner, std::string dir,
                  double rate_hz)
      : inner_(std::move(inner)), dir_(std::move(dir)), rate_hz_(rate_hz) {}

  // FAILED_PRECONDITION naming `dir` when it already holds a recording (a
  // second session written over the first would replay the first's tail).
  static absl::Status CheckNewRecording(const std::string& dir);

  absl::StatusOr<domain::RgbdFrame> Next() override;
  std::string name() const override {
    return inner_->name() + " (recording to " + dir_ + ")";
  }
  // Why the recording ended early; OK while it goes on.
  absl::Status recording_error() const { return error_; }
  int64_t frames_written() const { return written_; }

 private:
  void Stop(absl::Status why);

  const std::unique_ptr<FrameSource> inner_;
  const std::string dir_;
  const double rate_hz_;
  int64_t written_ = 0;
  absl::Status error_;
};

}  // namespace bitewise::camera

#endif  // BITEWISE_SERVICES_CAMERA_RECORDING_H_
