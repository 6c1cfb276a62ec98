// Sets FoodDetectorOptions fields by name from a "name=value,name=value"
// string: the detector evaluation's --detector_options, so that a setting
// tried on tuning seeds is rerun from the repository as it was run.
#ifndef BITEWISE_SERVICES_PERCEPTION_FOOD_DETECTOR_OPTIONS_H_
#define BITEWISE_SERVICES_PERCEPTION_FOOD_DETECTOR_OPTIONS_H_

#include "absl/status/status.h"
#include "absl/strings/string_view.h"
#include "services/perception/food_detector.h"

namespace bitewise::perception {

// Applies `spec` ("" or comma-separated name=value pairs; names are the
// FoodDetectorOptions fields, values numbers, or true/false for the two
// switches) to `options`. INVALID_ARGUMENT, naming the pair, for an unknown
// name, a pair without '=', a value that is not a finite number of the
// field's type, or a name given twice; `options` is then left as it was.
absl::Status ApplyDetectorOptions(absl::string_view spec,
                                  FoodDetectorOptions& options);

}  // namespace bitewise::perception

#endif  // BITEWISE_SERVICES_PERCEPTION_FOOD_DETECTOR_OPTIONS_H_
