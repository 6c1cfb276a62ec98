// The contact model (services/sim/contact_force.h) keeps the promises its
// header makes: depth at the reference speed is the profile's time, a fork
// that stops holds its force, one that pulls back unloads linearly and is
// released, and the plate is a spring that only pushes.
#include "services/sim/contact_force.h"

#include <random>

#include "gtest/gtest.h"
#include "services/sim/force_trace.h"

namespace bitewise::sim {
namespace {

void ExpectWrenchEq(const Wrench& got, const Wrench& want) {
  for (int i = 0; i < 3; ++i) {
    EXPECT_DOUBLE_EQ(got.force_n[i], want.force_n[i]) << "force " << i;
    EXPECT_DOUBLE_EQ(got.torque_nm[i], want.torque_nm[i]) << "torque " << i;
  }
}

ForceProfile Profile(HapticCategory category, uint64_t seed) {
  std::mt19937_64 rng(seed);
  return ForceProfile::Sample(category, rng);
}

TEST(ContactForceTest, DescentAtTheReferenceSpeedReproducesTheProfile) {
  const ContactModelOptions options;
  for (HapticCategory category :
       {HapticCategory::kHard, HapticCategory::kHardSkin,
        HapticCategory::kMedium, HapticCategory::kSoft}) {
    const ForceProfile profile = Profile(category, 3);
    ItemContact contact(profile, options);
    for (int step = 0; step <= 200; ++step) {
      const double tau_s = 0.001 * step;
      const double depth_m = tau_s * options.reference_speed_mps;
      ExpectWrenchEq(contact.Update(depth_m), profile.At(tau_s));
    }
    EXPECT_FALSE(contact.released());
  }
}

TEST(ContactForceTest, AForkThatStopsHoldsItsForce) {
  const ContactModelOptions options;
  const ForceProfile profile = Profile(HapticCategory::kMedium, 5);
  ItemContact contact(profile, options);
  const double depth_m = 0.004;
  const Wrench at_depth = contact.Update(depth_m);
  EXPECT_GT(at_depth.force_n[2], 0.0);
  for (int i = 0; i < 10; ++i)
    ExpectWrenchEq(contact.Update(depth_m), at_depth);
  EXPECT_FALSE(contact.released());
}

TEST(ContactForceTest, PullingBackUnloadsLinearlyThenReleases) {
  ContactModelOptions options;
  options.release_m = 0.001;
  const ForceProfile profile = Profile(HapticCategory::kHard, 7);
  ItemContact contact(profile, options);
  const double deepest_m = 0.005;
  const Wrench peak = contact.Update(deepest_m);
  ASSERT_GT(peak.force_n[2], 0.0);
  // A quarter of the way back: three quarters of the force, every channel.
  const Wrench quarter = contact.Update(deepest_m - 0.25 * options.release_m);
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(quarter.force_n[i], 0.75 * peak.force_n[i], 1e-12);
    EXPECT_NEAR(quarter.torque_nm[i], 0.75 * peak.torque_nm[i], 1e-12);
  }
  EXPECT_FALSE(contact.released());
  // Back by release_m: nothing, released, and it stays so even if the fork
  // goes deeper again.
  ExpectWrenchEq(contact.Update(deepest_m - options.release_m), Wrench());
  EXPECT_TRUE(contact.released());
  ExpectWrenchEq(contact.Update(2 * deepest_m), Wrench());
}

TEST(ContactForceTest, OutsideTheItemIsNoForceAndNoRelease) {
  const ForceProfile profile = Profile(HapticCategory::kSoft, 9);
  ItemContact contact(profile, ContactModelOptions());
  ExpectWrenchEq(contact.Update(-0.002), Wrench());
  ExpectWrenchEq(contact.Update(0.0), Wrench());
  EXPECT_FALSE(contact.released());  // it never went in
}

TEST(ContactForceTest, ThePlateIsASpringThatOnlyPushes) {
  ContactModelOptions options;
  options.plate_stiffness_n_per_m = 4e4;
  ExpectWrenchEq(PlateContactWrench(-0.001, options), Wrench());
  ExpectWrenchEq(PlateContactWrench(0.0, options), Wrench());
  const Wrench pressed = PlateContactWrench(0.0005, options);
  EXPECT_DOUBLE_EQ(pressed.force_n[2], 20.0);
  EXPECT_EQ(pressed.force_n[0], 0.0);
  EXPECT_EQ(pressed.force_n[1], 0.0);
  for (double t : pressed.torque_nm) EXPECT_EQ(t, 0.0);
}

}  // namespace
}  // namespace bitewise::sim
