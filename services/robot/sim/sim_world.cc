#include "services/robot/sim/sim_world.h"

#include <algorithm>
#include <cmath>

#include "services/domain/random.h"

namespace bitewise::sim {

SimWorld::SimWorld(const PlateScene& scene, const SimArm* arm,
                   const SimWorldOptions& options)
    : arm_(arm), options_(options), scene_(scene), outcome_rng_(options.seed) {}

Wrench SimWorld::WrenchAt(double time_s) {
  const robot::ForkPose pose = arm_->PoseAt(time_s);
  const Eigen::Vector3d& tip = pose.p_TaskTip_m;
  absl::MutexLock lock(&mu_);
  Wrench total;
  if (!engaged_ && !resolved_ && !carried_) {
    if (const SceneItem* item = ItemUnder(tip)) {
      engaged_ = *item;
      contact_.emplace(ProfileLocked(*item), options_.contact);
    }
  }
  if (engaged_ && !resolved_) {
    total = contact_->Update(engaged_->height_m - tip.z());
    if (contact_->released()) Resolve();
  }
  if (tip.z() < 0.0 && tip.head<2>().norm() < scene_.plate_radius_m) {
    const Wrench plate = PlateContactWrench(-tip.z(), options_.contact);
    total.force_n[2] += plate.force_n[2];
  }
  if (carried_) {
    // The item hangs from the tines and pulls the fork down.
    total.force_n[2] -= MassOf(*carried_) * options_.gravity_mps2;
  }
  return total;
}

void SimWorld::Resolve() {
  resolved_ = true;
  if (action_.empty() || !engaged_) return;
  // Every catalog food lists every action (tests/sim/food_catalog_test.cc);
  // an action it lacks would never acquire it.
  const double p =
      sim::SuccessProbability(*engaged_->food, action_).value_or(0.0);
  const bool success = random::Uniform(outcome_rng_, 0.0, 1.0) < p;
  if (!success) return;
  carried_ = engaged_;
  auto& items = scene_.items;
  items.erase(std::remove_if(items.begin(), items.end(),
                             [id = engaged_->id](const SceneItem& item) {
                               return item.id == id;
                             }),
              items.end());
}

void SimWorld::BeginAttempt(const robot::ActionSpec& action) {
  absl::MutexLock lock(&mu_);
  action_ = action.name;
  engaged_.reset();
  contact_.reset();
  resolved_ = false;
  carried_.reset();
}

robot::AttemptOutcome SimWorld::EndAttempt(double) {
  absl::MutexLock lock(&mu_);
  robot::AttemptOutcome outcome;
  outcome.success = carried_.has_value();
  if (engaged_) {
    outcome.true_food_type = engaged_->food->name;
    outcome.true_haptic_class = engaged_->food->category;
  }
  // The bite is delivered: the carried item is gone for good.
  action_.clear();
  engaged_.reset();
  contact_.reset();
  resolved_ = false;
  carried_.reset();
  return outcome;
}

void SimWorld::AbortAttempt() {
  absl::MutexLock lock(&mu_);
  // A stopped arm drops what it carries back onto the plate.
  if (carried_) scene_.items.push_back(*carried_);
  action_.clear();
  engaged_.reset();
  contact_.reset();
  resolved_ = false;
  carried_.reset();
}

PlateScene SimWorld::scene() const {
  absl::MutexLock lock(&mu_);
  return scene_;
}

int SimWorld::items_left() const {
  absl::MutexLock lock(&mu_);
  return static_cast<int>(scene_.items.size());
}

robot::RigidTransform SimWorld::X_TaskCamera() const {
  absl::MutexLock lock(&mu_);
  return robot::CameraLookingDown(scene_.camera_height_m);
}

std::optional<robot::AcquireTarget> SimWorld::TargetOf(uint32_t id) const {
  absl::MutexLock lock(&mu_);
  for (const SceneItem& item : scene_.items) {
    if (item.id != id) continue;
    robot::AcquireTarget target;
    target.p_CameraItem_m = Eigen::Vector3d(
        item.x_m, item.y_m, scene_.camera_height_m - item.height_m);
    target.major_axis_angle_rad = item.yaw_rad;
    return target;
  }
  return std::nullopt;
}

std::optional<ForceProfile> SimWorld::ProfileOf(uint32_t id) {
  absl::MutexLock lock(&mu_);
  for (const SceneItem& item : scene_.items) {
    if (item.id == id) return ProfileLocked(item);
  }
  return std::nullopt;
}

double SimWorld::MassOf(const SceneItem& item) const {
  return options_.food_density_kg_per_m3 * M_PI / 6.0 * item.length_m *
         item.width_m * item.height_m;
}

const SceneItem* SimWorld::ItemUnder(const Eigen::Vector3d& p_TaskTip) const {
  for (const SceneItem& item : scene_.items) {
    if (p_TaskTip.z() >= item.height_m) continue;
    // Into the item's own axes (plate frame: y flipped from the task frame).
    const double dx = p_TaskTip.x() - item.x_m;
    const double dy = -p_TaskTip.y() - item.y_m;
    const double c = std::cos(item.yaw_rad), s = std::sin(item.yaw_rad);
    const double u = (c * dx + s * dy) / (0.5 * item.length_m);
    const double v = (-s * dx + c * dy) / (0.5 * item.width_m);
    if (u * u + v * v <= 1.0) return &item;
  }
  return nullptr;
}

const ForceProfile& SimWorld::ProfileLocked(const SceneItem& item) {
  auto it = profiles_.find(item.id);
  if (it == profiles_.end()) {
    // Per item, not per draw order: the same item feels the same whatever
    // was touched before it.
    std::mt19937_64 rng(options_.seed * 0x9e3779b97f4a7c15ULL + item.id);
    it = profiles_
             .emplace(item.id, ForceProfile::Sample(item.food->category, rng))
             .first;
  }
  return it->second;
}

}  // namespace bitewise::sim
