// The simulated world's physics: the depth-based extension of the force
// trace model reproduces ForceProfile::At at the reference speed, holds when
// the fork stops and unloads when it pulls back; contact timing follows the
// simulated arm; a missed item means the plate; outcomes are seeded.
#include "services/robot/sim/sim_world.h"

#include <chrono>
#include <random>
#include <thread>

#include "gtest/gtest.h"
#include "services/domain/steady_time.h"
#include "services/sim/contact_force.h"

namespace bitewise::sim {
namespace {

TEST(ItemContactTest, DescentAtTheReferenceSpeedReproducesTheTrace) {
  std::mt19937_64 rng(4);
  const ForceProfile profile =
      ForceProfile::Sample(HapticCategory::kHardSkin, rng);
  ContactModelOptions options;
  options.reference_speed_mps = 0.05;
  ItemContact contact(profile, options);
  for (int i = 0; i <= 60; ++i) {
    const double tau_s = i * 0.001;
    const Wrench w = contact.Update(options.reference_speed_mps * tau_s);
    const Wrench expected = profile.At(tau_s);
    for (int c = 0; c < 3; ++c) {
      ASSERT_NEAR(w.force_n[c], expected.force_n[c], 1e-12) << tau_s;
      ASSERT_NEAR(w.torque_nm[c], expected.torque_nm[c], 1e-12) << tau_s;
    }
  }
  // Stopped: the force holds.
  const double held = contact.Update(0.003).force_n[2];
  EXPECT_DOUBLE_EQ(contact.Update(0.003).force_n[2], held);
  // Pulling back half the release distance halves it; the rest frees it.
  EXPECT_NEAR(contact.Update(0.003 - options.release_m / 2).force_n[2],
              held / 2, 1e-9);
  EXPECT_FALSE(contact.released());
  EXPECT_EQ(contact.Update(0.003 - options.release_m).force_n[2], 0.0);
  EXPECT_TRUE(contact.released());
  EXPECT_EQ(contact.Update(0.004).force_n[2], 0.0);  // stays released
}

TEST(PlateContactTest, IsAStiffSpring) {
  ContactModelOptions options;
  EXPECT_EQ(PlateContactWrench(-0.001, options).force_n[2], 0.0);
  EXPECT_DOUBLE_EQ(PlateContactWrench(0.0004, options).force_n[2], 20.0);
}

class SimWorldTest : public ::testing::Test {
 protected:
  SimWorldTest() : arm_(SimArmOptions()) {
    SceneItem item;
    item.id = 7;
    item.food = FindFood("carrot");
    item.x_m = 0.02;
    item.y_m = 0.01;  // plate frame: y down the image
    item.yaw_rad = 0.3;
    item.length_m = 0.05;
    item.width_m = 0.015;
    item.height_m = 0.012;
    scene_.items.push_back(item);
  }

  // Drives the tip to `p` (task frame) at the arm's speed limit and returns
  // the wrench once it is there.
  Wrench At(SimWorld& world, const Eigen::Vector3d& p) {
    robot::ForkPose pose;
    pose.p_TaskTip_m = p;
    for (int i = 0; i < 1000; ++i) {
      EXPECT_TRUE(arm_.Command(pose, robot::ForkVelocity()).ok());
      std::this_thread::sleep_for(std::chrono::milliseconds(11));
      if ((arm_.MeasuredPose()->p_TaskTip_m - p).norm() < 1e-12) break;
    }
    EXPECT_LT((arm_.MeasuredPose()->p_TaskTip_m - p).norm(), 1e-12);
    return world.WrenchAt(SteadyNowS());
  }

  SimArm arm_;
  PlateScene scene_;
};

TEST_F(SimWorldTest, ContactFollowsTheArm) {
  SimWorld world(scene_, &arm_, SimWorldOptions());
  const ForceProfile profile = *world.ProfileOf(7);
  // Above the item (task y = -plate y): nothing.
  EXPECT_EQ(At(world, {0.02, -0.01, 0.013}).force_n[2], 0.0);
  // 1 mm into it: the profile at 1 mm / 5 cm/s = 20 ms.
  const Wrench in = At(world, {0.02, -0.01, 0.011});
  EXPECT_NEAR(in.force_n[2], profile.At(0.02).force_n[2], 1e-9);
  EXPECT_GT(in.force_n[2], 1.0);
}

TEST_F(SimWorldTest, MissingTheItemMeansThePlate) {
  SimWorld world(scene_, &arm_, SimWorldOptions());
  // Mirrored in y: the wrong frame convention would land here.
  EXPECT_EQ(At(world, {0.02, 0.01, 0.005}).force_n[2], 0.0);
  EXPECT_NEAR(At(world, {0.02, 0.01, -0.0002}).force_n[2], 10.0, 1e-6);
}

TEST_F(SimWorldTest, TargetIsTheTopSurfaceInTheCameraFrame) {
  SimWorld world(scene_, &arm_, SimWorldOptions());
  const robot::AcquireTarget target = *world.TargetOf(7);
  EXPECT_DOUBLE_EQ(target.p_CameraItem_m.x(), 0.02);
  EXPECT_DOUBLE_EQ(target.p_CameraItem_m.y(), 0.01);
  EXPECT_DOUBLE_EQ(target.p_CameraItem_m.z(), 0.35 - 0.012);
  const robot::TaskTarget task =
      robot::ToTaskFrame(target, world.X_TaskCamera());
  EXPECT_NEAR(task.p_TaskItem_m.x(), 0.02, 1e-12);
  EXPECT_NEAR(task.p_TaskItem_m.y(), -0.01, 1e-12);
  EXPECT_NEAR(task.p_TaskItem_m.z(), 0.012, 1e-12);
  EXPECT_NEAR(task.major_axis_yaw_rad, -0.3, 1e-12);
}

TEST_F(SimWorldTest, PulledOutItemsAreCarriedOrLeft) {
  int successes = 0;
  for (uint64_t seed = 1; seed <= 20; ++seed) {
    SimWorldOptions options;
    options.seed = seed;
    SimWorld world(scene_, &arm_, options);
    world.BeginAttempt(*robot::FindAction("VS90"));  // 0.9 for carrots
    At(world, {0.02, -0.01, 0.013});
    At(world, {0.02, -0.01, 0.006});
    const Wrench lifted = At(world, {0.02, -0.01, 0.05});
    const robot::AttemptOutcome outcome = world.EndAttempt(0.0);
    EXPECT_EQ(outcome.true_food_type, "carrot");
    if (outcome.success) {
      ++successes;
      EXPECT_NEAR(lifted.force_n[2], -world.MassOf(scene_.items[0]) * 9.81,
                  1e-12);
      EXPECT_EQ(world.items_left(), 0);
    } else {
      EXPECT_EQ(lifted.force_n[2], 0.0);
      EXPECT_EQ(world.items_left(), 1);
    }
  }
  // 0.9 per attempt: 20 seeded draws land well inside (13, 20].
  EXPECT_GT(successes, 13);
}

}  // namespace
}  // namespace bitewise::sim
