// The featurizer check behind `bitewise-perception --check_model`: runs a
// loaded featurizer (through the same loader and Featurize the service
// uses) on crops given as PNG files and writes what it computed, so that a
// model exported elsewhere (scripts/spanet/export_onnx.py) can be compared
// with its source framework before anyone serves it. No gRPC.
#ifndef BITEWISE_SERVICES_PERCEPTION_MODEL_CHECK_H_
#define BITEWISE_SERVICES_PERCEPTION_MODEL_CHECK_H_

#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "services/perception/featurizer.h"

namespace bitewise::perception {

struct CheckCrop {
  std::string png_path;
  FoodLocation location = FoodLocation::kIsolated;
};

// Parses "PATH[:LOCATION],..." with LOCATION one of isolated, wall,
// lettuce (default isolated). INVALID_ARGUMENT naming the entry otherwise.
absl::StatusOr<std::vector<CheckCrop>> ParseCheckCrops(absl::string_view spec);

// For crop i, featurizes the whole PNG (read as RGB) and writes into
// out_dir:
//   crop<i>.txt         lines "context ...", "action_scores ...",
//                       "skewer_points u0 v0 u1 v1" (%.9g)
//   crop<i>.canvas.png  SPANet's 144x144 input canvas (SPANet only)
// Errors: NOT_FOUND / INVALID_ARGUMENT naming a crop that cannot be read;
// the featurizer's own error; FAILED_PRECONDITION when out_dir cannot be
// written.
absl::Status RunModelCheck(const Featurizer& featurizer,
                           const std::vector<CheckCrop>& crops,
                           const std::string& out_dir);

}  // namespace bitewise::perception

#endif  // BITEWISE_SERVICES_PERCEPTION_MODEL_CHECK_H_
