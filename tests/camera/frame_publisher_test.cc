// FramePublisher (services/camera/frame_publisher.h) over real recordings:
// before its first frame it is unavailable naming the source's error, a
// finished recording's last frame is kept and ages until it is refused
// naming its age, the limit, the source and why, and a looping recording
// is published frame after frame with nothing dropped.
#include "services/camera/frame_publisher.h"

#include <filesystem>
#include <fstream>
#include <memory>
#include <string>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "absl/time/time.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "services/camera/recording.h"

namespace bitewise::camera {
namespace {

using ::testing::HasSubstr;

std::string FreshDir(const std::string& name) {
  const std::string dir = ::testing::TempDir() + "/frame_publisher_" + name;
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

// A 4x3 frame whose pixels say which frame it is.
domain::RgbdFrame TinyFrame(int index) {
  domain::RgbdFrame frame;
  frame.intrinsics = {4, 3, 5.0, 5.0, 2.0, 1.5};
  frame.rgb.assign(4 * 3 * 3, static_cast<uint8_t>(10 * index + 1));
  frame.depth_mm.assign(4 * 3, static_cast<uint16_t>(300 + index));
  return frame;
}

// A recording of `frames` tiny frames at 1 kHz.
std::string Record(const std::string& name, int frames) {
  const std::string dir = FreshDir(name);
  EXPECT_TRUE(WriteRecordingHeader(dir, TinyFrame(0).intrinsics, 1000.0).ok());
  for (int i = 0; i < frames; ++i) {
    EXPECT_TRUE(WriteRecordedFrame(dir, i, TinyFrame(i)).ok());
  }
  return dir;
}

std::unique_ptr<FrameSource> Replay(const std::string& dir, bool loop) {
  ReplayOptions options;
  options.loop = loop;
  absl::StatusOr<std::unique_ptr<ReplaySource>> source =
      ReplaySource::Open(dir, options);
  EXPECT_TRUE(source.ok()) << source.status();
  return source.ok() ? *std::move(source) : nullptr;
}

// Waits up to 10 s for `done`.
template <typename Fn>
bool WaitFor(Fn done) {
  const absl::Time deadline = absl::Now() + absl::Seconds(10);
  while (!done()) {
    if (absl::Now() > deadline) return false;
    absl::SleepFor(absl::Milliseconds(2));
  }
  return true;
}

TEST(FramePublisherTest, BeforeItsFirstFrameItIsUnavailableNamingTheError) {
  const std::string dir = Record("corrupt", 1);
  // The only frame's colour image is not a PNG: the replay never serves
  // one (a damaged frame among good ones is skipped).
  std::ofstream(dir + "/000000.rgb.png", std::ios::trunc) << "not a PNG";
  FramePublisher publisher(Replay(dir, /*loop=*/true));
  EXPECT_EQ(publisher.source_name(), "replay:" + dir);
  ASSERT_TRUE(
      WaitFor([&] { return !publisher.Counters().last_error.empty(); }));
  const PublisherCounters counters = publisher.Counters();
  EXPECT_EQ(counters.frames_captured, 0u);
  EXPECT_EQ(counters.newest_age_s, -1.0);
  EXPECT_THAT(counters.last_error, HasSubstr("000000.rgb.png"));
  const absl::Status status = publisher.Newest(0.0).status();
  EXPECT_EQ(status.code(), absl::StatusCode::kUnavailable);
  EXPECT_THAT(status.message(),
              HasSubstr(absl::StrCat("camera replay:", dir,
                                     " has sent no frame yet; last error: ")));
  EXPECT_THAT(status.message(), HasSubstr("000000.rgb.png"));
}

TEST(FramePublisherTest, AFinishedRecordingsLastFrameAgesUntilItIsRefused) {
  const std::string dir = Record("ends", 3);
  FramePublisher publisher(Replay(dir, /*loop=*/false));
  ASSERT_TRUE(WaitFor([&] {
    return absl::StrContains(publisher.Counters().last_error, "ended after");
  }));
  absl::StatusOr<PublishedFrame> newest = publisher.Newest(0.0);
  ASSERT_TRUE(newest.ok()) << newest.status();
  EXPECT_EQ(newest->frame.sequence, 2u);
  EXPECT_EQ(newest->frame.rgb, TinyFrame(2).rgb);
  EXPECT_EQ(newest->frame.depth_mm, TinyFrame(2).depth_mm);
  EXPECT_EQ(newest->frames_captured, 3u);
  EXPECT_EQ(newest->frames_dropped, 0u);
  EXPECT_GE(newest->age_s, 0.0);

  absl::SleepFor(absl::Milliseconds(100));
  EXPECT_GE(publisher.Counters().newest_age_s, 0.1);
  // No limit: still the last frame. A limit it has passed: refused.
  EXPECT_TRUE(publisher.Newest(0.0).ok());
  EXPECT_TRUE(publisher.Newest(60.0).ok());
  const absl::Status stale = publisher.Newest(0.05).status();
  EXPECT_EQ(stale.code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(stale.message(),
              HasSubstr(absl::StrCat(
                  "the newest frame from camera replay:", dir, " is ")));
  EXPECT_THAT(stale.message(), HasSubstr(" s old (limit 0.05 s)"));
  EXPECT_THAT(stale.message(), HasSubstr("ended after 3 frames"));
}

TEST(FramePublisherTest, ALoopingRecordingIsPublishedWithNothingDropped) {
  const std::string dir = Record("loops", 2);
  FramePublisher publisher(Replay(dir, /*loop=*/true));
  ASSERT_TRUE(
      WaitFor([&] { return publisher.Counters().frames_captured >= 20; }));
  const absl::StatusOr<PublishedFrame> newest = publisher.Newest(5.0);
  ASSERT_TRUE(newest.ok()) << newest.status();
  EXPECT_GE(newest->frame.sequence, 19u);
  // The frame counter counts on over the loop; its pixels are those of
  // recorded frame sequence % 2.
  EXPECT_EQ(newest->frame.depth_mm,
            TinyFrame(static_cast<int>(newest->frame.sequence % 2)).depth_mm);
  EXPECT_EQ(newest->frames_captured, newest->frame.sequence + 1);
  EXPECT_EQ(newest->frames_dropped, 0u);
  EXPECT_EQ(publisher.Counters().last_error, "");
}

}  // namespace
}  // namespace bitewise::camera
