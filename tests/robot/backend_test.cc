// The RobotService's simulated backend (services/robot/backend.h) on its
// own: the plate is the seeded one, frames are that plate rendered with
// per-frame noise, the arm runs at the acquisition's control period, and
// an unknown food is refused naming it.
#include "services/robot/backend.h"

#include <random>
#include <string>
#include <vector>

#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "services/domain/steady_time.h"
#include "services/sim/food_catalog.h"

namespace bitewise::robot {
namespace {

using ::testing::HasSubstr;

RobotBackendOptions SimOptions(std::vector<std::string> foods, uint64_t seed) {
  RobotBackendOptions options;
  options.kind = BackendKind::kSim;
  options.sim.seed = seed;
  options.sim.foods = std::move(foods);
  options.sim.box.rate_hz = 1000.0;
  return options;
}

TEST(RobotBackendTest, TheSimulatedPlateIsTheSeededOneRenderedFrameByFrame) {
  absl::StatusOr<std::unique_ptr<RobotBackend>> backend =
      RobotBackend::Create(SimOptions({"carrot", "banana", "kiwi"}, 5));
  ASSERT_TRUE(backend.ok()) << backend.status();
  RobotBackend& b = **backend;
  EXPECT_TRUE(b.simulated());
  EXPECT_EQ(b.items_left(), 3);
  EXPECT_TRUE(b.FtLive());

  // The plate, drawn here from the same seed.
  std::mt19937_64 rng(5);
  const sim::PlateScene want = sim::RandomPlate(
      {sim::FindFood("carrot"), sim::FindFood("banana"), sim::FindFood("kiwi")},
      false, rng);
  const sim::PlateScene scene = b.world()->scene();
  ASSERT_EQ(scene.items.size(), want.items.size());
  for (size_t i = 0; i < want.items.size(); ++i) {
    EXPECT_EQ(scene.items[i].food, want.items[i].food) << i;
    EXPECT_EQ(scene.items[i].x_m, want.items[i].x_m) << i;
    EXPECT_EQ(scene.items[i].y_m, want.items[i].y_m) << i;
  }
  for (uint64_t sequence = 0; sequence < 2; ++sequence) {
    const absl::StatusOr<domain::RgbdFrame> frame = b.CaptureFrame();
    ASSERT_TRUE(frame.ok()) << frame.status();
    EXPECT_EQ(frame->sequence, sequence);
    const sim::RenderedFrame rendered = sim::RenderPlate(
        want, sim::D415Intrinsics(), 5 * 1000003ULL + sequence);
    EXPECT_EQ(frame->rgb, rendered.rgb) << "frame " << sequence;
    EXPECT_EQ(frame->depth_mm, rendered.depth_mm) << "frame " << sequence;
  }
}

// The plate, the outcomes and the box's noise were once three generators
// of one seed: attempt k succeeded exactly when the k-th number that had
// drawn the first item's size was below p, and the F/T bias showed it.
TEST(RobotBackendTest, OutcomesAndNoiseAreNotThePlatesStream) {
  for (uint64_t seed = 0; seed < 1000; ++seed) {
    const SimStreamSeeds s = StreamSeeds(seed);
    EXPECT_EQ(s.plate, seed);  // the simulated camera's plate too
    EXPECT_NE(s.world, s.plate) << seed;
    EXPECT_NE(s.box, s.plate) << seed;
    EXPECT_NE(s.box, s.world) << seed;
  }
  RobotBackendOptions options = SimOptions({"carrot"}, 7);
  options.ft.counts_per_force = 2e6;
  options.ft.counts_per_torque = 3e6;
  const sim::SimNetFtBoxOptions box = SimBoxOptions(options);
  EXPECT_EQ(box.seed, StreamSeeds(7).box);
  EXPECT_EQ(box.counts_per_force, 2e6);
  EXPECT_EQ(box.counts_per_torque, 3e6);
  absl::StatusOr<std::unique_ptr<RobotBackend>> backend =
      RobotBackend::Create(options);
  ASSERT_TRUE(backend.ok()) << backend.status();
  EXPECT_EQ((*backend)->world()->options().seed, StreamSeeds(7).world);
}

TEST(RobotBackendTest, TheArmStartsHomeAndMovesAtTheAcquisitionsPeriod) {
  RobotBackendOptions options = SimOptions({"carrot"}, 2);
  options.acquisition.control_period_s = 0.02;
  options.sim.arm.control_period_s = 0.5;  // the acquisition's wins
  absl::StatusOr<std::unique_ptr<RobotBackend>> backend =
      RobotBackend::Create(options);
  ASSERT_TRUE(backend.ok()) << backend.status();
  sim::SimArm* arm = (*backend)->sim_arm();
  ASSERT_NE(arm, nullptr);
  const absl::StatusOr<ForkPose> home = arm->MeasuredPose();
  ASSERT_TRUE(home.ok());
  EXPECT_EQ(home->p_TaskTip_m, options.sim.arm.home.p_TaskTip_m);

  // 5 cm away: one command moves max_speed * period, 4 mm at 20 ms.
  ForkPose far = *home;
  far.p_TaskTip_m.x() += 0.05;
  ASSERT_TRUE(arm->Command(far, {}).ok());
  const ForkPose reached = arm->PoseAt(SteadyNowS() + 1e6);
  EXPECT_NEAR((reached.p_TaskTip_m - home->p_TaskTip_m).norm(),
              options.sim.arm.max_speed_mps * 0.02, 1e-12);
}

TEST(RobotBackendTest, AnUnknownFoodIsRefusedNamingIt) {
  const absl::Status status =
      RobotBackend::Create(SimOptions({"carrot", "durian"}, 1)).status();
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(status.message(), HasSubstr("unknown food \"durian\""));
}

}  // namespace
}  // namespace bitewise::robot
