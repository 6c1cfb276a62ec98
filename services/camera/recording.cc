#include "services/camera/recording.h"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <utility>
#include <vector>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_split.h"
#include "absl/time/clock.h"
#include "absl/time/time.h"
#include "opencv2/core.hpp"
#include "opencv2/imgcodecs.hpp"
#include "opencv2/imgproc.hpp"

namespace bitewise::camera {
namespace {

std::string FramePath(const std::string& dir, int64_t index, const char* kind) {
  return absl::StrFormat("%s/%06d.%s.png", dir, index, kind);
}

}  // namespace

absl::Status WriteRecordingHeader(const std::string& dir,
                                  const domain::CameraIntrinsics& k,
                                  double rate_hz) {
  const std::string path = dir + "/camera.txt";
  std::ofstream out(path, std::ios::trunc);
  out << absl::StrFormat(
      "version 1\nwidth %d\nheight %d\nfx %.17g\nfy %.17g\ncx %.17g\ncy "
      "%.17g\nrate_hz %.17g\n",
      k.width, k.height, k.fx, k.fy, k.cx, k.cy, rate_hz);
  out.flush();
  if (!out) {
    return absl::FailedPreconditionError(
        absl::StrCat("cannot write \"", path, "\""));
  }
  return absl::OkStatus();
}

absl::Status WriteRecordedFrame(const std::string& dir, int64_t index,
                                const domain::RgbdFrame& frame) {
  const domain::CameraIntrinsics& k = frame.intrinsics;
  const size_t pixels = static_cast<size_t>(k.width) * k.height;
  if (k.width <= 0 || k.height <= 0 || frame.rgb.size() != pixels * 3 ||
      frame.depth_mm.size() != pixels) {
    return absl::InvalidArgumentError(absl::StrCat(
        "frame ", index, " has ", frame.rgb.size(), " RGB bytes and ",
        frame.depth_mm.size(), " depth values for ", k.width, "x", k.height));
  }
  cv::Mat rgb(k.height, k.width, CV_8UC3,
              const_cast<uint8_t*>(frame.rgb.data()));
  cv::Mat bgr;
  cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
  const cv::Mat depth(k.height, k.width, CV_16UC1,
                      const_cast<uint16_t*>(frame.depth_mm.data()));
  for (const auto& [path, image] :
       {std::pair{FramePath(dir, index, "rgb"), bgr},
        std::pair{FramePath(dir, index, "depth"), depth}}) {
    if (!cv::imwrite(path, image)) {
      return absl::FailedPreconditionError(
          absl::StrCat("cannot write \"", path, "\""));
    }
  }
  return absl::OkStatus();
}

ReplaySource::ReplaySource(std::string dir, domain::CameraIntrinsics k,
                           int64_t count, double rate_hz, bool loop)
    : dir_(std::move(dir)),
      intrinsics_(k),
      count_(count),
      loop_(loop),
      pacer_(rate_hz) {}

absl::StatusOr<std::unique_ptr<ReplaySource>> ReplaySource::Open(
    const std::string& dir, const ReplayOptions& options) {
  const std::string header = dir + "/camera.txt";
  std::ifstream in(header);
  if (!in) {
    return absl::NotFoundError(absl::StrCat(
        "recording \"", dir, "\": no camera.txt (not a recording?)"));
  }
  std::map<std::string, double> values;
  std::string line;
  for (int n = 1; std::getline(in, line); ++n) {
    std::vector<std::string> words =
        absl::StrSplit(line, ' ', absl::SkipWhitespace());
    if (words.empty()) continue;
    double v = 0.0;
    if (words.size() != 2 || !absl::SimpleAtod(words[1], &v) ||
        !std::isfinite(v)) {
      return absl::InvalidArgumentError(
          absl::StrCat(header, " line ", n,
                       ": expected \"name number\", got \"", line, "\""));
    }
    values[words[0]] = v;
  }
  for (const char* key :
       {"version", "width", "height", "fx", "fy", "cx", "cy", "rate_hz"}) {
    if (!values.count(key)) {
      return absl::InvalidArgumentError(
          absl::StrCat(header, ": no \"", key, "\" line"));
    }
  }
  const double rate = options.rate_hz > 0 ? options.rate_hz : values["rate_hz"];
  for (const char* side : {"width", "height"}) {
    const double v = values[side];
    if (!(v >= 1 && v <= domain::kMaxFrameSide && v == std::floor(v))) {
      return absl::InvalidArgumentError(
          absl::StrCat(header, ": ", side, " ", v, " is not a whole number of ",
                       "pixels in [1, ", domain::kMaxFrameSide, "]"));
    }
  }
  domain::CameraIntrinsics k;
  k.width = static_cast<int>(values["width"]);
  k.height = static_cast<int>(values["height"]);
  k.fx = values["fx"];
  k.fy = values["fy"];
  k.cx = values["cx"];
  k.cy = values["cy"];
  if (values["version"] != 1 || !(rate > 0)) {
    return absl::InvalidArgumentError(
        absl::StrCat(header, ": version must be 1 and rate_hz > 0"));
  }
  if (absl::Status valid =
          domain::ValidateIntrinsics(k, absl::StrCat(header, ": intrinsics"));
      !valid.ok()) {
    return valid;
  }
  int64_t count = 0;
  while (std::filesystem::exists(FramePath(dir, count, "rgb"))) ++count;
  if (count == 0) {
    return absl::FailedPreconditionError(absl::StrCat(
        "recording \"", dir, "\" has no frames (000000.rgb.png missing)"));
  }
  return std::unique_ptr<ReplaySource>(
      new ReplaySource(dir, k, count, rate, options.loop));
}

absl::StatusOr<domain::RgbdFrame> ReplaySource::Next() {
  if (!loop_ && sequence_ >= static_cast<uint64_t>(count_)) {
    return absl::OutOfRangeError(absl::StrCat(
        "recording \"", dir_, "\" ended after ", count_, " frames"));
  }
  pacer_.Wait();
  // Counted before it is read: a damaged frame is skipped (named once a
  // pass), not read again forever, and shows as a dropped frame.
  const uint64_t sequence = sequence_++;
  const int64_t index = static_cast<int64_t>(sequence % count_);
  const std::string rgb_path = FramePath(dir_, index, "rgb");
  const std::string depth_path = FramePath(dir_, index, "depth");
  const cv::Mat bgr = cv::imread(rgb_path, cv::IMREAD_COLOR);
  const cv::Mat depth = cv::imread(depth_path, cv::IMREAD_UNCHANGED);
  const cv::Size size(intrinsics_.width, intrinsics_.height);
  if (bgr.empty() || bgr.size() != size) {
    return absl::FailedPreconditionError(
        absl::StrCat("\"", rgb_path, "\" is missing, unreadable or not ",
                     size.width, "x", size.height));
  }
  if (depth.empty() || depth.size() != size || depth.type() != CV_16UC1) {
    return absl::FailedPreconditionError(
        absl::StrCat("\"", depth_path, "\" is missing, unreadable or not a ",
                     size.width, "x", size.height, " 16-bit depth image"));
  }
  domain::RgbdFrame frame;
  frame.intrinsics = intrinsics_;
  frame.rgb.resize(static_cast<size_t>(size.area()) * 3);
  cv::Mat rgb(size, CV_8UC3, frame.rgb.data());
  cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
  frame.depth_mm.assign(depth.begin<uint16_t>(), depth.end<uint16_t>());
  frame.sequence = sequence;
  frame.capture_s = SteadyNowS();
  return frame;
}

absl::Status RecordingSource::CheckNewRecording(const std::string& dir) {
  for (const std::string& path :
       {dir + "/camera.txt", FramePath(dir, 0, "rgb")}) {
    std::error_code error;
    if (std::filesystem::exists(path, error)) {
      return absl::FailedPreconditionError(absl::StrCat(
          "\"", dir, "\" already holds a recording (", path,
          "); record into a new directory (a second session written over "
          "the first would replay the first's tail after it)"));
    }
  }
  return absl::OkStatus();
}

void RecordingSource::Stop(absl::Status why) {
  error_ = std::move(why);
  std::fprintf(stderr,
               "bitewise-camera: recording to %s stopped after %lld frames "
               "(the recording is whole up to there; the camera goes on "
               "serving frames): %s\n",
               dir_.c_str(), static_cast<long long>(written_),
               error_.ToString().c_str());
  std::fflush(stderr);
}

absl::StatusOr<domain::RgbdFrame> RecordingSource::Next() {
  absl::StatusOr<domain::RgbdFrame> frame = inner_->Next();
  if (!frame.ok() || !error_.ok()) return frame;
  if (written_ == 0) {
    if (absl::Status fresh = CheckNewRecording(dir_); !fresh.ok()) {
      Stop(fresh);
      return frame;
    }
    std::error_code error;
    std::filesystem::create_directories(dir_, error);
    absl::Status header =
        WriteRecordingHeader(dir_, frame->intrinsics, rate_hz_);
    if (!header.ok()) {
      Stop(header);
      return frame;
    }
  }
  absl::Status written = WriteRecordedFrame(dir_, written_, *frame);
  if (!written.ok()) {
    // A colour image without its depth would replay as a damaged frame.
    std::error_code ignored;
    std::filesystem::remove(FramePath(dir_, written_, "rgb"), ignored);
    Stop(written);
    return frame;
  }
  ++written_;
  return frame;
}

}  // namespace bitewise::camera
