// Loading a HapticNet model and the familiarity model fitted with it, as
// the HapticService binary and bitewise-haptic-eval both do: a named file or
// the model compiled into the binary (default_model.h), and the familiarity
// file beside the model (docs/haptic.md, "Familiarity"). One rule, so the
// evaluator scores exactly what the service would serve.
#ifndef BITEWISE_SERVICES_HAPTIC_MODEL_LOADING_H_
#define BITEWISE_SERVICES_HAPTIC_MODEL_LOADING_H_

#include <memory>
#include <string>

#include "absl/status/statusor.h"
#include "services/haptic/core/familiarity.h"
#include "services/haptic/core/haptic_net.h"

namespace bitewise::haptic {

// The ONNX file at `model_path`, or the compiled-in model when it is empty.
absl::StatusOr<std::unique_ptr<HapticNet>> LoadHapticNet(
    const std::string& model_path);

// The window (s) to run `net` with. `flag_window_s` 0 means the model's own
// (HapticNet::window_s(), or 0.05 s for a model that records none); a
// positive value is used only for a model that records none or the same
// window, and anything else is INVALID_ARGUMENT naming both windows, because
// a model run on another window sees a picture it was never trained on.
absl::StatusOr<double> ModelWindow(const HapticNet& net, double flag_window_s,
                                   const std::string& source);

// The familiarity model `flag` asks for, null for none:
//   "none"  no score;
//   a path  that file (missing or malformed: an error naming it);
//   ""      the file beside the model, <model_path>.familiarity (none if it
//           does not exist; malformed: an error), or the compiled-in one
//           when `model_path` is empty.
// `described` says which, for start-up lines and reports.
absl::StatusOr<std::unique_ptr<FamiliarityModel>> LoadFamiliarity(
    const std::string& flag, const std::string& model_path,
    std::string* described);

}  // namespace bitewise::haptic

#endif  // BITEWISE_SERVICES_HAPTIC_MODEL_LOADING_H_
