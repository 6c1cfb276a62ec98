#include "services/perception/food_detector_options.h"

#include <cmath>
#include <cstdint>
#include <functional>
#include <map>
#include <set>
#include <string>
#include <variant>

#include "absl/strings/ascii.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"

namespace bitewise::perception {
namespace {

using Field = std::variant<double*, int*, bool*, uint64_t*>;

// Every field of FoodDetectorOptions by its name, pointing into `options`
// (the macro writes each name from its member, so the two cannot differ).
// A field added to FoodDetectorOptions is added here too.
#define BITEWISE_OPTION(field) \
  { #field, &options.field }
std::map<std::string, Field, std::less<>> Fields(FoodDetectorOptions& options) {
  return {
      BITEWISE_OPTION(min_height_mm),
      BITEWISE_OPTION(plate_tolerance_mm),
      BITEWISE_OPTION(min_item_area_m2),
      BITEWISE_OPTION(min_colour_distance),
      BITEWISE_OPTION(max_bare_plate_mm),
      BITEWISE_OPTION(max_shadow_chroma),
      BITEWISE_OPTION(min_edge_strength),
      BITEWISE_OPTION(min_soft_edge_distance),
      BITEWISE_OPTION(valley_width_px),
      BITEWISE_OPTION(min_valley_mm),
      BITEWISE_OPTION(valley_fraction),
      BITEWISE_OPTION(cliff_window_px),
      BITEWISE_OPTION(min_cliff_mm),
      BITEWISE_OPTION(cliff_fraction),
      BITEWISE_OPTION(min_seed_px),
      BITEWISE_OPTION(terrace_window_px),
      BITEWISE_OPTION(terrace_open_px),
      BITEWISE_OPTION(min_terrace_px),
      BITEWISE_OPTION(max_merge_top_ratio),
      BITEWISE_OPTION(min_enclosed_share),
      BITEWISE_OPTION(enclosed_kin),
      BITEWISE_OPTION(max_enclosed_median_ratio),
      BITEWISE_OPTION(min_sandwich_share),
      BITEWISE_OPTION(max_highlight_hue_deg),
      BITEWISE_OPTION(max_highlight_chroma_share),
      BITEWISE_OPTION(max_highlight_below_plate_l),
      BITEWISE_OPTION(min_crease_shade_l),
      BITEWISE_OPTION(valley_flank_px),
      BITEWISE_OPTION(min_valley_flank_share),
      BITEWISE_OPTION(min_seam_flank_height_share),
      BITEWISE_OPTION(min_contact_seam_share),
      BITEWISE_OPTION(min_contact_part_px),
      BITEWISE_OPTION(min_join_fill),
      BITEWISE_OPTION(min_join_elongation),
      BITEWISE_OPTION(min_stick_seed_elongation),
      BITEWISE_OPTION(min_stick_part_elongation),
      BITEWISE_OPTION(min_stick_fill),
      BITEWISE_OPTION(min_stick_elongation),
      BITEWISE_OPTION(stick_fill_counts_long_parts),
      BITEWISE_OPTION(max_stick_shade_distance),
      BITEWISE_OPTION(join_top_quantile),
      BITEWISE_OPTION(max_waist_solidity),
      BITEWISE_OPTION(min_waist_solidity),
      BITEWISE_OPTION(min_waist_depth_px),
      BITEWISE_OPTION(min_waist_part_share),
      BITEWISE_OPTION(waist_fills_inner_seams),
      BITEWISE_OPTION(max_waist_crumb_px),
      BITEWISE_OPTION(max_waist_cut_share),
      BITEWISE_OPTION(max_tail_width_px),
      BITEWISE_OPTION(max_tail_body_elongation),
      BITEWISE_OPTION(ransac_iterations),
      BITEWISE_OPTION(ransac_seed),
      BITEWISE_OPTION(ransac_below_weight),
  };
}
#undef BITEWISE_OPTION

// Fields whose value sizes a window or a loop: below 1 there is nothing to
// run (OpenCV refuses an empty structuring element).
const std::set<std::string, std::less<>>& AtLeastOne() {
  static const auto* names = new std::set<std::string, std::less<>>{
      "valley_width_px", "terrace_window_px", "terrace_open_px",
      "ransac_iterations"};
  return *names;
}

// Parses `text` into the field; otherwise what was expected.
absl::Status Set(const Field& field, absl::string_view text, int at_least) {
  if (auto* d = std::get_if<double*>(&field)) {
    double v = 0.0;
    if (!absl::SimpleAtod(text, &v) || !std::isfinite(v) || v < at_least) {
      return absl::InvalidArgumentError(
          absl::StrCat("expected a finite number of at least ", at_least));
    }
    **d = v;
    return absl::OkStatus();
  }
  if (auto* i = std::get_if<int*>(&field)) {
    int v = 0;
    if (!absl::SimpleAtoi(text, &v) || v < at_least) {
      return absl::InvalidArgumentError(
          absl::StrCat("expected an integer of at least ", at_least));
    }
    **i = v;
    return absl::OkStatus();
  }
  if (auto* b = std::get_if<bool*>(&field)) {
    if (text != "true" && text != "false") {
      return absl::InvalidArgumentError("expected true or false");
    }
    **b = text == "true";
    return absl::OkStatus();
  }
  uint64_t v = 0;
  if (!absl::SimpleAtoi(text, &v)) {
    return absl::InvalidArgumentError("expected a non-negative integer");
  }
  *std::get<uint64_t*>(field) = v;
  return absl::OkStatus();
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
    const int at_least = AtLeastOne().count(name) ? 1 : 0;
    if (const absl::Status set = Set(it->second, value, at_least); !set.ok()) {
      return absl::InvalidArgumentError(absl::StrCat(
          "detector option \"", name, "\": \"", value, "\": ", set.message()));
    }
  }
  options = changed;
  return absl::OkStatus();
}

}  // namespace bitewise::perception
