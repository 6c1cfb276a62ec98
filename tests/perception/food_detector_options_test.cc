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

TEST(DetectorOptionsTest, EveryFieldIsSetByItsOwnName) {
  // Each field a value of its own (the switches, true by default, false):
  // a name pointing at another field, or a field left out, fails here.
  FoodDetectorOptions options;
  for (const char* name : {"enclosed_kin", "stick_fill_counts_long_parts",
                           "waist_fills_inner_seams"}) {
    ASSERT_TRUE(
        ApplyDetectorOptions(absl::StrCat(name, "=true"), options).ok());
  }
  ASSERT_TRUE(ApplyDetectorOptions("min_height_mm=101.5,"
                                   "plate_tolerance_mm=102.5,"
                                   "min_item_area_m2=103.5,"
                                   "min_colour_distance=104.5,"
                                   "max_bare_plate_mm=105.5,"
                                   "max_shadow_chroma=106.5,"
                                   "min_edge_strength=107.5,"
                                   "min_soft_edge_distance=108.5,"
                                   "valley_width_px=109,"
                                   "min_valley_mm=110.5,"
                                   "valley_fraction=111.5,"
                                   "cliff_window_px=112,"
                                   "min_cliff_mm=113.5,"
                                   "cliff_fraction=114.5,"
                                   "min_seed_px=115,"
                                   "terrace_window_px=116,"
                                   "terrace_open_px=117,"
                                   "min_terrace_px=118,"
                                   "max_merge_top_ratio=119.5,"
                                   "min_enclosed_share=120.5,"
                                   "enclosed_kin=false,"
                                   "max_enclosed_median_ratio=156.5,"
                                   "min_sandwich_share=122.5,"
                                   "max_highlight_hue_deg=123.5,"
                                   "max_highlight_chroma_share=124.5,"
                                   "max_highlight_below_plate_l=125.5,"
                                   "min_crease_shade_l=126.5,"
                                   "valley_flank_px=127,"
                                   "min_valley_flank_share=128.5,"
                                   "min_seam_flank_height_share=129.5,"
                                   "min_contact_seam_share=145.5,"
                                   "min_contact_part_px=146,"
                                   "min_join_fill=130.5,"
                                   "min_join_elongation=131.5,"
                                   "min_stick_seed_elongation=132.5,"
                                   "min_stick_part_elongation=133.5,"
                                   "min_stick_fill=134.5,"
                                   "min_stick_elongation=135.5,"
                                   "stick_fill_counts_long_parts=false,"
                                   "max_stick_shade_distance=137.5,"
                                   "join_top_quantile=138.5,"
                                   "max_waist_solidity=139.5,"
                                   "min_waist_solidity=140.5,"
                                   "min_waist_depth_px=141.5,"
                                   "min_waist_part_share=142.5,"
                                   "waist_fills_inner_seams=false,"
                                   "max_waist_crumb_px=155,"
                                   "max_waist_cut_share=152.5,"
                                   "max_tail_width_px=153.5,"
                                   "max_tail_body_elongation=154.5,"
                                   "ransac_iterations=143,"
                                   "ransac_seed=144,"
                                   "ransac_below_weight=147.5",
                                   options)
                  .ok());
  EXPECT_EQ(options.min_height_mm, 101.5);
  EXPECT_EQ(options.plate_tolerance_mm, 102.5);
  EXPECT_EQ(options.min_item_area_m2, 103.5);
  EXPECT_EQ(options.min_colour_distance, 104.5);
  EXPECT_EQ(options.max_bare_plate_mm, 105.5);
  EXPECT_EQ(options.max_shadow_chroma, 106.5);
  EXPECT_EQ(options.min_edge_strength, 107.5);
  EXPECT_EQ(options.min_soft_edge_distance, 108.5);
  EXPECT_EQ(options.valley_width_px, 109);
  EXPECT_EQ(options.min_valley_mm, 110.5);
  EXPECT_EQ(options.valley_fraction, 111.5);
  EXPECT_EQ(options.cliff_window_px, 112);
  EXPECT_EQ(options.min_cliff_mm, 113.5);
  EXPECT_EQ(options.cliff_fraction, 114.5);
  EXPECT_EQ(options.min_seed_px, 115);
  EXPECT_EQ(options.terrace_window_px, 116);
  EXPECT_EQ(options.terrace_open_px, 117);
  EXPECT_EQ(options.min_terrace_px, 118);
  EXPECT_EQ(options.max_merge_top_ratio, 119.5);
  EXPECT_EQ(options.min_enclosed_share, 120.5);
  EXPECT_FALSE(options.enclosed_kin);
  EXPECT_EQ(options.max_enclosed_median_ratio, 156.5);
  EXPECT_EQ(options.min_sandwich_share, 122.5);
  EXPECT_EQ(options.max_highlight_hue_deg, 123.5);
  EXPECT_EQ(options.max_highlight_chroma_share, 124.5);
  EXPECT_EQ(options.max_highlight_below_plate_l, 125.5);
  EXPECT_EQ(options.min_crease_shade_l, 126.5);
  EXPECT_EQ(options.valley_flank_px, 127);
  EXPECT_EQ(options.min_valley_flank_share, 128.5);
  EXPECT_EQ(options.min_seam_flank_height_share, 129.5);
  EXPECT_EQ(options.min_contact_seam_share, 145.5);
  EXPECT_EQ(options.min_contact_part_px, 146);
  EXPECT_EQ(options.min_join_fill, 130.5);
  EXPECT_EQ(options.min_join_elongation, 131.5);
  EXPECT_EQ(options.min_stick_seed_elongation, 132.5);
  EXPECT_EQ(options.min_stick_part_elongation, 133.5);
  EXPECT_EQ(options.min_stick_fill, 134.5);
  EXPECT_EQ(options.min_stick_elongation, 135.5);
  EXPECT_FALSE(options.stick_fill_counts_long_parts);
  EXPECT_EQ(options.max_stick_shade_distance, 137.5);
  EXPECT_EQ(options.join_top_quantile, 138.5);
  EXPECT_EQ(options.max_waist_solidity, 139.5);
  EXPECT_EQ(options.min_waist_solidity, 140.5);
  EXPECT_EQ(options.min_waist_depth_px, 141.5);
  EXPECT_EQ(options.min_waist_part_share, 142.5);
  EXPECT_FALSE(options.waist_fills_inner_seams);
  EXPECT_EQ(options.max_waist_crumb_px, 155);
  EXPECT_EQ(options.max_waist_cut_share, 152.5);
  EXPECT_EQ(options.max_tail_width_px, 153.5);
  EXPECT_EQ(options.max_tail_body_elongation, 154.5);
  EXPECT_EQ(options.ransac_iterations, 143);
  EXPECT_EQ(options.ransac_seed, 144u);
  EXPECT_EQ(options.ransac_below_weight, 147.5);
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
      {"min_soft_edge_distance=soft",
       "\"soft\": expected a finite number of at least 0"},
      {"min_soft_edge_distance=nan", "\"nan\": expected a finite number"},
      {"min_soft_edge_distance=inf", "\"inf\": expected a finite number"},
      {"min_soft_edge_distance=-1", "\"-1\": expected a finite number"},
      {"valley_width_px=25.5", "\"25.5\": expected an integer of at least 1"},
      {"valley_width_px=0", "\"0\": expected an integer of at least 1"},
      {"min_terrace_px=-1", "\"-1\": expected an integer of at least 0"},
      {"enclosed_kin=1", "\"1\": expected true or false"},
      {"ransac_seed=-1", "\"-1\": expected a non-negative integer"},
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
