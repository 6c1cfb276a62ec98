// libFuzzer target: PerceptionService frame decoding (sizes, encodings,
// PNG/JPEG headers and bodies, depth, intrinsics) on arbitrary input. The
// first 12 bytes choose width, height, encoding and how the rest is split
// between the RGB and depth payloads; a frame that decodes must have the
// size it claimed.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>

#include "absl/strings/string_view.h"
#include "services/perception/frame.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace bitewise::perception;  // NOLINT: one namespace
  if (size < 12) return 0;
  uint16_t width, height;
  uint32_t split;
  std::memcpy(&width, data, 2);
  std::memcpy(&height, data + 2, 2);
  const uint8_t encoding = data[4];
  std::memcpy(&split, data + 8, 4);
  const char* rest = reinterpret_cast<const char*>(data + 12);
  const size_t rest_size = size - 12;
  const size_t rgb_size = rest_size == 0 ? 0 : split % (rest_size + 1);
  FrameBytes bytes;
  bytes.width = width;
  bytes.height = height;
  bytes.encoding = static_cast<ImageEncoding>(encoding % 4);
  bytes.rgb = absl::string_view(rest, rgb_size);
  bytes.depth_mm = absl::string_view(rest + rgb_size, rest_size - rgb_size);
  bytes.intrinsics.fx = data[5] == 0 ? 0.0 : 615.0;
  bytes.intrinsics.fy = 615.0;
  bytes.intrinsics.cx = data[6];
  bytes.intrinsics.cy = data[7];
  absl::StatusOr<DecodedFrame> frame = DecodeFrame(bytes);
  if (frame.ok() && (frame->width() != width || frame->height() != height)) {
    std::abort();
  }
  return 0;
}
