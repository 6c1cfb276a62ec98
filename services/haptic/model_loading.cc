#include "services/haptic/model_loading.h"

#include <cmath>
#include <filesystem>
#include <optional>
#include <system_error>
#include <utility>

#include "absl/strings/str_cat.h"
#include "services/haptic/default_model.h"

namespace bitewise::haptic {

absl::StatusOr<std::unique_ptr<HapticNet>> LoadHapticNet(
    const std::string& model_path) {
  if (model_path.empty()) {
    return HapticNet::FromOnnxBytes(DefaultHapticNetOnnx(),
                                    kDefaultHapticNetSource);
  }
  return HapticNet::FromOnnxFile(model_path);
}

absl::StatusOr<double> ModelWindow(const HapticNet& net, double flag_window_s,
                                   const std::string& source) {
  if (!std::isfinite(flag_window_s) || flag_window_s < 0.0) {
    return absl::InvalidArgumentError(
        absl::StrCat("--window_s must be 0 (the model's own) or positive, not ",
                     flag_window_s));
  }
  const std::optional<double> declared = net.window_s();
  if (flag_window_s == 0.0) return declared.value_or(WindowOptions().window_s);
  if (declared.has_value() && std::abs(*declared - flag_window_s) > 1e-9) {
    return absl::InvalidArgumentError(absl::StrCat(
        "HapticNet model ", source, " was trained on a ", *declared,
        " s window (", kHapticNetWindowKey, ") but --window_s=", flag_window_s,
        "; leave --window_s at 0 to use the model's"));
  }
  return flag_window_s;
}

absl::StatusOr<std::unique_ptr<FamiliarityModel>> LoadFamiliarity(
    const std::string& flag, const std::string& model_path,
    std::string* described) {
  if (flag == "none") {
    *described = "no familiarity score (--familiarity=none)";
    return nullptr;
  }
  absl::StatusOr<FamiliarityModel> model = absl::InternalError("not loaded");
  std::string source;
  if (!flag.empty()) {
    source = flag;
    model = FamiliarityModel::FromFile(flag);
  } else if (model_path.empty()) {
    source = kDefaultHapticFamiliaritySource;
    model = FamiliarityModel::FromText(DefaultHapticFamiliarity(), source);
  } else {
    source = FamiliarityPathFor(model_path);
    std::error_code error;
    if (!std::filesystem::exists(source, error)) {
      *described =
          absl::StrCat("no familiarity score: ", source, " does not exist");
      return nullptr;
    }
    model = FamiliarityModel::FromFile(source);
  }
  if (!model.ok()) return model.status();
  *described =
      absl::StrCat("familiarity ", source, ", threshold ", model->threshold(),
                   ", fitted on ", model->trained_on());
  return std::make_unique<FamiliarityModel>(std::move(model).value());
}

}  // namespace bitewise::haptic
