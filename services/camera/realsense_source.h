// The Intel RealSense D415 as a FrameSource, through the RealSense SDK 2.0
// C API loaded at run time (dlopen; realsense_api.h), so bitewise builds
// without the SDK and a lab installs the SDK it has. Colour (RGB8) and
// depth (Z16) streams at one size and rate, depth aligned to colour by the
// SDK's align block, depth converted to millimetres with the device's
// depth units, the colour stream's intrinsics, and the colour frame's
// counter as the sequence (gaps are frames the camera dropped).
//
// Not thread-safe (one publisher thread).
#ifndef BITEWISE_SERVICES_CAMERA_REALSENSE_SOURCE_H_
#define BITEWISE_SERVICES_CAMERA_REALSENSE_SOURCE_H_

#include <atomic>
#include <cstdint>
#include <memory>
#include <string>

#include "absl/status/statusor.h"
#include "services/camera/frame_source.h"

namespace bitewise::camera {

struct RealSenseOptions {
  // The SDK's shared library; empty tries librealsense2.so, then the
  // run-time names librealsense2.so.2.60 down to 2.50.
  std::string library;
  int width = 640;
  int height = 480;
  int fps = 15;
  // How long Next waits for a frameset before UNAVAILABLE.
  int timeout_ms = 1000;
};

class RealSenseSource final : public FrameSource {
 public:
  // Loads the SDK, starts the streams and the align block. Errors:
  // NOT_FOUND when the library cannot be loaded (naming it and dlerror);
  // FAILED_PRECONDITION naming a function the library lacks, or the SDK's
  // own error (no device, a mode it does not support) with the call that
  // failed; INVALID_ARGUMENT for non-positive sizes or rate.
  static absl::StatusOr<std::unique_ptr<RealSenseSource>> Open(
      const RealSenseOptions& options);
  ~RealSenseSource() override;

  // Errors: UNAVAILABLE when no frameset arrives in timeout_ms (the SDK's
  // message), or when the streams cannot be started again after such a
  // failure (a camera unplugged: the SDK's message, after the failure's);
  // FAILED_PRECONDITION when a frameset lacks the colour or the aligned
  // depth frame, or they are not the configured size. After an
  // UNAVAILABLE the next call stops and starts the streams first, so a
  // camera plugged back in is found again.
  absl::StatusOr<domain::RgbdFrame> Next() override;
  std::string name() const override;

  // How many times the streams were started again after a failure.
  int restarts() const { return restarts_; }

  struct Api;  // the resolved functions (realsense_source.cc)
  struct Handles;

 private:
  RealSenseSource(std::unique_ptr<Api> api, std::unique_ptr<Handles> handles,
                  const RealSenseOptions& options, std::string library);

  absl::Status Restart();

  std::unique_ptr<Api> api_;
  std::unique_ptr<Handles> handles_;
  const RealSenseOptions options_;
  const std::string library_;
  std::string restart_reason_;  // non-empty: start the streams again first
  uint64_t sequence_offset_ = 0;
  bool rebase_ = false;  // the next frame continues after last_sequence_
  uint64_t last_sequence_ = 0;
  std::atomic<int> restarts_{0};
};

}  // namespace bitewise::camera

#endif  // BITEWISE_SERVICES_CAMERA_REALSENSE_SOURCE_H_
