#include "services/perception/default_featurizer.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "opencv2/imgproc.hpp"
#include "services/common/status_macros.h"
#include "services/perception/context_scale.h"
#include "services/perception/default_featurizer_stats_data.h"

namespace bitewise::perception {
namespace {

constexpr double kPi = 3.14159265358979323846;
// Pixels around the box that sample the plate the item lies on.
constexpr int kRingPx = 4;

double Median(std::vector<double> values) {
  if (values.empty()) return 0.0;
  const size_t mid = values.size() / 2;
  std::nth_element(values.begin(), values.begin() + mid, values.end());
  return values[mid];
}

double Percentile(std::vector<double> values, double p) {
  if (values.empty()) return 0.0;
  const size_t k =
      std::min(values.size() - 1, static_cast<size_t>(p * values.size()));
  std::nth_element(values.begin(), values.begin() + k, values.end());
  return values[k];
}

// Standard deviations below this are treated as this: features that barely
// vary among seen foods are not blown up.
constexpr double kMinSd = 1e-3;
// Features [0, kStandardised) are standardised.
constexpr int kStandardised = 60;

}  // namespace

absl::StatusOr<DefaultFeaturizerStats> ParseDefaultFeaturizerStats(
    const std::string& text) {
  DefaultFeaturizerStats stats;
  stats.mean.assign(kDefaultFeatureDim, std::nan(""));
  stats.sd.assign(kDefaultFeatureDim, std::nan(""));
  for (const StatsLine& line : StatsLines(text)) {
    const std::vector<absl::string_view>& fields = line.fields;
    auto bad = [&](absl::string_view why) {
      return absl::InvalidArgumentError(
          absl::StrCat("featurizer statistics line ", line.number, ": ", why,
                       ": \"", line.text, "\""));
    };
    if (fields[0] == "version" && fields.size() == 2) {
      if (!absl::SimpleAtoi(fields[1], &stats.version)) {
        return bad("version is not an integer");
      }
    } else if (fields[0] == "mean_squared_norm" && fields.size() == 2) {
      if (!absl::SimpleAtod(fields[1], &stats.mean_squared_norm) ||
          !(stats.mean_squared_norm > 0.0)) {
        return bad("mean_squared_norm must be a positive number");
      }
    } else if (fields[0] == "feature" && fields.size() == 4) {
      int k = -1;
      double mean = 0.0, sd = 0.0;
      if (!absl::SimpleAtoi(fields[1], &k) || k < 0 ||
          k >= kDefaultFeatureDim || !absl::SimpleAtod(fields[2], &mean) ||
          !absl::SimpleAtod(fields[3], &sd) || !std::isfinite(mean) ||
          !std::isfinite(sd) || sd < 0.0) {
        return bad("expected: feature <0-63> <mean> <sd >= 0>");
      }
      stats.mean[k] = mean;
      stats.sd[k] = sd;
    } else {
      return bad("unknown entry");
    }
  }
  if (stats.version < 1) {
    return absl::InvalidArgumentError("featurizer statistics: no version line");
  }
  for (int k = 0; k < kDefaultFeatureDim; ++k) {
    if (std::isnan(stats.mean[k])) {
      return absl::InvalidArgumentError(
          absl::StrCat("featurizer statistics: feature ", k, " is missing"));
    }
  }
  if (!(stats.mean_squared_norm > 0.0)) {
    return absl::InvalidArgumentError(
        "featurizer statistics: no mean_squared_norm line");
  }
  return stats;
}

void StandardizeDefaultFeatures(const DefaultFeaturizerStats& stats,
                                std::vector<double>* features) {
  std::vector<double>& f = *features;
  for (int k = 0; k < kStandardised; ++k) {
    const double z = (f[k] - stats.mean[k]) / std::max(stats.sd[k], kMinSd);
    f[k] = std::clamp(z, -kStandardClip, kStandardClip);
  }
}

const DefaultFeaturizerStats& ShippedDefaultFeaturizerStats() {
  static const DefaultFeaturizerStats* const stats = [] {
    absl::StatusOr<DefaultFeaturizerStats> parsed =
        ParseDefaultFeaturizerStats(kDefaultFeaturizerStatsText);
    if (!parsed.ok()) {
      std::fprintf(stderr, "embedded %s: %s\n", kDefaultFeaturizerStatsSource,
                   parsed.status().ToString().c_str());
      std::abort();
    }
    return new DefaultFeaturizerStats(*std::move(parsed));
  }();
  return *stats;
}

double DefaultFeaturizer::context_mean_squared_norm() const {
  return options_.standardize
             ? ShippedDefaultFeaturizerStats().mean_squared_norm
             : 0.0;
}

DefaultFeaturizer::DefaultFeaturizer(const DefaultFeaturizerOptions& options)
    : options_(options) {}

absl::StatusOr<Features> DefaultFeaturizer::Featurize(
    const DecodedFrame& frame, const PixelBox& box,
    FoodLocation location) const {
  RETURN_IF_ERROR(ValidateBox(box, frame.width(), frame.height()));
  if (!frame.has_depth()) {
    // Without depth, the size and height features would come out at their
    // floor and look like any other context to the bandit.
    return absl::InvalidArgumentError(
        "frame.depth_mm is empty: the default featurizer measures the "
        "item's size and height from the aligned depth image (features "
        "48-63); send the frame with its depth");
  }
  const cv::Rect inner(box.x, box.y, box.width, box.height);
  const cv::Rect outer =
      cv::Rect(box.x - kRingPx, box.y - kRingPx, box.width + 2 * kRingPx,
               box.height + 2 * kRingPx) &
      cv::Rect(0, 0, frame.width(), frame.height());
  const cv::Mat crop = frame.rgb(inner);

  // The plate around the item: the ring between the box and the grown box
  // (or the box's own edge pixels when the box fills the frame).
  cv::Mat lab_outer;
  cv::Mat rgb_outer_f;
  frame.rgb(outer).convertTo(rgb_outer_f, CV_32FC3, 1.0 / 255.0);
  cv::cvtColor(rgb_outer_f, lab_outer, cv::COLOR_RGB2Lab);
  const cv::Rect inner_in_outer = inner - outer.tl();
  std::vector<double> ring_l, ring_a, ring_b, ring_depth;
  for (int v = 0; v < outer.height; ++v) {
    for (int u = 0; u < outer.width; ++u) {
      const bool inside = inner_in_outer.contains({u, v});
      const bool edge = u == inner_in_outer.x || v == inner_in_outer.y ||
                        u == inner_in_outer.br().x - 1 ||
                        v == inner_in_outer.br().y - 1;
      if (inside && !(outer == inner && edge)) continue;
      const cv::Vec3f& p = lab_outer.at<cv::Vec3f>(v, u);
      ring_l.push_back(p[0]);
      ring_a.push_back(p[1]);
      ring_b.push_back(p[2]);
      if (frame.has_depth()) {
        const uint16_t d =
            frame.depth_mm.at<uint16_t>(v + outer.y, u + outer.x);
        if (d > 0) ring_depth.push_back(d);
      }
    }
  }
  const cv::Vec3f plate_lab(static_cast<float>(Median(ring_l)),
                            static_cast<float>(Median(ring_a)),
                            static_cast<float>(Median(ring_b)));
  const double plate_depth_mm = Median(ring_depth);

  // The item: what differs from that plate in colour or rises above it,
  // largest connected part.
  const cv::Mat lab = lab_outer(inner_in_outer);
  cv::Mat item(box.height, box.width, CV_8UC1, cv::Scalar(0));
  const double de2 =
      options_.min_colour_distance * options_.min_colour_distance;
  for (int v = 0; v < box.height; ++v) {
    for (int u = 0; u < box.width; ++u) {
      const cv::Vec3f diff = lab.at<cv::Vec3f>(v, u) - plate_lab;
      bool food = diff.dot(diff) > de2;
      if (!food && frame.has_depth() && plate_depth_mm > 0) {
        const uint16_t d = frame.depth_mm.at<uint16_t>(v + box.y, u + box.x);
        food = d > 0 && plate_depth_mm - d > options_.min_height_mm;
      }
      if (food) item.at<uint8_t>(v, u) = 255;
    }
  }
  cv::Mat labels, stats, centroids;
  const int n =
      cv::connectedComponentsWithStats(item, labels, stats, centroids, 8);
  int best = -1;
  for (int i = 1; i < n; ++i) {
    if (best < 0 || stats.at<int>(i, cv::CC_STAT_AREA) >
                        stats.at<int>(best, cv::CC_STAT_AREA)) {
      best = i;
    }
  }
  // An item that cannot be told from the plate: describe the whole box.
  if (best < 0 || stats.at<int>(best, cv::CC_STAT_AREA) <
                      std::max(4, box.width * box.height / 20)) {
    item.setTo(255);
  } else {
    item = labels == best;
  }
  std::vector<cv::Point> points;
  cv::findNonZero(item, points);
  const double area_px = static_cast<double>(points.size());

  Features features;
  std::vector<double>& f = features.context;
  f.assign(kDefaultFeatureDim, 0.0);

  // Colour.
  cv::Mat hsv;
  cv::cvtColor(crop, hsv, cv::COLOR_RGB2HSV_FULL);  // H in 0-255
  double hue_weight = 0.0;
  cv::Vec3d sum(0, 0, 0), sum2(0, 0, 0);
  for (const cv::Point& p : points) {
    const cv::Vec3b& c = hsv.at<cv::Vec3b>(p);
    const double s = c[1] / 255.0;
    f[std::min(15, c[0] * 16 / 256)] += s;
    hue_weight += s;
    f[16 + std::min(7, c[1] * 8 / 256)] += 1.0 / area_px;
    f[24 + std::min(7, c[2] * 8 / 256)] += 1.0 / area_px;
    const cv::Vec3b& rgb = crop.at<cv::Vec3b>(p);
    for (int k = 0; k < 3; ++k) {
      sum[k] += rgb[k] / 255.0;
      sum2[k] += (rgb[k] / 255.0) * (rgb[k] / 255.0);
    }
  }
  if (hue_weight > 0) {
    for (int k = 0; k < 16; ++k) f[k] /= hue_weight;
  }
  for (int k = 0; k < 3; ++k) {
    const double mean = sum[k] / area_px;
    f[32 + k] = mean;
    f[35 + k] = std::sqrt(std::max(0.0, sum2[k] / area_px - mean * mean));
  }

  // Shape, from the item's outline.
  const cv::RotatedRect rect = cv::minAreaRect(points);
  const double major_px = std::max(rect.size.width, rect.size.height);
  const double minor_px = std::min(rect.size.width, rect.size.height);
  double axis_rad = rect.angle * kPi / 180.0;
  if (rect.size.width < rect.size.height) axis_rad += kPi / 2;

  // Texture: gradients of the grey image, orientation relative to the
  // major axis so that the features do not depend on how the item lies.
  cv::Mat grey, gx, gy;
  cv::cvtColor(crop, grey, cv::COLOR_RGB2GRAY);
  grey.convertTo(grey, CV_32F, 1.0 / 255.0);
  cv::Sobel(grey, gx, CV_32F, 1, 0, 3, 1.0 / 8);
  cv::Sobel(grey, gy, CV_32F, 0, 1, 3, 1.0 / 8);
  double g_sum = 0, g_sum2 = 0;
  for (const cv::Point& p : points) {
    const double x = gx.at<float>(p), y = gy.at<float>(p);
    const double mag = std::hypot(x, y);
    g_sum += mag;
    g_sum2 += mag * mag;
    double theta = std::atan2(y, x) - axis_rad;
    theta = std::fmod(theta, kPi);
    if (theta < 0) theta += kPi;
    f[40 + std::min(7, static_cast<int>(theta / kPi * 8))] += mag;
  }
  const double g_mean = g_sum / area_px;
  f[38] = g_mean;
  f[39] = std::sqrt(std::max(0.0, g_sum2 / area_px - g_mean * g_mean));
  if (g_sum > 0) {
    for (int k = 40; k < 48; ++k) f[k] /= g_sum;
  }

  // Depth: height above the surrounding plate, and the item's distance for
  // converting pixels to metres.
  std::vector<double> heights, depths;
  if (frame.has_depth()) {
    for (const cv::Point& p : points) {
      const uint16_t d = frame.depth_mm.at<uint16_t>(p.y + box.y, p.x + box.x);
      if (d == 0) continue;
      depths.push_back(d);
      if (plate_depth_mm > 0) heights.push_back(plate_depth_mm - d);
    }
  }
  const double z_m = (depths.empty() ? plate_depth_mm : Median(depths)) / 1000;
  const double m_per_px =
      z_m > 0 ? z_m / std::sqrt(frame.intrinsics.fx * frame.intrinsics.fy)
              : 0.0;
  std::vector<cv::Point> contour_hull;
  cv::convexHull(points, contour_hull);
  const double hull_area = std::max(1.0, cv::contourArea(contour_hull));
  std::vector<std::vector<cv::Point>> contours;
  cv::findContours(item.clone(), contours, cv::RETR_EXTERNAL,
                   cv::CHAIN_APPROX_NONE);
  double perimeter = 0.0;
  for (const auto& c : contours) perimeter += cv::arcLength(c, true);
  f[48] = major_px * m_per_px / 0.1;
  f[49] = minor_px * m_per_px / 0.1;
  f[50] = major_px > 0 ? minor_px / major_px : 0.0;
  f[51] = area_px * m_per_px * m_per_px / 25e-4;
  f[52] = std::min(1.0, area_px / std::max(1.0, major_px * minor_px));
  f[53] = std::min(1.0, area_px / hull_area);
  f[54] = perimeter > 0
              ? std::min(1.0, 4 * kPi * area_px / (perimeter * perimeter))
              : 0.0;
  f[55] = area_px / (static_cast<double>(box.width) * box.height);
  if (!heights.empty()) {
    double mean = 0, mean2 = 0;
    for (double h : heights) {
      mean += h;
      mean2 += h * h;
    }
    mean /= heights.size();
    mean2 /= heights.size();
    f[56] = Percentile(heights, 0.9) / 50.0;
    f[57] = Median(heights) / 50.0;
    f[58] = std::sqrt(std::max(0.0, mean2 - mean * mean)) / 50.0;
  }
  f[59] = depths.size() / area_px;
  f[60 + static_cast<int>(location)] = 1.0;
  f[63] = 1.0;
  if (options_.standardize) {
    StandardizeDefaultFeatures(ShippedDefaultFeaturizerStats(), &f);
  }
  return features;
}

}  // namespace bitewise::perception
