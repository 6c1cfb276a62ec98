#include "services/perception/model_check.h"

#include <cstdio>
#include <fstream>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_split.h"
#include "opencv2/imgcodecs.hpp"
#include "opencv2/imgproc.hpp"
#include "services/common/status_macros.h"
#include "services/perception/spanet_featurizer.h"

namespace bitewise::perception {
namespace {

std::string Join(const std::vector<double>& values) {
  std::string out;
  for (const double v : values) absl::StrAppendFormat(&out, " %.9g", v);
  return out;
}

}  // namespace

absl::StatusOr<std::vector<CheckCrop>> ParseCheckCrops(absl::string_view spec) {
  std::vector<CheckCrop> crops;
  for (absl::string_view entry : absl::StrSplit(spec, ',', absl::SkipEmpty())) {
    CheckCrop crop;
    const size_t colon = entry.rfind(':');
    absl::string_view location = "isolated";
    if (colon != absl::string_view::npos) {
      location = entry.substr(colon + 1);
      entry = entry.substr(0, colon);
    }
    if (location == "isolated") {
      crop.location = FoodLocation::kIsolated;
    } else if (location == "wall") {
      crop.location = FoodLocation::kWall;
    } else if (location == "lettuce") {
      crop.location = FoodLocation::kLettuce;
    } else {
      return absl::InvalidArgumentError(
          absl::StrCat("--check_crops: \"", entry, ":", location,
                       "\": location must be isolated, wall or lettuce"));
    }
    if (entry.empty()) {
      return absl::InvalidArgumentError("--check_crops: an entry has no path");
    }
    crop.png_path = std::string(entry);
    crops.push_back(std::move(crop));
  }
  if (crops.empty()) {
    return absl::InvalidArgumentError("--check_crops: no crops given");
  }
  return crops;
}

absl::Status RunModelCheck(const Featurizer& featurizer,
                           const std::vector<CheckCrop>& crops,
                           const std::string& out_dir) {
  for (size_t i = 0; i < crops.size(); ++i) {
    const cv::Mat bgr = cv::imread(crops[i].png_path, cv::IMREAD_COLOR);
    if (bgr.empty()) {
      return absl::NotFoundError(absl::StrCat("crop \"", crops[i].png_path,
                                              "\" is missing or not an image"));
    }
    DecodedFrame frame;
    cv::cvtColor(bgr, frame.rgb, cv::COLOR_BGR2RGB);
    ASSIGN_OR_RETURN(
        const Features features,
        featurizer.Featurize(frame, PixelBox{0, 0, bgr.cols, bgr.rows},
                             crops[i].location));
    const std::string stem = absl::StrCat(out_dir, "/crop", i);
    std::ofstream out(stem + ".txt", std::ios::trunc);
    out << "context" << Join(features.context) << "\n";
    out << "action_scores" << Join(features.action_scores) << "\n";
    std::vector<double> points;
    for (const CropPoint& p : features.skewer_points) {
      points.push_back(p.u);
      points.push_back(p.v);
    }
    out << "skewer_points" << Join(points) << "\n";
    out.flush();
    if (!out) {
      return absl::FailedPreconditionError(
          absl::StrCat("cannot write \"", stem, ".txt\""));
    }
    if (featurizer.name() == "spanet") {
      cv::Mat canvas_bgr;
      cv::cvtColor(SpanetCanvas8u(frame.rgb), canvas_bgr, cv::COLOR_RGB2BGR);
      if (!cv::imwrite(stem + ".canvas.png", canvas_bgr)) {
        return absl::FailedPreconditionError(
            absl::StrCat("cannot write \"", stem, ".canvas.png\""));
      }
    }
  }
  return absl::OkStatus();
}

}  // namespace bitewise::perception
