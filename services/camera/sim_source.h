// The simulated wrist camera as a FrameSource: a random plate of the
// simulated world's foods rendered by the D415 model (services/sim), a new
// noise draw every frame, paced at a rate. For running bitewise-camera and
// the hardware backend's camera path without a camera.
#ifndef BITEWISE_SERVICES_CAMERA_SIM_SOURCE_H_
#define BITEWISE_SERVICES_CAMERA_SIM_SOURCE_H_

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "services/camera/frame_source.h"
#include "services/sim/scene.h"

namespace bitewise::camera {

struct SimSourceOptions {
  uint64_t seed = 1;
  // Food names (services/sim/food_catalog.h); empty: the unseen foods.
  std::vector<std::string> foods;
  bool allow_touching = false;
  double rate_hz = 15.0;
};

class SimSource final : public FrameSource {
 public:
  // INVALID_ARGUMENT for an unknown food or a non-positive rate.
  static absl::StatusOr<std::unique_ptr<SimSource>> Create(
      const SimSourceOptions& options);

  absl::StatusOr<domain::RgbdFrame> Next() override;
  std::string name() const override;

 private:
  SimSource(sim::PlateScene scene, const SimSourceOptions& options);

  const sim::PlateScene scene_;
  const SimSourceOptions options_;
  Pacer pacer_;
  uint64_t sequence_ = 0;
};

}  // namespace bitewise::camera

#endif  // BITEWISE_SERVICES_CAMERA_SIM_SOURCE_H_
