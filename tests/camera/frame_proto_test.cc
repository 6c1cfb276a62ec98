// RGB-D frames to and from the API's Frame (services/camera/frame_proto.h):
// depth goes little-endian whatever the host, a round trip keeps every
// pixel, and each malformed field is INVALID_ARGUMENT naming it.
#include "services/camera/frame_proto.h"

#include <cstdint>
#include <limits>
#include <string>

#include "absl/strings/str_cat.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace bitewise::camera {
namespace {

using ::testing::HasSubstr;

// A 3x2 frame whose every byte differs, depths using both bytes.
domain::RgbdFrame SmallFrame() {
  domain::RgbdFrame frame;
  frame.intrinsics = {3, 2, 600.5, 601.25, 1.5, 0.75};
  for (int i = 0; i < 3 * 2 * 3; ++i) frame.rgb.push_back(10 + 7 * i);
  frame.depth_mm = {0, 1, 0x1234, 0xff00, 0x00ff, 0xffff};
  return frame;
}

v1::Frame SmallProto() {
  v1::Frame proto;
  FrameToProto(SmallFrame(), 12.5, "wrist", &proto);
  return proto;
}

TEST(FrameToProtoTest, WritesRgb8LittleEndianDepthAndTheIntrinsics) {
  const domain::RgbdFrame frame = SmallFrame();
  const v1::Frame proto = SmallProto();
  EXPECT_EQ(proto.width(), 3u);
  EXPECT_EQ(proto.height(), 2u);
  EXPECT_EQ(proto.rgb_encoding(), v1::IMAGE_ENCODING_RGB8);
  EXPECT_EQ(proto.rgb(), std::string(frame.rgb.begin(), frame.rgb.end()));
  const std::string want_depth(
      "\x00\x00\x01\x00\x34\x12\x00\xff\xff\x00\xff\xff", 12);
  EXPECT_EQ(proto.depth_mm(), want_depth);
  EXPECT_EQ(proto.intrinsics().fx(), 600.5);
  EXPECT_EQ(proto.intrinsics().fy(), 601.25);
  EXPECT_EQ(proto.intrinsics().cx(), 1.5);
  EXPECT_EQ(proto.intrinsics().cy(), 0.75);
  EXPECT_EQ(proto.timestamp_s(), 12.5);
  EXPECT_EQ(proto.frame_id(), "wrist");
}

TEST(FrameFromProtoTest, ARoundTripKeepsEveryPixelAndTheIntrinsics) {
  const domain::RgbdFrame frame = SmallFrame();
  const absl::StatusOr<domain::RgbdFrame> back = FrameFromProto(SmallProto());
  ASSERT_TRUE(back.ok()) << back.status();
  EXPECT_EQ(back->rgb, frame.rgb);
  EXPECT_EQ(back->depth_mm, frame.depth_mm);
  EXPECT_EQ(back->intrinsics.width, 3);
  EXPECT_EQ(back->intrinsics.height, 2);
  EXPECT_EQ(back->intrinsics.fx, 600.5);
  EXPECT_EQ(back->intrinsics.fy, 601.25);
  EXPECT_EQ(back->intrinsics.cx, 1.5);
  EXPECT_EQ(back->intrinsics.cy, 0.75);
}

TEST(FrameFromProtoTest, AnotherEncodingIsRefusedNamingIt) {
  v1::Frame proto = SmallProto();
  proto.set_rgb_encoding(v1::IMAGE_ENCODING_PNG);
  const absl::Status status = FrameFromProto(proto).status();
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(status.message(), HasSubstr("frame.rgb_encoding"));
  EXPECT_THAT(status.message(), HasSubstr("IMAGE_ENCODING_PNG"));
}

TEST(FrameFromProtoTest, SidesOfZeroOrOver8192AreRefusedNamingTheSize) {
  for (const auto& [width, height] :
       {std::pair<uint32_t, uint32_t>{0, 2}, {3, 0}, {8193, 2}, {3, 8193}}) {
    v1::Frame proto = SmallProto();
    proto.set_width(width);
    proto.set_height(height);
    const absl::Status status = FrameFromProto(proto).status();
    EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
    EXPECT_THAT(status.message(),
                HasSubstr(absl::StrCat("frame size ", width, "x", height)));
    EXPECT_THAT(status.message(), HasSubstr("[1, 8192]"));
  }
}

TEST(FrameFromProtoTest, RgbOrDepthOfTheWrongLengthIsRefusedNamingIt) {
  v1::Frame short_rgb = SmallProto();
  short_rgb.mutable_rgb()->pop_back();
  absl::Status status = FrameFromProto(short_rgb).status();
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(status.message(), HasSubstr("frame.rgb: 17 bytes"));
  EXPECT_THAT(status.message(), HasSubstr("expected 18"));

  // The same bytes read as a frame of another shape do not fit either.
  v1::Frame reshaped = SmallProto();
  reshaped.set_width(2);
  reshaped.set_height(3);
  EXPECT_TRUE(FrameFromProto(reshaped).ok());
  reshaped.set_width(6);
  reshaped.set_height(1);
  EXPECT_TRUE(FrameFromProto(reshaped).ok());
  reshaped.set_width(4);
  EXPECT_THAT(FrameFromProto(reshaped).status().message(),
              HasSubstr("frame.rgb"));

  v1::Frame long_depth = SmallProto();
  long_depth.mutable_depth_mm()->append("\x01\x02", 2);
  status = FrameFromProto(long_depth).status();
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(status.message(), HasSubstr("frame.depth_mm: 14 bytes"));
  EXPECT_THAT(status.message(), HasSubstr("expected 12"));

  v1::Frame no_depth = SmallProto();
  no_depth.clear_depth_mm();
  EXPECT_THAT(FrameFromProto(no_depth).status().message(),
              HasSubstr("frame.depth_mm: 0 bytes"));
}

TEST(FrameFromProtoTest, BadFocalLengthsOrPrincipalPointAreRefusedNamingThem) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  struct Bad {
    double fx, fy, cx, cy;
  };
  for (const Bad& bad :
       {Bad{0.0, 600.0, 1.0, 1.0}, Bad{-600.0, 600.0, 1, 1},
        Bad{600.0, nan, 1.0, 1.0}, Bad{inf, 600.0, 1.0, 1.0},
        Bad{600.0, 600.0, nan, 1.0}, Bad{600.0, 600.0, 1.0, -inf},
        // Perception's rule, here at the link: a focal length below a
        // pixel, a principal point far off the 3x2 image.
        Bad{1e-200, 600.0, 1.0, 1.0}, Bad{600.0, 2e6, 1.0, 1.0},
        Bad{600.0, 600.0, 1000.0, 1.0}}) {
    v1::Frame proto = SmallProto();
    proto.mutable_intrinsics()->set_fx(bad.fx);
    proto.mutable_intrinsics()->set_fy(bad.fy);
    proto.mutable_intrinsics()->set_cx(bad.cx);
    proto.mutable_intrinsics()->set_cy(bad.cy);
    const absl::Status status = FrameFromProto(proto).status();
    EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument)
        << bad.fx << " " << bad.fy << " " << bad.cx << " " << bad.cy;
    EXPECT_THAT(status.message(), HasSubstr("frame.intrinsics"));
  }
  v1::Frame no_intrinsics = SmallProto();
  no_intrinsics.clear_intrinsics();
  EXPECT_THAT(FrameFromProto(no_intrinsics).status().message(),
              HasSubstr("frame.intrinsics"));
}

}  // namespace
}  // namespace bitewise::camera
