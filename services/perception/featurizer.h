// The visual context c of the paper (docs/robot.md): a Featurizer turns one
// food item (a box in a frame) into the feature vector the bandit learns from.
// Two implementations: SPANet from an ONNX file (spanet_featurizer.h) and the
// weight-free default (default_featurizer.h), behind one interface so the
// service and the meal do not care which one runs.
#ifndef BITEWISE_SERVICES_PERCEPTION_FEATURIZER_H_
#define BITEWISE_SERVICES_PERCEPTION_FEATURIZER_H_

#include <array>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "services/perception/frame.h"

namespace bitewise::perception {

// Where the item lies on the plate: SPANet's 3-way location one-hot, in
// SPANet's order.
enum class FoodLocation { kIsolated = 0, kWall = 1, kLettuce = 2 };

// A point in crop-normalised coordinates: (0, 0) is the crop's top-left
// corner, (1, 1) its bottom-right.
struct CropPoint {
  double u = 0.0;
  double v = 0.0;
};

struct Features {
  std::vector<double> context;
  // SPANet only: the two skewer end points and the per-action success
  // estimates (action order VS0, VS90, TV0, TV90, TA0, TA90). Empty
  // for featurizers that do not predict them.
  std::vector<CropPoint> skewer_points;
  std::vector<double> action_scores;
};

// Implementations are thread-safe: Featurize may be called concurrently.
class Featurizer {
 public:
  virtual ~Featurizer() = default;

  // Short name reported to clients ("spanet", "default").
  virtual std::string name() const = 0;
  // Length of Features::context.
  virtual int dimension() const = 0;
  // E||c||^2 of this featurizer's contexts on the simulated world's seen
  // foods (never the unseen evaluation foods), shipped with it; 0 when
  // unknown. The bandit's context ridge only means something relative to
  // it: new users get lambda_c = rho_c * this (docs/algorithms.md).
  virtual double context_mean_squared_norm() const { return 0.0; }

  // Features of the item inside `box`. Errors: INVALID_ARGUMENT when the
  // box is empty or leaves the frame (see ValidateBox); INTERNAL when the
  // model fails at run time.
  virtual absl::StatusOr<Features> Featurize(const DecodedFrame& frame,
                                             const PixelBox& box,
                                             FoodLocation location) const = 0;
};

}  // namespace bitewise::perception

#endif  // BITEWISE_SERVICES_PERCEPTION_FEATURIZER_H_
