// The simulated wrist camera (services/camera/sim_source.h): its frames are
// the seeded plate rendered with fresh noise each time and numbered in
// order, it keeps its rate, and bad options are refused naming them.
#include "services/camera/sim_source.h"

#include <cmath>
#include <limits>
#include <random>

#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "services/domain/steady_time.h"
#include "services/sim/food_catalog.h"

namespace bitewise::camera {
namespace {

using ::testing::HasSubstr;

TEST(SimSourceTest, FramesAreTheSeededPlateWithFreshNoiseInOrder) {
  SimSourceOptions options;
  options.seed = 7;
  options.foods = {"carrot", "kiwi"};
  options.rate_hz = 1000.0;
  absl::StatusOr<std::unique_ptr<SimSource>> source =
      SimSource::Create(options);
  ASSERT_TRUE(source.ok()) << source.status();
  EXPECT_EQ((*source)->name(), "sim:seed=7");

  // The same plate and noise seeds, computed here.
  std::mt19937_64 rng(7);
  const sim::PlateScene plate = sim::RandomPlate(
      {sim::FindFood("carrot"), sim::FindFood("kiwi")}, false, rng);
  for (uint64_t sequence = 0; sequence < 2; ++sequence) {
    const double before_s = SteadyNowS();
    const absl::StatusOr<domain::RgbdFrame> frame = (*source)->Next();
    ASSERT_TRUE(frame.ok()) << frame.status();
    const sim::RenderedFrame want = sim::RenderPlate(
        plate, sim::D415Intrinsics(), 7 * 1000003ULL + sequence);
    EXPECT_EQ(frame->sequence, sequence);
    EXPECT_GE(frame->capture_s, before_s);
    EXPECT_LE(frame->capture_s, SteadyNowS());
    EXPECT_EQ(frame->rgb, want.rgb) << "frame " << sequence;
    EXPECT_EQ(frame->depth_mm, want.depth_mm) << "frame " << sequence;
    EXPECT_EQ(frame->intrinsics.width, want.intrinsics.width);
    EXPECT_EQ(frame->intrinsics.fx, want.intrinsics.fx);
  }
}

TEST(SimSourceTest, WithoutFoodsThePlateHoldsTheUnseenFoods) {
  SimSourceOptions options;
  options.seed = 3;
  options.rate_hz = 1000.0;
  absl::StatusOr<std::unique_ptr<SimSource>> source =
      SimSource::Create(options);
  ASSERT_TRUE(source.ok()) << source.status();
  std::mt19937_64 rng(3);
  const sim::PlateScene plate =
      sim::RandomPlate(sim::UnseenFoods(), false, rng);
  const absl::StatusOr<domain::RgbdFrame> frame = (*source)->Next();
  ASSERT_TRUE(frame.ok()) << frame.status();
  EXPECT_EQ(frame->rgb,
            sim::RenderPlate(plate, sim::D415Intrinsics(), 3 * 1000003ULL).rgb);
}

TEST(SimSourceTest, FramesComeNoFasterThanTheRate) {
  SimSourceOptions options;
  options.rate_hz = 20.0;
  absl::StatusOr<std::unique_ptr<SimSource>> source =
      SimSource::Create(options);
  ASSERT_TRUE(source.ok()) << source.status();
  const double start_s = SteadyNowS();
  for (int i = 0; i < 4; ++i) ASSERT_TRUE((*source)->Next().ok());
  // The first at once, then one each 50 ms.
  EXPECT_GE(SteadyNowS() - start_s, 3 * 0.05 - 1e-3);
}

TEST(SimSourceTest, AnUnknownFoodOrABadRateIsRefusedNamingIt) {
  SimSourceOptions unknown;
  unknown.foods = {"carrot", "durian"};
  absl::Status status = SimSource::Create(unknown).status();
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(status.message(), HasSubstr("unknown food \"durian\""));

  for (const double rate :
       {0.0, -15.0, std::numeric_limits<double>::quiet_NaN()}) {
    SimSourceOptions bad_rate;
    bad_rate.rate_hz = rate;
    status = SimSource::Create(bad_rate).status();
    EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument) << rate;
    EXPECT_THAT(status.message(), HasSubstr("rate_hz must be > 0"));
  }
}

}  // namespace
}  // namespace bitewise::camera
