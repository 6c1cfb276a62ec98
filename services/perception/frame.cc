#include "services/perception/frame.h"

#include <cmath>
#include <cstdint>
#include <cstring>
#include <optional>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "opencv2/imgcodecs.hpp"
#include "opencv2/imgproc.hpp"

namespace bitewise::perception {
namespace {

absl::Status Invalid(absl::string_view message) {
  return absl::InvalidArgumentError(message);
}

const char* EncodingName(ImageEncoding encoding) {
  switch (encoding) {
    case ImageEncoding::kRgb8:
      return "IMAGE_ENCODING_RGB8";
    case ImageEncoding::kPng:
      return "IMAGE_ENCODING_PNG";
    case ImageEncoding::kJpeg:
      return "IMAGE_ENCODING_JPEG";
    case ImageEncoding::kUnspecified:
      break;
  }
  return "IMAGE_ENCODING_UNSPECIFIED";
}

bool HasSignature(absl::string_view bytes, ImageEncoding encoding) {
  if (encoding == ImageEncoding::kPng) {
    static constexpr char kPng[] = "\x89PNG\r\n\x1a\n";
    return bytes.size() >= 8 && std::memcmp(bytes.data(), kPng, 8) == 0;
  }
  return bytes.size() >= 3 && static_cast<unsigned char>(bytes[0]) == 0xFF &&
         static_cast<unsigned char>(bytes[1]) == 0xD8 &&
         static_cast<unsigned char>(bytes[2]) == 0xFF;
}

uint32_t BigEndian(absl::string_view b, size_t at, int n) {
  uint32_t v = 0;
  for (int i = 0; i < n; ++i) v = (v << 8) | static_cast<uint8_t>(b[at + i]);
  return v;
}

// The size a PNG or JPEG header declares, read without decoding, so that a
// small file claiming a huge image is refused before anything is
// allocated for it. nullopt when the header cannot be found.
std::optional<std::pair<uint32_t, uint32_t>> HeaderSize(
    absl::string_view b, ImageEncoding encoding) {
  if (encoding == ImageEncoding::kPng) {
    // Signature, then the IHDR chunk: length, type, width, height.
    if (b.size() < 24 || b.substr(12, 4) != "IHDR") return std::nullopt;
    return std::pair{BigEndian(b, 16, 4), BigEndian(b, 20, 4)};
  }
  // JPEG: walk the marker segments to the first start-of-frame.
  size_t at = 2;
  while (at + 4 <= b.size()) {
    if (static_cast<uint8_t>(b[at]) != 0xFF) return std::nullopt;
    const uint8_t marker = static_cast<uint8_t>(b[at + 1]);
    if (marker == 0xFF) {  // fill byte
      ++at;
      continue;
    }
    if (marker == 0x01 || (marker >= 0xD0 && marker <= 0xD7)) {
      at += 2;  // no length
      continue;
    }
    if (marker == 0xDA || marker == 0xD9) return std::nullopt;  // no SOF
    const uint32_t length = BigEndian(b, at + 2, 2);
    const bool sof = marker >= 0xC0 && marker <= 0xCF && marker != 0xC4 &&
                     marker != 0xC8 && marker != 0xCC;
    if (sof) {
      if (at + 9 > b.size()) return std::nullopt;
      return std::pair{BigEndian(b, at + 7, 2), BigEndian(b, at + 5, 2)};
    }
    at += 2 + length;
  }
  return std::nullopt;
}

absl::StatusOr<cv::Mat> DecodeRgb(const FrameBytes& bytes, int width,
                                  int height) {
  if (bytes.encoding == ImageEncoding::kRgb8) {
    const size_t expected = static_cast<size_t>(width) * height * 3;
    if (bytes.rgb.size() != expected) {
      return Invalid(absl::StrCat("frame.rgb has ", bytes.rgb.size(),
                                  " bytes; IMAGE_ENCODING_RGB8 at ", width, "x",
                                  height, " needs ", expected));
    }
    cv::Mat rgb(height, width, CV_8UC3);
    std::memcpy(rgb.data, bytes.rgb.data(), expected);
    return rgb;
  }
  const char* name = EncodingName(bytes.encoding);
  if (bytes.rgb.empty()) {
    return Invalid(absl::StrCat("frame.rgb is empty (", name, ")"));
  }
  if (!HasSignature(bytes.rgb, bytes.encoding)) {
    return Invalid(
        absl::StrCat("frame.rgb does not start with the ",
                     bytes.encoding == ImageEncoding::kPng ? "PNG" : "JPEG",
                     " signature although frame.rgb_encoding is ", name));
  }
  const auto declared = HeaderSize(bytes.rgb, bytes.encoding);
  if (!declared) {
    return Invalid(absl::StrCat("frame.rgb: corrupt ", name,
                                " data (no image size in its header)"));
  }
  if (declared->first != static_cast<uint32_t>(width) ||
      declared->second != static_cast<uint32_t>(height)) {
    return Invalid(absl::StrCat(
        "frame.rgb's ", bytes.encoding == ImageEncoding::kPng ? "PNG" : "JPEG",
        " header says ", declared->first, "x", declared->second,
        " but frame.width x frame.height is ", width, "x", height,
        " (not decoded)"));
  }
  // OpenCV decodes a baseline JPEG cut short inside its image data, filling
  // the missing rows with junk; a whole JPEG ends with its end-of-image
  // marker (FF D9), which some encoders follow with padding.
  if (bytes.encoding == ImageEncoding::kJpeg) {
    constexpr size_t kMaxPaddingBytes = 1024;
    const size_t eoi = bytes.rgb.rfind("\xFF\xD9");
    if (eoi == absl::string_view::npos ||
        bytes.rgb.size() - eoi > kMaxPaddingBytes) {
      return Invalid(
          "frame.rgb: JPEG data without its end-of-image marker (cut "
          "short?)");
    }
  }
  cv::Mat bgr;
  try {
    const cv::Mat buffer(1, static_cast<int>(bytes.rgb.size()), CV_8UC1,
                         const_cast<char*>(bytes.rgb.data()));
    // The sensor's grid as sent: an EXIF orientation would turn the colour
    // image against its depth.
    bgr =
        cv::imdecode(buffer, cv::IMREAD_COLOR | cv::IMREAD_IGNORE_ORIENTATION);
  } catch (const cv::Exception& e) {
    return Invalid(
        absl::StrCat("frame.rgb: corrupt ", name, " data: ", e.what()));
  }
  if (bgr.empty()) {
    return Invalid(absl::StrCat("frame.rgb: corrupt ", name, " data (",
                                bytes.rgb.size(),
                                " bytes that cannot be decoded)"));
  }
  if (bgr.cols != width || bgr.rows != height) {
    return Invalid(absl::StrCat("frame.rgb decodes to ", bgr.cols, "x",
                                bgr.rows, " but frame.width x frame.height is ",
                                width, "x", height));
  }
  cv::Mat rgb;
  cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
  return rgb;
}

}  // namespace

absl::StatusOr<DecodedFrame> DecodeFrame(const FrameBytes& bytes) {
  if (bytes.width <= 0 || bytes.height <= 0) {
    return Invalid(
        absl::StrCat("frame.width and frame.height must be > 0 (got ",
                     bytes.width, "x", bytes.height, ")"));
  }
  if (bytes.width > kMaxFrameSide || bytes.height > kMaxFrameSide) {
    return Invalid(absl::StrCat("frame size ", bytes.width, "x", bytes.height,
                                " exceeds the limit of ", kMaxFrameSide,
                                " pixels per side"));
  }
  if (bytes.width * bytes.height > kMaxFramePixels) {
    return Invalid(absl::StrCat("frame size ", bytes.width, "x", bytes.height,
                                " exceeds the limit of ", kMaxFramePixels,
                                " pixels (4K UHD is 8294400)"));
  }
  if (bytes.encoding == ImageEncoding::kUnspecified) {
    return Invalid(
        "frame.rgb_encoding is IMAGE_ENCODING_UNSPECIFIED; set RGB8, PNG or "
        "JPEG");
  }
  const int width = static_cast<int>(bytes.width);
  const int height = static_cast<int>(bytes.height);
  const CameraIntrinsics& k = bytes.intrinsics;
  CameraIntrinsics sized = k;
  sized.width = width;
  sized.height = height;
  if (absl::Status valid =
          domain::ValidateIntrinsics(sized, "frame.intrinsics");
      !valid.ok()) {
    return valid;
  }

  DecodedFrame frame;
  frame.intrinsics = k;
  frame.intrinsics.width = width;
  frame.intrinsics.height = height;
  absl::StatusOr<cv::Mat> rgb = DecodeRgb(bytes, width, height);
  if (!rgb.ok()) return rgb.status();
  frame.rgb = *std::move(rgb);

  if (!bytes.depth_mm.empty()) {
    const size_t expected = static_cast<size_t>(width) * height * 2;
    if (bytes.depth_mm.size() != expected) {
      return Invalid(absl::StrCat(
          "frame.depth_mm has ", bytes.depth_mm.size(), " bytes; a ", width,
          "x", height, " frame needs ", expected,
          " (one little-endian uint16 per RGB pixel) or none"));
    }
    frame.depth_mm.create(height, width, CV_16UC1);
    const auto* in =
        reinterpret_cast<const unsigned char*>(bytes.depth_mm.data());
    auto* out = frame.depth_mm.ptr<uint16_t>();
    const size_t n = static_cast<size_t>(width) * height;
    for (size_t i = 0; i < n; ++i) {
      out[i] = static_cast<uint16_t>(in[2 * i] | (in[2 * i + 1] << 8));
    }
  }
  return frame;
}

absl::Status ValidateBox(const PixelBox& box, int frame_width,
                         int frame_height) {
  if (box.width <= 0 || box.height <= 0) {
    return Invalid(absl::StrCat("bbox ", BoxToString(box),
                                " is an empty crop: width and height must be "
                                "> 0"));
  }
  // In 64 bits so that huge coordinates cannot overflow into the frame.
  const int64_t right = static_cast<int64_t>(box.x) + box.width;
  const int64_t bottom = static_cast<int64_t>(box.y) + box.height;
  if (box.x < 0 || box.y < 0 || right > frame_width || bottom > frame_height) {
    return Invalid(absl::StrCat("bbox ", BoxToString(box), " lies outside the ",
                                frame_width, "x", frame_height, " frame"));
  }
  return absl::OkStatus();
}

std::string BoxToString(const PixelBox& box) {
  return absl::StrCat("{x=", box.x, ", y=", box.y, ", width=", box.width,
                      ", height=", box.height, "}");
}

DecodedFrame ViewFrame(const CameraIntrinsics& intrinsics,
                       std::vector<uint8_t>& rgb,
                       std::vector<uint16_t>& depth_mm) {
  DecodedFrame frame;
  frame.intrinsics = intrinsics;
  frame.rgb = cv::Mat(intrinsics.height, intrinsics.width, CV_8UC3, rgb.data());
  if (!depth_mm.empty()) {
    frame.depth_mm =
        cv::Mat(intrinsics.height, intrinsics.width, CV_16UC1, depth_mm.data());
  }
  return frame;
}

}  // namespace bitewise::perception
