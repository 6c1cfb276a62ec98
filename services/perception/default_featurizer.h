// The weight-free featurizer the default meal runs on: a fixed 64-number
// description of a food item from its colour (HSV histograms and RGB
// moments), texture (gradient statistics along and across the item), shape
// (size in metres, elongation, convexity) and height above the plate. Fully
// deterministic, needs no model file, and takes well under a millisecond.
//
// Layout of the context vector (kDefaultFeatureDim = 64):
//   [0, 16)  hue histogram, 16 bins over 0-360 degrees, each pixel weighted
//            by its saturation (greys carry no hue), normalised to sum 1
//   [16, 24) saturation histogram, 8 bins, fraction of item pixels
//   [24, 32) value (brightness) histogram, 8 bins, fraction of item pixels
//   [32, 38) mean R, G, B and their standard deviations, sRGB in [0, 1]
//   [38, 40) mean and standard deviation of the grey gradient magnitude
//            (per pixel, grey in [0, 1])
//   [40, 48) gradient orientation histogram, 8 bins over [0, pi) measured
//            from the item's major axis, magnitude weighted, sums to 1
//   [48, 56) shape: major and minor axis lengths / 0.1 m, minor/major,
//            area / 25 cm^2, extent (area / min-area rectangle), solidity
//            (area / convex hull), circularity 4 pi A / P^2, item pixels /
//            box pixels
//   [56, 60) height above the surrounding plate: 90th percentile / 0.05 m,
//            median / 0.05 m, standard deviation / 0.05 m, and the fraction
//            of item pixels that have depth (all 0 without depth)
//   [60, 63) location one-hot (isolated, wall, lettuce), as SPANet's
//   63       constant 1, so linear models get an intercept
// Lengths need depth; without it they are 0.
#ifndef BITEWISE_SERVICES_PERCEPTION_DEFAULT_FEATURIZER_H_
#define BITEWISE_SERVICES_PERCEPTION_DEFAULT_FEATURIZER_H_

#include <string>

#include "services/perception/featurizer.h"

namespace bitewise::perception {

constexpr int kDefaultFeatureDim = 64;

struct DefaultFeaturizerOptions {
  // CIELAB distance from the surrounding plate's colour beyond which a
  // pixel in the box belongs to the item.
  double min_colour_distance = 14.0;
  // Height above the surrounding plate beyond which a pixel belongs to the
  // item.
  double min_height_mm = 4.0;
};

// Stateless; thread-safe.
class DefaultFeaturizer final : public Featurizer {
 public:
  explicit DefaultFeaturizer(const DefaultFeaturizerOptions& options = {});

  std::string name() const override { return "default"; }
  int dimension() const override { return kDefaultFeatureDim; }
  absl::StatusOr<Features> Featurize(const DecodedFrame& frame,
                                     const PixelBox& box,
                                     FoodLocation location) const override;

 private:
  DefaultFeaturizerOptions options_;
};

}  // namespace bitewise::perception

#endif  // BITEWISE_SERVICES_PERCEPTION_DEFAULT_FEATURIZER_H_
