// SimWorld: the simulated plate the robot eats from. It owns the PlateScene
// (render/scene.h; acquired items leave it), feels the fork through the
// simulated arm's pose (which item the tines are in, how deep, whether they
// hit the plate) and turns that into the wrench the simulated Net F/T box
// streams; and, as the SuccessJudge of simulation, it decides whether an
// attempt picked the item up, from the food type's success probability for
// the action (seeded, so meals repeat).
//
// Frames: the scene's plate frame is x right, y down (image), z up; the task
// frame of robot/arm.h is x right, y up (image), z up, so a plate point
// (x, y, z) is (x, -y, z) in the task frame and a yaw flips sign.
//
// Thread-safe.
#ifndef BITEWISE_SERVICES_ROBOT_SIM_SIM_WORLD_H_
#define BITEWISE_SERVICES_ROBOT_SIM_SIM_WORLD_H_

#include <cstdint>
#include <map>
#include <optional>
#include <random>
#include <string>

#include "absl/base/thread_annotations.h"
#include "absl/synchronization/mutex.h"
#include "services/robot/actions.h"
#include "services/robot/sim/sim_arm.h"
#include "services/robot/sim/sim_netft_box.h"
#include "services/robot/success_judge.h"
#include "services/sim/contact_force.h"
#include "services/sim/scene.h"

namespace bitewise::sim {

struct SimWorldOptions {
  uint64_t seed = 1;
  ContactModelOptions contact;
  double food_density_kg_per_m3 = 1000.0;
  double gravity_mps2 = 9.81;
};

class SimWorld final : public WrenchSource, public robot::SuccessJudge {
 public:
  // `arm` must outlive the world.
  SimWorld(const PlateScene& scene, const SimArm* arm,
           const SimWorldOptions& options);

  // WrenchSource: item contact, plate contact and the weight of a carried
  // item. Resolves an attempt's outcome when the fork pulls out of the item.
  Wrench WrenchAt(double time_s) override;

  // SuccessJudge.
  void BeginAttempt(const robot::ActionSpec& action) override;
  robot::AttemptOutcome EndAttempt(double static_load_n) override;
  void AbortAttempt() override;

  PlateScene scene() const;
  const SimWorldOptions& options() const { return options_; }
  int items_left() const;
  // Camera pose in the task frame implied by the scene's camera height.
  robot::RigidTransform X_TaskCamera() const;
  // What a perfect detector would report for item `id`: its top-surface
  // centre in the camera frame and its major axis angle in the image.
  std::optional<robot::AcquireTarget> TargetOf(uint32_t id) const;
  // The item's force profile (sampled on first use, seeded by the item id).
  std::optional<ForceProfile> ProfileOf(uint32_t id);
  // Mass of an item (an ellipsoid of its size), kg.
  double MassOf(const SceneItem& item) const;

 private:
  const SceneItem* ItemUnder(const Eigen::Vector3d& p_TaskTip) const
      ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_);
  const ForceProfile& ProfileLocked(const SceneItem& item)
      ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_);
  void Resolve() ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_);

  const SimArm* const arm_;
  const SimWorldOptions options_;

  mutable absl::Mutex mu_;
  PlateScene scene_ ABSL_GUARDED_BY(mu_);
  std::map<uint32_t, ForceProfile> profiles_ ABSL_GUARDED_BY(mu_);
  std::mt19937_64 outcome_rng_ ABSL_GUARDED_BY(mu_);
  // The current attempt.
  // The action of the attempt under way ("" between attempts).
  std::string action_ ABSL_GUARDED_BY(mu_);
  std::optional<SceneItem> engaged_ ABSL_GUARDED_BY(mu_);
  std::optional<ItemContact> contact_ ABSL_GUARDED_BY(mu_);
  bool resolved_ ABSL_GUARDED_BY(mu_) = false;
  std::optional<SceneItem> carried_ ABSL_GUARDED_BY(mu_);
};

}  // namespace bitewise::sim

#endif  // BITEWISE_SERVICES_ROBOT_SIM_SIM_WORLD_H_
