#include "services/camera/recording.h"

#include <cmath>
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
  domain::CameraIntrinsics k;
  k.width = static_cast<int>(values["width"]);
  k.height = static_cast<int>(values["height"]);
  k.fx = values["fx"];
  k.fy = values["fy"];
  k.cx = values["cx"];
  k.cy = values["cy"];
  const double rate = options.rate_hz > 0 ? options.rate_hz : values["rate_hz"];
  if (values["version"] != 1 || k.width <= 0 || k.height <= 0 || k.fx <= 0 ||
      k.fy <= 0 || rate <= 0) {
    return absl::InvalidArgumentError(absl::StrCat(
        header, ": version must be 1, sizes, focal lengths and rate_hz > 0"));
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
  const int64_t index = static_cast<int64_t>(sequence_ % count_);
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
  frame.sequence = sequence_++;
  frame.capture_s = SteadyNowS();
  return frame;
}

absl::StatusOr<domain::RgbdFrame> RecordingSource::Next() {
  absl::StatusOr<domain::RgbdFrame> frame = inner_->Next();
  if (!frame.ok()) return frame;
  if (written_ == 0) {
    std::error_code error;
    std::filesystem::create_directories(dir_, error);
    absl::Status header =
        WriteRecordingHeader(dir_, frame->intrinsics, rate_hz_);
    if (!header.ok()) return header;
  }
  absl::Status written = WriteRecordedFrame(dir_, written_, *frame);
  if (!written.ok()) return written;
  ++written_;
  return frame;
}

}  // namespace bitewise::camera
