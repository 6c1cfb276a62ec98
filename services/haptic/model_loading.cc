#include "services/haptic/model_loading.h"

#include <filesystem>
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
