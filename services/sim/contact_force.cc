#include "services/sim/contact_force.h"

#include <algorithm>

namespace bitewise::sim {

Wrench ItemContact::Update(double depth_m) {
  if (released_) return Wrench();
  if (depth_m >= max_depth_m_) {
    max_depth_m_ = depth_m;
    if (depth_m <= 0.0) return Wrench();
    return profile_.At(depth_m / options_.reference_speed_mps);
  }
  const double back_m = max_depth_m_ - depth_m;
  if (back_m >= options_.release_m || depth_m <= 0.0) {
    released_ = max_depth_m_ > 0.0;
    return Wrench();
  }
  // Unloading: linear from the force at the deepest point to zero.
  Wrench w = profile_.At(max_depth_m_ / options_.reference_speed_mps);
  const double scale = 1.0 - back_m / options_.release_m;
  for (int i = 0; i < 3; ++i) {
    w.force_n[i] *= scale;
    w.torque_nm[i] *= scale;
  }
  return w;
}

Wrench PlateContactWrench(double below_m, const ContactModelOptions& options) {
  Wrench w;
  if (below_m > 0.0) w.force_n[2] = options.plate_stiffness_n_per_m * below_m;
  return w;
}

}  // namespace bitewise::sim
