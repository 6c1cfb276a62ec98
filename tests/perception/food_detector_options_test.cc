// ApplyDetectorOptions: FoodDetectorOptions fields set by name from the
// detector evaluation's --detector_options; a bad pair is refused, named,
// and changes nothing.
#include "services/perception/food_detector_options.h"

#include "absl/strings/str_cat.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace bitewise::perception {
namespace {

using ::testing::HasSubstr;

TEST(DetectorOptionsTest, SetsFieldsOfEachTypeByName) {
  FoodDetectorOptions options;
  ASSERT_TRUE(ApplyDetectorOptions(
                  " min_soft_edge_distance=20, valley_width_px = 25,"
                  "enclosed_kin=false,ransac_seed=7,max_merge_top_ratio=1.4",
                  options)
                  .ok());
  EXPECT_EQ(options.min_soft_edge_distance, 20.0);
  EXPECT_EQ(options.valley_width_px, 25);
  EXPECT_FALSE(options.enclosed_kin);
  EXPECT_EQ(options.ransac_seed, 7u);
  EXPECT_EQ(options.max_merge_top_ratio, 1.4);
  // Everything not named keeps its default.
  EXPECT_EQ(options.min_edge_strength, FoodDetectorOptions().min_edge_strength);
  EXPECT_EQ(options.min_seed_px, FoodDetectorOptions().min_seed_px);
}

TEST(DetectorOptionsTest, AnEmptySpecChangesNothing) {
  FoodDetectorOptions options;
  options.min_valley_mm = 2.5;
  ASSERT_TRUE(ApplyDetectorOptions("", options).ok());
  ASSERT_TRUE(ApplyDetectorOptions(" , ", options).ok());
  EXPECT_EQ(options.min_valley_mm, 2.5);
}

TEST(DetectorOptionsTest, ABadPairIsRefusedByNameAndChangesNothing) {
  const struct {
    const char* spec;
    const char* message;
  } cases[] = {
      {"min_soft_edge=20", "unknown detector option \"min_soft_edge\""},
      {"min_soft_edge_distance", "\"min_soft_edge_distance\" has no '='"},
      {"min_soft_edge_distance=soft", "\"soft\" is not a finite value"},
      {"min_soft_edge_distance=nan", "\"nan\" is not a finite value"},
      {"min_soft_edge_distance=inf", "\"inf\" is not a finite value"},
      {"valley_width_px=25.5", "\"25.5\" is not a finite value"},
      {"enclosed_kin=1", "\"1\" is not a finite value"},
      {"min_cliff_mm=2,min_cliff_mm=4", "\"min_cliff_mm\" is given twice"},
  };
  for (const auto& c : cases) {
    FoodDetectorOptions options;
    // A good pair before the bad one is not applied either.
    const absl::Status status =
        ApplyDetectorOptions(absl::StrCat("min_seed_px=99,", c.spec), options);
    EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument) << c.spec;
    EXPECT_THAT(status.message(), HasSubstr(c.message)) << c.spec;
    EXPECT_EQ(options.min_seed_px, FoodDetectorOptions().min_seed_px) << c.spec;
    EXPECT_EQ(options.min_soft_edge_distance,
              FoodDetectorOptions().min_soft_edge_distance)
        << c.spec;
  }
}

}  // namespace
}  // namespace bitewise::perception
