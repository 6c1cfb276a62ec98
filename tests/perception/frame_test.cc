// DecodeFrame and ValidateBox: every malformed field gets INVALID_ARGUMENT
// naming it; good RGB8, PNG and JPEG frames decode to the same pixels.
#include "services/perception/frame.h"

#include <string>

#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "services/perception/converters.h"
#include "tests/perception/test_frames.h"

namespace bitewise::perception {
namespace {

using ::testing::HasSubstr;

class FrameTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    scene_ = new testing::TestScene(testing::RenderTestScene(1, 3, false));
  }
  static void TearDownTestSuite() { delete scene_; }

  v1::Frame Proto(v1::ImageEncoding encoding) {
    return testing::ToProto(scene_->rendered, encoding);
  }
  static testing::TestScene* scene_;
};
testing::TestScene* FrameTest::scene_ = nullptr;

absl::StatusOr<DecodedFrame> Decode(const v1::Frame& frame) {
  return DecodeFrame(FrameBytesFromProto(frame));
}

TEST_F(FrameTest, Rgb8AndPngDecodeToTheRenderedPixels) {
  for (auto encoding : {v1::IMAGE_ENCODING_RGB8, v1::IMAGE_ENCODING_PNG}) {
    const v1::Frame proto = Proto(encoding);
    absl::StatusOr<DecodedFrame> frame = Decode(proto);
    ASSERT_TRUE(frame.ok()) << frame.status();
    EXPECT_EQ(frame->width(), 640);
    EXPECT_EQ(frame->height(), 480);
    ASSERT_TRUE(frame->has_depth());
    EXPECT_EQ(std::memcmp(frame->rgb.data, scene_->rendered.rgb.data(),
                          scene_->rendered.rgb.size()),
              0);
    EXPECT_EQ(frame->depth_mm.at<uint16_t>(240, 320),
              scene_->rendered.depth_mm[240 * 640 + 320]);
  }
}

TEST_F(FrameTest, JpegDecodesCloseToTheRenderedPixels) {
  absl::StatusOr<DecodedFrame> frame = Decode(Proto(v1::IMAGE_ENCODING_JPEG));
  ASSERT_TRUE(frame.ok()) << frame.status();
  const cv::Mat original(480, 640, CV_8UC3, scene_->rendered.rgb.data());
  EXPECT_LT(cv::norm(frame->rgb, original, cv::NORM_L1) / original.total(),
            3 * 4.0);
}

// `jpeg` with an EXIF block (APP1, right after the start-of-image marker)
// whose orientation tag is `orientation` (1-8).
std::string WithExifOrientation(const std::string& jpeg, int orientation) {
  std::string tiff("MM\0\x2a\0\0\0\x08", 8);           // big-endian, IFD at 8
  tiff += std::string("\0\x01", 2);                    // one entry:
  tiff += std::string("\x01\x12\0\x03\0\0\0\x01", 8);  // Orientation, SHORT x1
  tiff += std::string("\0", 1) + static_cast<char>(orientation);
  tiff += std::string("\0\0", 2);      // value padding
  tiff += std::string("\0\0\0\0", 4);  // no next IFD
  const std::string payload = std::string("Exif\0\0", 6) + tiff;
  const size_t length = payload.size() + 2;
  std::string app1("\xff\xe1", 2);
  app1 += static_cast<char>(length >> 8);
  app1 += static_cast<char>(length & 0xff);
  return jpeg.substr(0, 2) + app1 + payload + jpeg.substr(2);
}

// A camera's frame is its sensor's grid, aligned with its depth: an EXIF
// orientation tag must not turn the colour image against the depth (it
// did: OpenCV applies it by default, and DetectFood found other items).
TEST_F(FrameTest, AJpegsExifOrientationIsIgnored) {
  const v1::Frame plain = Proto(v1::IMAGE_ENCODING_JPEG);
  absl::StatusOr<DecodedFrame> expected = Decode(plain);
  ASSERT_TRUE(expected.ok()) << expected.status();
  for (const int orientation : {2, 3, 6}) {
    v1::Frame tagged = plain;
    tagged.set_rgb(WithExifOrientation(plain.rgb(), orientation));
    absl::StatusOr<DecodedFrame> frame = Decode(tagged);
    ASSERT_TRUE(frame.ok()) << orientation << ": " << frame.status();
    EXPECT_EQ(cv::norm(frame->rgb, expected->rgb, cv::NORM_INF), 0)
        << "orientation " << orientation;
  }
}

