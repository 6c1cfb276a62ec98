// The stages of FoodDetector::Detect, each a function of its inputs so it
// can be read and tested alone (tests/perception/food_detector_stages_test):
//
//   MeasureHeight   depth -> the plate's plane and every pixel's height
//   FindPlate       heights -> the plate (its region and visible surface)
//   FindEvidence    colour and heights inside the plate -> food-like pixels
//   PlantSeeds      one seed per item: bump tops, cut at colour edges and
//                   at height valleys and steps between touching items,
//                   and terraces (an item's part showing beside one on it)
//   GrowRegions     watershed on the RGB image from the seeds
//   MergeSplitItems neighbours that are one item cut in two become one
//   SplitAtWaists   one region that is two convex items with a waist
//                   between them becomes two
//   DescribeItems   each region -> a DetectedFood (box, centre, depth, ...)
//
// Images after FindPlate are the plate's bounding box (roi) of the frame.
// All stages are pure and thread-compatible.
#ifndef BITEWISE_SERVICES_PERCEPTION_FOOD_DETECTOR_STAGES_H_
#define BITEWISE_SERVICES_PERCEPTION_FOOD_DETECTOR_STAGES_H_

#include <optional>
#include <vector>

#include "opencv2/core.hpp"
#include "services/perception/food_detector.h"
#include "services/perception/frame.h"

