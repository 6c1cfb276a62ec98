#include "services/perception/food_detector_options.h"

#include <cmath>
#include <cstdint>
#include <map>
#include <set>
#include <string>
#include <variant>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "absl/strings/strip.h"

namespace bitewise::perception {
namespace {

using Field = std::variant<double*, int*, bool*, uint64_t*>;

// Every field of FoodDetectorOptions by its name, pointing into `options`.
std::map<std::string, Field, std::less<>> Fields(FoodDetectorOptions& options) {
  return {
      {"min_height_mm", &options.min_height_mm},
      {"plate_tolerance_mm", &options.plate_tolerance_mm},
      {"min_item_area_m2", &options.min_item_area_m2},
      {"min_colour_distance", &options.min_colour_distance},
      {"max_bare_plate_mm", &options.max_bare_plate_mm},
      {"max_shadow_chroma", &options.max_shadow_chroma},
      {"min_edge_strength", &options.min_edge_strength},
      {"min_soft_edge_distance", &options.min_soft_edge_distance},
      {"valley_width_px", &options.valley_width_px},
      {"min_valley_mm", &options.min_valley_mm},
      {"valley_fraction", &options.valley_fraction},
      {"cliff_window_px", &options.cliff_window_px},
      {"min_cliff_mm", &options.min_cliff_mm},
      {"cliff_fraction", &options.cliff_fraction},
      {"min_seed_px", &options.min_seed_px},
      {"terrace_window_px", &options.terrace_window_px},
      {"terrace_open_px", &options.terrace_open_px},
      {"min_terrace_px", &options.min_terrace_px},
      {"max_merge_top_ratio", &options.max_merge_top_ratio},
      {"min_enclosed_share", &options.min_enclosed_share},
      {"enclosed_kin", &options.enclosed_kin},
      {"min_sandwich_share", &options.min_sandwich_share},
      {"max_highlight_hue_deg", &options.max_highlight_hue_deg},
      {"max_highlight_chroma_share", &options.max_highlight_chroma_share},
      {"max_highlight_below_plate_l", &options.max_highlight_below_plate_l},
      {"min_crease_shade_l", &options.min_crease_shade_l},
      {"valley_flank_px", &options.valley_flank_px},
      {"min_valley_flank_share", &options.min_valley_flank_share},
      {"min_seam_flank_height_share", &options.min_seam_flank_height_share},
      {"min_join_fill", &options.min_join_fill},
      {"min_join_elongation", &options.min_join_elongation},
      {"min_stick_seed_elongation", &options.min_stick_seed_elongation},
      {"min_stick_part_elongation", &options.min_stick_part_elongation},
      {"min_stick_fill", &options.min_stick_fill},
      {"min_stick_elongation", &options.min_stick_elongation},
      {"stick_fill_counts_long_parts", &options.stick_fill_counts_long_parts},
      {"max_stick_shade_distance", &options.max_stick_shade_distance},
      {"join_top_quantile", &options.join_top_quantile},
      {"max_waist_solidity", &options.max_waist_solidity},
      {"min_waist_solidity", &options.min_waist_solidity},
      {"min_waist_depth_px", &options.min_waist_depth_px},
      {"min_waist_part_share", &options.min_waist_part_share},
      {"ransac_iterations", &options.ransac_iterations},
      {"ransac_seed", &options.ransac_seed},
  };
}

// Parses `text` into the field; false when it is not a finite value of the
// field's type.
bool Set(const Field& field, absl::string_view text) {
  if (auto* d = std::get_if<double*>(&field)) {
    double v = 0.0;
    if (!absl::SimpleAtod(text, &v) || !std::isfinite(v)) return false;
    **d = v;
    return true;
  }
  if (auto* i = std::get_if<int*>(&field)) return absl::SimpleAtoi(text, *i);
  if (auto* b = std::get_if<bool*>(&field)) {
    if (text != "true" && text != "false") return false;
    **b = text == "true";
    return true;
  }
  return absl::SimpleAtoi(text, std::get<uint64_t*>(field));
}

}  // namespace

absl::Status ApplyDetectorOptions(absl::string_view spec,
                                  FoodDetectorOptions& options) {
  FoodDetectorOptions changed = options;  // no partial writes
  const auto fields = Fields(changed);
  std::set<std::string, std::less<>> seen;
  for (absl::string_view pair :
       absl::StrSplit(spec, ',', absl::SkipWhitespace())) {
    pair = absl::StripAsciiWhitespace(pair);
    const size_t eq = pair.find('=');
    if (eq == absl::string_view::npos) {
      return absl::InvalidArgumentError(absl::StrCat(
          "detector option \"", pair, "\" has no '=' (name=value)"));
    }
    const absl::string_view name =
        absl::StripAsciiWhitespace(pair.substr(0, eq));
    const absl::string_view value =
        absl::StripAsciiWhitespace(pair.substr(eq + 1));
    const auto it = fields.find(name);
    if (it == fields.end()) {
      return absl::InvalidArgumentError(
          absl::StrCat("unknown detector option \"", name,
                       "\" (the names are FoodDetectorOptions' fields, "
                       "services/perception/food_detector.h)"));
    }
    if (!seen.insert(std::string(name)).second) {
      return absl::InvalidArgumentError(
          absl::StrCat("detector option \"", name, "\" is given twice"));
    }
    if (!Set(it->second, value)) {
      return absl::InvalidArgumentError(
          absl::StrCat("detector option \"", name, "\": \"", value,
                       "\" is not a finite value of its type"));
    }
  }
  options = changed;
  return absl::OkStatus();
}

}  // namespace bitewise::perception