TEST_F(FrameTest, DepthMayBeAbsent) {
  v1::Frame proto = Proto(v1::IMAGE_ENCODING_RGB8);
  proto.clear_depth_mm();
  absl::StatusOr<DecodedFrame> frame = Decode(proto);
  ASSERT_TRUE(frame.ok()) << frame.status();
  EXPECT_FALSE(frame->has_depth());
}

void ExpectInvalid(const v1::Frame& proto, const std::string& fragment) {
  absl::StatusOr<DecodedFrame> frame = Decode(proto);
  ASSERT_FALSE(frame.ok());
  EXPECT_EQ(frame.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(frame.status().message(), HasSubstr(fragment));
}

TEST_F(FrameTest, CorruptPngIsInvalidArgument) {
  v1::Frame proto = Proto(v1::IMAGE_ENCODING_PNG);
  std::string bytes = proto.rgb();
  // Keep the signature and the header, destroy the chunks after them.
  for (size_t i = 40; i < bytes.size(); i += 7) bytes[i] ^= 0x5A;
  proto.set_rgb(bytes);
  ExpectInvalid(proto, "corrupt IMAGE_ENCODING_PNG");
}

TEST_F(FrameTest, TruncatedJpegIsInvalidArgument) {
  v1::Frame proto = Proto(v1::IMAGE_ENCODING_JPEG);
  proto.set_rgb(proto.rgb().substr(0, 40));
  ExpectInvalid(proto, "corrupt IMAGE_ENCODING_JPEG");
}

// Cut inside its image data, after the header: OpenCV would decode it with
// junk rows; its missing end-of-image marker gives it away.
TEST_F(FrameTest, JpegCutShortInItsImageDataIsInvalidArgument) {
  v1::Frame proto = Proto(v1::IMAGE_ENCODING_JPEG);
  proto.set_rgb(proto.rgb().substr(0, proto.rgb().size() / 2));
  ExpectInvalid(proto, "JPEG data without its end-of-image marker");
}

TEST_F(FrameTest, BytesOfAnotherFormatAreInvalidArgument) {
  v1::Frame proto = Proto(v1::IMAGE_ENCODING_JPEG);
  proto.set_rgb_encoding(v1::IMAGE_ENCODING_PNG);
  ExpectInvalid(proto, "does not start with the PNG signature");
  proto = Proto(v1::IMAGE_ENCODING_RGB8);
  proto.set_rgb_encoding(v1::IMAGE_ENCODING_JPEG);
  ExpectInvalid(proto, "JPEG signature");
}

TEST_F(FrameTest, PngOfAnotherSizeIsInvalidArgument) {
  v1::Frame proto = Proto(v1::IMAGE_ENCODING_PNG);
  proto.set_width(320);
  proto.clear_depth_mm();
  ExpectInvalid(proto,
                "header says 640x480 but frame.width x frame.height "
                "is 320x480 (not decoded)");
}

// A small file whose header claims a huge image is refused from its header,
// before the decoder allocates gigabytes for it.
TEST_F(FrameTest, HeaderClaimingAHugeImageIsRefusedBeforeDecoding) {
  v1::Frame png = Proto(v1::IMAGE_ENCODING_PNG);
  std::string bytes = png.rgb();
  for (int i = 0; i < 2; ++i) {  // IHDR width and height: 20000
    bytes[16 + 4 * i] = 0;
    bytes[17 + 4 * i] = 0;
    bytes[18 + 4 * i] = static_cast<char>(20000 >> 8);
    bytes[19 + 4 * i] = static_cast<char>(20000 & 0xFF);
  }
  png.set_rgb(bytes);
  ExpectInvalid(png, "PNG header says 20000x20000");
  v1::Frame jpeg = Proto(v1::IMAGE_ENCODING_JPEG);
  bytes = jpeg.rgb();
  const size_t sof = bytes.find("\xFF\xC0");
  ASSERT_NE(sof, std::string::npos);
  bytes[sof + 5] = static_cast<char>(0x4E);  // height 20000 (0x4E20)
  bytes[sof + 6] = static_cast<char>(0x20);
  jpeg.set_rgb(bytes);
  ExpectInvalid(jpeg, "JPEG header says 640x20000");
}

TEST_F(FrameTest, WrongRgbLengthIsInvalidArgument) {
  v1::Frame proto = Proto(v1::IMAGE_ENCODING_RGB8);
  proto.mutable_rgb()->pop_back();
  ExpectInvalid(proto, "frame.rgb has 921599 bytes");
}

TEST_F(FrameTest, DepthSizeMismatchIsInvalidArgument) {
  v1::Frame proto = Proto(v1::IMAGE_ENCODING_RGB8);
  proto.set_depth_mm(std::string(320 * 240 * 2, '\0'));
  ExpectInvalid(proto, "frame.depth_mm has 153600 bytes");
}

TEST_F(FrameTest, BadSizesEncodingAndIntrinsicsAreInvalidArgument) {
  v1::Frame proto = Proto(v1::IMAGE_ENCODING_RGB8);
  proto.set_width(0);
  ExpectInvalid(proto, "frame.width and frame.height must be > 0");
  proto = Proto(v1::IMAGE_ENCODING_RGB8);
  proto.set_height(100000);
  ExpectInvalid(proto, "exceeds the limit");
  proto = Proto(v1::IMAGE_ENCODING_RGB8);
  proto.set_width(4000);
  proto.set_height(4000);
  ExpectInvalid(proto, "exceeds the limit of 8388608 pixels");
  proto = Proto(v1::IMAGE_ENCODING_RGB8);
  proto.set_rgb_encoding(v1::IMAGE_ENCODING_UNSPECIFIED);
  ExpectInvalid(proto, "frame.rgb_encoding");
  proto = Proto(v1::IMAGE_ENCODING_RGB8);
  proto.mutable_intrinsics()->set_fx(0);
  ExpectInvalid(proto, "frame.intrinsics.fx");
  proto = Proto(v1::IMAGE_ENCODING_RGB8);
  proto.mutable_intrinsics()->set_cy(std::nan(""));
  ExpectInvalid(proto, "frame.intrinsics.cx and cy");
  // Focal lengths whose square underflows, or absurd ones; a principal
  // point far off the image.
  for (double fx : {1e-200, 0.5, 1e7}) {
    proto = Proto(v1::IMAGE_ENCODING_RGB8);
    proto.mutable_intrinsics()->set_fx(fx);
    ExpectInvalid(proto, "frame.intrinsics.fx and fy must be focal lengths");
  }
  proto = Proto(v1::IMAGE_ENCODING_RGB8);
  proto.mutable_intrinsics()->set_cx(1e6);
  ExpectInvalid(proto, "frame.intrinsics.cx and cy must be finite and within");
}

TEST(ValidateBoxTest, AcceptsBoxesInsideAndRejectsOthers) {
  EXPECT_TRUE(ValidateBox({0, 0, 640, 480}, 640, 480).ok());
  EXPECT_TRUE(ValidateBox({600, 400, 40, 80}, 640, 480).ok());
  for (const PixelBox& outside :
       {PixelBox{-1, 0, 10, 10}, PixelBox{0, -5, 10, 10},
        PixelBox{631, 0, 10, 10}, PixelBox{0, 471, 10, 10},
        PixelBox{2147483000, 0, 2000, 10}}) {
    const absl::Status status = ValidateBox(outside, 640, 480);
    EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
    EXPECT_THAT(status.message(), HasSubstr("lies outside the 640x480 frame"));
  }
  for (const PixelBox& empty :
       {PixelBox{10, 10, 0, 10}, PixelBox{10, 10, 10, 0},
        PixelBox{10, 10, -3, 10}}) {
    const absl::Status status = ValidateBox(empty, 640, 480);
    EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
    EXPECT_THAT(status.message(), HasSubstr("empty crop"));
  }
}

}  // namespace
}  // namespace bitewise::perception