namespace bitewise::perception::detection {

// A plane n.P + d = 0 in camera coordinates (millimetres), |n| = 1, oriented
// so that the camera (the origin) has positive height.
struct Plane {
  cv::Vec3d n;
  double d = 0.0;
  double Height(const cv::Vec3d& p) const { return n.dot(p) + d; }
};

// The camera-frame point (mm) of pixel (u, v) at depth z_mm.
cv::Vec3d Deproject(const CameraIntrinsics& k, double u, double v, double z_mm);

struct HeightMap {
  Plane plane;
  cv::Mat height_mm;  // CV_32FC1: height above the plane, 0 without depth
  cv::Mat valid;      // CV_8UC1: 255 where the median-filtered depth exists
};

// The plate's plane (RANSAC over the middle of the image, counting points
// well below a plane against it, then least squares on its inliers) and
// each pixel's height above it, after a 5x5 median filter takes out speckle
// holes. nullopt when no plane is found (see
// FoodDetectorOptions::ransac_below_weight).
std::optional<HeightMap> MeasureHeight(const cv::Mat& depth_mm,
                                       const CameraIntrinsics& k,
                                       const FoodDetectorOptions& options);

struct PlateRegion {
  cv::Rect roi;     // the plate's bounding box in the frame
  cv::Mat plate;    // CV_8UC1 over roi: inside the plate's outline
  cv::Mat surface;  // CV_8UC1 over roi: the plate's own visible surface
};

// The largest flat region (within plate_tolerance_mm of the plane), closed
// over its food by its convex hull and eroded from the rim. nullopt when it
// covers less than a tenth of the image.
std::optional<PlateRegion> FindPlate(const HeightMap& heights,
                                     const FoodDetectorOptions& options);

struct FoodEvidence {
  cv::Mat lab;          // CV_32FC3: CIELAB of the roi
  cv::Mat above;        // CV_8UC1: higher than min_height_mm, holes filled
  cv::Mat colour;       // CV_8UC1: farther than min_colour_distance from the
                        // plate's median colour
  cv::Mat bare;         // CV_8UC1: plainly plate (see max_bare_plate_mm)
  cv::Vec3f plate_lab;  // the plate's median colour (CIELAB)
};

// Food by depth and by colour, inside the plate, and the bare plate between.
// `rgb`, `height_mm` and `valid` are the roi's.
FoodEvidence FindEvidence(const cv::Mat& rgb, const cv::Mat& height_mm,
                          const cv::Mat& valid, const PlateRegion& plate,
                          const FoodDetectorOptions& options);

// How far from a pixel the stages after FindEvidence look, at most: the
// widest window among the options (the valley closing's two passes,
// valley_width_px - 1; the step and terrace windows), the flood's reach
// beyond the food (the 15 px dilation, 7 px), the 21 px local top
// (10 px), and a few pixels for the gradients and openings. 52 px with
// the defaults.
int FoodMargin(const FoodDetectorOptions& options);

// The bounding box of the food-like pixels (`above` or `colour`), widened
// by FoodMargin and clipped to the roi; empty when there are none. The
// stages after FindEvidence give the same items on it as on the whole roi.
cv::Rect FoodBox(const FoodEvidence& evidence,
                 const FoodDetectorOptions& options);

// `evidence` restricted to `box` (views, no copies).
FoodEvidence CropEvidence(const FoodEvidence& evidence, const cv::Rect& box);

struct Regions {
  // CV_32SC1 labels: 1..background-1 items; background; 0 unlabelled
  // before GrowRegions, -1 on watershed ridges after it.
  cv::Mat markers;
  int background = 0;
  // CV_32FC1: how far a closing lifts each pixel (height valleys).
  cv::Mat valley_mm;
};

// Greyscale closing (dilate, then erode) of a CV_32FC1 image by a
// structuring element whose rows are each one run of ones (an ellipse, a
// rectangle), anchored at its centre, with OpenCV's border rule (outside
// the image counts for nothing). The same result as cv::morphologyEx(
// MORPH_CLOSE) to the bit, in a fraction of the time for a large ellipse:
// each row of the element is a horizontal running max or min, and the
// rows are combined. Each row of the element must be one run of ones
// (cv::getStructuringElement's ellipses and rectangles are); a row with a
// gap fails a CV_Assert.
cv::Mat CloseByRows(const cv::Mat& image, const cv::Mat& element);

// Seeds: the upper half of every bump in the height map (at least half its
// local top within 21 px), not on a strong colour edge, cut along height
// valleys and steps only where that splits a seed into two or more parts of
// min_seed_px; and terraces, the lower steps beside a higher item that the
// half-height rule leaves without a seed (see FoodDetectorOptions). nullopt
// when there is no seed.
std::optional<Regions> PlantSeeds(const FoodEvidence& evidence,
                                  const cv::Mat& height_mm,
                                  const FoodDetectorOptions& options);

// Marks the background (plate well away from food-like pixels, bare plate,
// and all that is off the plate) and floods the RGB image from the seeds.
void GrowRegions(const cv::Mat& rgb, const FoodEvidence& evidence,
                 const cv::Mat& plate, Regions& regions);

// Joins neighbouring regions of similar colour with no valley in height
// along their shared boundary (one item cut in two), unless one's top stands
// more than max_merge_top_ratio times the other's (one lies on the other);
// and, whatever their colour, a part inside an item, a highlight, a band
// across an item and a stick's two parts under an item lying across it
// (see FoodDetectorOptions).
void MergeSplitItems(const FoodEvidence& evidence, const cv::Mat& height_mm,
                     const cv::Mat& valid, const FoodDetectorOptions& options,
                     Regions& regions);

// Cuts each region with a waist in two (see max_waist_solidity in
// FoodDetectorOptions): two touching convex items that grew as one. The
// cut is a ridge (-1); the new part takes the next label, and the
// background's label moves up by one per cut.
void SplitAtWaists(const FoodDetectorOptions& options, Regions& regions);

// One DetectedFood per region of at least min_item_area_m2 on the plate
// (ridge pixels that look like food join a neighbour), in frame pixels,
// sorted by score, then top to bottom, then left to right. `raw_depth_mm`
// is the roi of the unfiltered depth.
std::vector<DetectedFood> DescribeItems(const Regions& regions,
                                        const FoodEvidence& evidence,
                                        const cv::Mat& raw_depth_mm,
                                        const cv::Rect& roi, const Plane& plane,
                                        const CameraIntrinsics& k,
                                        const FoodDetectorOptions& options);

}  // namespace bitewise::perception::detection

#endif  // BITEWISE_SERVICES_PERCEPTION_FOOD_DETECTOR_STAGES_H_
