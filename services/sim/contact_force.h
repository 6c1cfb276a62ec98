// The force-trace model (force_trace.h) turned from a function of time into
// a function of how deep the fork is in the item, so the simulated arm's own
// motion sets contact timing: a fork descending at the reference speed
// reproduces ForceProfile::At exactly, a fork stopped at the force limit
// holds its force, and a fork pulled back unloads. Also the plate under the
// food, as a stiff spring, so a fork that misses the food hits the plate.
#ifndef BITEWISE_SERVICES_SIM_CONTACT_FORCE_H_
#define BITEWISE_SERVICES_SIM_CONTACT_FORCE_H_

#include "services/sim/force_trace.h"

namespace bitewise::sim {

struct ContactModelOptions {
  // The insertion speed that ForceProfile's time axis stands for: depth d
  // feels like At(d / reference_speed_mps). Equal to the acquisition's
  // descent speed, so the streamed traces are the ones HapticNet trains on.
  double reference_speed_mps = 0.05;
  // Pulling back this far from the deepest point unloads the tines fully
  // (elastic recovery of the food).
  double release_m = 0.0005;
  // The plate: ceramic behind a fork that flexes a little.
  double plate_stiffness_n_per_m = 5e4;
};

// One fork-in-item contact, from first touch to release.
class ItemContact {
 public:
  ItemContact(const ForceProfile& profile, const ContactModelOptions& options)
      : profile_(profile), options_(options) {}

  // The wrench at penetration depth `depth_m` (<= 0: not inside). Depths
  // must come in time order.
  Wrench Update(double depth_m);

  // True once the fork has pulled back by release_m after going in.
  bool released() const { return released_; }

 private:
  ForceProfile profile_;
  ContactModelOptions options_;
  double max_depth_m_ = 0.0;
  bool released_ = false;
};

// The plate's push on the tines when they are `below_m` under its surface.
Wrench PlateContactWrench(double below_m, const ContactModelOptions& options);

}  // namespace bitewise::sim

#endif  // BITEWISE_SERVICES_SIM_CONTACT_FORCE_H_
