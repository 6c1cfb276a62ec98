// Helpers shared by the tests of the independent trace stories
// (services/sim/trace_stories.h): the four categories in order, and a median.
#ifndef BITEWISE_TESTS_HAPTIC_STORY_TEST_HELPERS_H_
#define BITEWISE_TESTS_HAPTIC_STORY_TEST_HELPERS_H_

#include <algorithm>
#include <array>
#include <vector>

#include "services/sim/food_catalog.h"

namespace bitewise::sim {

inline constexpr std::array<HapticCategory, 4> kCategories = {
    HapticCategory::kHard, HapticCategory::kMedium, HapticCategory::kSoft,
    HapticCategory::kHardSkin};

// The upper median of `v` (taken by value: it is reordered).
inline double Median(std::vector<double> v) {
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

}  // namespace bitewise::sim

#endif  // BITEWISE_TESTS_HAPTIC_STORY_TEST_HELPERS_H_
