#include "services/perception/food_detector_stages.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <optional>
#include <random>
#include <set>
#include <utility>
#include <vector>

#include "opencv2/imgproc.hpp"
#include "services/domain/random.h"

namespace bitewise::perception::detection {
namespace {

constexpr double kPi = 3.14159265358979323846;

std::optional<Plane> PlaneThrough(const cv::Vec3d& a, const cv::Vec3d& b,
                                  const cv::Vec3d& c) {
  cv::Vec3d n = (b - a).cross(c - a);
  const double norm = cv::norm(n);
  if (norm < 1e-6) return std::nullopt;
  n /= norm;
  Plane plane{n, -n.dot(a)};
  if (plane.d < 0) {
    plane.n = -plane.n;
    plane.d = -plane.d;
  }
  return plane;
}

// Least-squares plane through points: the normal is the direction of least
// spread.
std::optional<Plane> FitLeastSquares(const std::vector<cv::Vec3d>& points) {
  if (points.size() < 3) return std::nullopt;
  cv::Vec3d mean(0, 0, 0);
  for (const cv::Vec3d& p : points) mean += p;
  mean /= static_cast<double>(points.size());
  cv::Matx33d cov = cv::Matx33d::zeros();
  for (const cv::Vec3d& p : points) {
    const cv::Vec3d q = p - mean;
    cov += q * q.t();
  }
  cv::Mat values, vectors;
  cv::eigen(cv::Mat(cov), values, vectors);  // descending eigenvalues
  cv::Vec3d n(vectors.at<double>(2, 0), vectors.at<double>(2, 1),
              vectors.at<double>(2, 2));
  Plane plane{n, -n.dot(mean)};
  if (plane.d < 0) {
    plane.n = -plane.n;
    plane.d = -plane.d;
  }
  return plane;
}

// The plate's surface plane, from points in the middle of the image, where
// the plate is when the camera looks at it. RANSAC because food covers part
// of that window; a plane's points well below it count against it
// (FoodDetectorOptions::ransac_below_weight).
std::optional<Plane> FitPlatePlane(const cv::Mat& depth_mm,
                                   const CameraIntrinsics& k,
                                   const FoodDetectorOptions& options) {
  const int w = depth_mm.cols, h = depth_mm.rows;
  std::vector<cv::Vec3d> points;
  const int step = std::max(1, std::min(w, h) / 160);
  for (int v = h * 3 / 10; v < h * 7 / 10; v += step) {
    const auto* row = depth_mm.ptr<uint16_t>(v);
    for (int u = w * 3 / 10; u < w * 7 / 10; u += step) {
      if (row[u] > 0) points.push_back(Deproject(k, u, v, row[u]));
    }
  }
  if (points.size() < 50) return std::nullopt;
  std::mt19937_64 rng(options.ransac_seed);
  auto pick = [&] {
    return static_cast<size_t>(
        random::UniformInt(rng, 0, static_cast<int64_t>(points.size()) - 1));
  };
  std::optional<Plane> best;
  double best_score = 0.0;
  const size_t check_step = std::max<size_t>(1, points.size() / 1500);
  for (int it = 0; it < options.ransac_iterations; ++it) {
    std::optional<Plane> plane =
        PlaneThrough(points[pick()], points[pick()], points[pick()]);
    if (!plane) continue;
    size_t inliers = 0, below = 0;
    for (size_t i = 0; i < points.size(); i += check_step) {
      const double height = plane->Height(points[i]);
      if (std::abs(height) < options.plate_tolerance_mm) {
        ++inliers;
      } else if (height < -options.plate_tolerance_mm) {
        ++below;
      }
    }
    const double score =
        static_cast<double>(inliers) - options.ransac_below_weight * below;
    if (score > best_score) {
      best_score = score;
      best = plane;
    }
  }
  if (!best) return std::nullopt;
  std::vector<cv::Vec3d> inliers;
  for (const cv::Vec3d& p : points) {
    if (std::abs(best->Height(p)) < options.plate_tolerance_mm) {
      inliers.push_back(p);
    }
  }
  return FitLeastSquares(inliers);
}

double Median(std::vector<double>& values) {
  if (values.empty()) return 0.0;
  const size_t mid = values.size() / 2;
  std::nth_element(values.begin(), values.begin() + mid, values.end());
  return values[mid];
}

// Fills every hole inside the blobs of a binary mask.
cv::Mat FillHoles(const cv::Mat& mask) {
  std::vector<std::vector<cv::Point>> contours;
  cv::findContours(mask.clone(), contours, cv::RETR_EXTERNAL,
                   cv::CHAIN_APPROX_SIMPLE);
  cv::Mat filled = cv::Mat::zeros(mask.size(), CV_8UC1);
  cv::drawContours(filled, contours, -1, cv::Scalar(255), cv::FILLED);
  return filled;
}

double MajorAxisAngle(const std::vector<cv::Point>& points) {
  const cv::RotatedRect rect = cv::minAreaRect(points);
  cv::Point2f corners[4];
  rect.points(corners);
  const cv::Point2f e1 = corners[1] - corners[0];
  const cv::Point2f e2 = corners[2] - corners[1];
  const cv::Point2f major = cv::norm(e1) >= cv::norm(e2) ? e1 : e2;
  double angle = std::atan2(major.y, major.x);
  if (angle <= -kPi / 2) angle += kPi;
  if (angle > kPi / 2) angle -= kPi;
  return angle;
}

}  // namespace

cv::Vec3d Deproject(const CameraIntrinsics& k, double u, double v,
                    double z_mm) {
  return {(u - k.cx) * z_mm / k.fx, (v - k.cy) * z_mm / k.fy, z_mm};
}

std::optional<HeightMap> MeasureHeight(const cv::Mat& depth_mm,
                                       const CameraIntrinsics& k,
                                       const FoodDetectorOptions& options) {
  const int w = depth_mm.cols, h = depth_mm.rows;
  // Speckle holes and single-pixel noise out; larger holes stay holes.
  cv::Mat depth;
  cv::medianBlur(depth_mm, depth, 5);
  const std::optional<Plane> plane = FitPlatePlane(depth, k, options);
  if (!plane) return std::nullopt;
  HeightMap map;
  map.plane = *plane;
  map.height_mm = cv::Mat(h, w, CV_32FC1, cv::Scalar(0));
  map.valid = cv::Mat(h, w, CV_8UC1, cv::Scalar(0));
  for (int v = 0; v < h; ++v) {
    const auto* d = depth.ptr<uint16_t>(v);
    auto* out = map.height_mm.ptr<float>(v);
    auto* ok = map.valid.ptr<uint8_t>(v);
    for (int u = 0; u < w; ++u) {
      if (d[u] == 0) continue;
      ok[u] = 255;
      out[u] = static_cast<float>(plane->Height(Deproject(k, u, v, d[u])));
    }
  }
  return map;
}

std::optional<PlateRegion> FindPlate(const HeightMap& heights,
                                     const FoodDetectorOptions& options) {
  const int w = heights.height_mm.cols, h = heights.height_mm.rows;
  // The plate: the largest flat region, closed over its food (convex hull).
  cv::Mat surface =
      heights.valid & (cv::abs(heights.height_mm) < options.plate_tolerance_mm);
  cv::morphologyEx(surface, surface, cv::MORPH_CLOSE,
                   cv::getStructuringElement(cv::MORPH_ELLIPSE, {5, 5}));
  cv::Mat labels, stats, centroids;
  const int n_surface =
      cv::connectedComponentsWithStats(surface, labels, stats, centroids, 8);
  int plate_label = -1;
  int plate_area = 0;
  for (int i = 1; i < n_surface; ++i) {
    if (stats.at<int>(i, cv::CC_STAT_AREA) > plate_area) {
      plate_area = stats.at<int>(i, cv::CC_STAT_AREA);
      plate_label = i;
    }
  }
  if (plate_label < 0 || plate_area < w * h / 10) return std::nullopt;
  const cv::Mat plate_surface_full = labels == plate_label;
  std::vector<std::vector<cv::Point>> contours;
  cv::findContours(plate_surface_full.clone(), contours, cv::RETR_EXTERNAL,
                   cv::CHAIN_APPROX_SIMPLE);
  std::vector<cv::Point> outline;
  for (const auto& c : contours)
    outline.insert(outline.end(), c.begin(), c.end());
  std::vector<cv::Point> hull;
  cv::convexHull(outline, hull);
  cv::Mat plate = cv::Mat::zeros(h, w, CV_8UC1);
  cv::fillConvexPoly(plate, hull, cv::Scalar(255));
  cv::erode(plate, plate, cv::getStructuringElement(cv::MORPH_ELLIPSE, {7, 7}));
  PlateRegion region;
  region.roi = cv::boundingRect(hull) & cv::Rect(0, 0, w, h);
  region.plate = plate(region.roi);
  region.surface = plate_surface_full(region.roi);
  return region;
}

FoodEvidence FindEvidence(const cv::Mat& rgb, const cv::Mat& height_mm,
                          const cv::Mat& valid, const PlateRegion& region,
                          const FoodDetectorOptions& options) {
  const int w = rgb.cols, h = rgb.rows;
  const cv::Mat& plate = region.plate;
  const cv::Mat& plate_surface = region.surface;
  FoodEvidence evidence;
  // Food by depth: above the plate surface, inside the plate.
  cv::Mat& above = evidence.above;
  above = valid & (height_mm > options.min_height_mm) & plate;
  cv::morphologyEx(above, above, cv::MORPH_OPEN,
                   cv::getStructuringElement(cv::MORPH_ELLIPSE, {3, 3}));
  above = FillHoles(above) & plate;

  // Food by colour: far from the plate's own colour in CIELAB.
  cv::Mat rgb_f;
  cv::Mat& lab = evidence.lab;
  rgb.convertTo(rgb_f, CV_32FC3, 1.0 / 255.0);
  cv::cvtColor(rgb_f, lab, cv::COLOR_RGB2Lab);
  std::vector<double> ls, as, bs;
  for (int v = 0; v < h; v += 3) {
    const auto* s = plate_surface.ptr<uint8_t>(v);
    const auto* px = lab.ptr<cv::Vec3f>(v);
    for (int u = 0; u < w; u += 3) {
      if (!s[u]) continue;
      ls.push_back(px[u][0]);
      as.push_back(px[u][1]);
      bs.push_back(px[u][2]);
    }
  }
  const cv::Vec3f plate_lab(static_cast<float>(Median(ls)),
                            static_cast<float>(Median(as)),
                            static_cast<float>(Median(bs)));
  evidence.plate_lab = plate_lab;
  cv::Mat& colour = evidence.colour;
  colour = cv::Mat(h, w, CV_8UC1, cv::Scalar(0));
  const float min_de2 = static_cast<float>(options.min_colour_distance *
                                           options.min_colour_distance);
  const float max_shadow_c2 =
      static_cast<float>(options.max_shadow_chroma * options.max_shadow_chroma);
  for (int v = 0; v < h; ++v) {
    const auto* px = lab.ptr<cv::Vec3f>(v);
    const auto* in = plate.ptr<uint8_t>(v);
    const auto* ok = valid.ptr<uint8_t>(v);
    const auto* hv = height_mm.ptr<float>(v);
    auto* out = colour.ptr<uint8_t>(v);
    for (int u = 0; u < w; ++u) {
      if (!in[u]) continue;
      const cv::Vec3f diff = px[u] - plate_lab;
      if (diff.dot(diff) <= min_de2) continue;
      const bool shadow =
          ok[u] && hv[u] <= options.max_bare_plate_mm && diff[0] < 0.0f &&
          diff[1] * diff[1] + diff[2] * diff[2] <= max_shadow_c2;
      if (!shadow) out[u] = 255;
    }
  }
  cv::morphologyEx(colour, colour, cv::MORPH_OPEN,
                   cv::getStructuringElement(cv::MORPH_ELLIPSE, {3, 3}));

  // Bare plate: depth on the plate and the plate's colour.
  evidence.bare =
      options.max_bare_plate_mm > 0.0
          ? cv::Mat(valid & (height_mm <= options.max_bare_plate_mm) & plate &
                    ~colour & ~above)
          : cv::Mat(h, w, CV_8UC1, cv::Scalar(0));
  return evidence;
}

int FoodMargin(const FoodDetectorOptions& options) {
  const int widest = std::max({options.valley_width_px, options.cliff_window_px,
                               options.terrace_window_px});
  return widest + 7 + 10 + 4;
}

cv::Rect FoodBox(const FoodEvidence& evidence,
                 const FoodDetectorOptions& options) {
  const cv::Mat food_like = evidence.above | evidence.colour;
  const cv::Rect food = cv::boundingRect(food_like);
  if (food.empty()) return cv::Rect();
  const int margin = FoodMargin(options);
  return (food - cv::Point(margin, margin) + cv::Size(2 * margin, 2 * margin)) &
         cv::Rect(0, 0, food_like.cols, food_like.rows);
}

FoodEvidence CropEvidence(const FoodEvidence& evidence, const cv::Rect& box) {
  FoodEvidence crop;
  crop.lab = evidence.lab(box);
  crop.above = evidence.above(box);
  crop.colour = evidence.colour(box);
  if (!evidence.bare.empty()) crop.bare = evidence.bare(box);
  crop.plate_lab = evidence.plate_lab;
  return crop;
}

namespace {

// Dilation (max) or erosion (min) by `element`: per row of the element a
// horizontal running max (min) over its run, combined over the rows. Runs
// centred on the anchor (an ellipse's, a rectangle's) are built up one
// half-width at a time from the narrower ones; others take a pass each.
template <bool kMax>
cv::Mat MorphByRows(const cv::Mat& image, const cv::Mat& element) {
  const int rows = element.rows;
  const cv::Point anchor(element.cols / 2, rows / 2);
  const int w = image.cols, h = image.rows;
  const float none = kMax ? -std::numeric_limits<float>::max()
                          : std::numeric_limits<float>::max();
  // Row-wise max (min) into `out`: loops the compiler vectorizes.
  auto pick = [](float* __restrict out, const float* __restrict in, int n) {
    for (int u = 0; u < n; ++u) {
      if constexpr (kMax) {
        out[u] = std::max(out[u], in[u]);
      } else {
        out[u] = std::min(out[u], in[u]);
      }
    }
  };
  struct Run {
    int first = -1;
    int last = -1;
  };
  std::vector<Run> runs(rows);
  bool centred = true;
  int widest = 0;
  for (int i = 0; i < rows; ++i) {
    const auto* e = element.ptr<uint8_t>(i);
    for (int j = 0; j < element.cols; ++j) {
      if (!e[j]) continue;
      if (runs[i].first < 0) runs[i].first = j;
      runs[i].last = j;
    }
    if (runs[i].first < 0) continue;
    CV_Assert(cv::countNonZero(element.row(i)) ==
              runs[i].last - runs[i].first + 1);
    centred &= anchor.x - runs[i].first == runs[i].last - anchor.x;
    widest = std::max(widest, anchor.x - runs[i].first);
  }
  cv::Mat out(image.size(), CV_32FC1, cv::Scalar(none));
  // Output row v takes row v + dy of a horizontal pass.
  auto combine = [&](const cv::Mat& pass, int dy) {
    for (int v = std::max(0, -dy); v < std::min(h, h - dy); ++v) {
      pick(out.ptr<float>(v), pass.ptr<float>(v + dy), w);
    }
  };
  if (centred) {
    // Strips of output rows, so that the passes over the input rows a strip
    // needs stay in the cache.
    constexpr int kStrip = 64;
    for (int v0 = 0; v0 < h; v0 += kStrip) {
      const int v1 = std::min(h, v0 + kStrip);
      const int a0 = std::max(0, v0 - anchor.y);
      const int a1 = std::min(h, v1 + rows - 1 - anchor.y);
      const cv::Mat source = image.rowRange(a0, a1);
      cv::Mat pass = source.clone();  // the running max over [u - r, u + r]
      for (int r = 0; r <= widest; ++r) {
        if (r > 0 && r < w) {
          for (int v = 0; v < a1 - a0; ++v) {
            float* p = pass.ptr<float>(v);
            const float* in = source.ptr<float>(v);
            pick(p + r, in, w - r);
            pick(p, in + r, w - r);
          }
        }
        for (int i = 0; i < rows; ++i) {
          if (runs[i].first < 0 || anchor.x - runs[i].first != r) continue;
          // Output row v takes pass row v + dy (input rows outside the
          // image count for nothing).
          const int dy = i - anchor.y;
          const int lo = std::max(v0, a0 - dy);
          const int hi = std::min(v1, a1 - dy);
          if (hi <= lo) continue;
          for (int v = lo; v < hi; ++v) {
            pick(out.ptr<float>(v), pass.ptr<float>(v + dy - a0), w);
          }
        }
      }
    }
    return out;
  }
  for (int i = 0; i < rows; ++i) {
    if (runs[i].first < 0) continue;
    const cv::Mat line =
        cv::Mat::ones(1, runs[i].last - runs[i].first + 1, CV_8UC1);
    const cv::Point line_anchor(anchor.x - runs[i].first, 0);
    cv::Mat pass;
    if constexpr (kMax) {
      cv::dilate(image, pass, line, line_anchor);
    } else {
      cv::erode(image, pass, line, line_anchor);
    }
    combine(pass, i - anchor.y);
  }
  return out;
}

}  // namespace

cv::Mat CloseByRows(const cv::Mat& image, const cv::Mat& element) {
  CV_Assert(image.type() == CV_32FC1 && element.type() == CV_8UC1);
  return MorphByRows<false>(MorphByRows<true>(image, element), element);
}

std::optional<Regions> PlantSeeds(const FoodEvidence& evidence,
                                  const cv::Mat& height_mm,
                                  const FoodDetectorOptions& options) {
  const int w = height_mm.cols, h = height_mm.rows;
  const cv::Mat& lab = evidence.lab;
  const cv::Mat& above = evidence.above;
  // Seeds: the upper part of every bump in the height map, cut along strong
  // colour edges. Touching items meet low down, where their rounded sides
  // touch, so keeping only what is at least half as high as the highest
  // point nearby leaves one seed per item, whatever the items' colours; the
  // colour edges split items whose sides touch high up. An item cut into
  // several seeds is merged again below.
  cv::Mat smooth, gx, gy;
  cv::GaussianBlur(lab, smooth, {3, 3}, 0);
  cv::Sobel(smooth, gx, CV_32F, 1, 0, 3, 1.0 / 8);
  cv::Sobel(smooth, gy, CV_32F, 0, 1, 3, 1.0 / 8);
  cv::Mat local_top;
  cv::dilate(height_mm, local_top,
             cv::getStructuringElement(cv::MORPH_RECT, {21, 21}));
  // Height valleys: how far a closing (which bridges a seam narrower than
  // its element) lifts each pixel. Two rounded items side by side meet in
  // a valley as deep as their curvature makes it (two cylinders: half
  // their height); the top of one item is not lifted at all.
  Regions regions;
  cv::Mat& valley = regions.valley_mm;
  valley = CloseByRows(
      height_mm,
      cv::getStructuringElement(cv::MORPH_ELLIPSE, {options.valley_width_px,
                                                    options.valley_width_px}));
  valley -= height_mm;
  cv::Mat cores(h, w, CV_8UC1, cv::Scalar(0));
  cv::Mat seams(h, w, CV_8UC1, cv::Scalar(0));
  const float min_valley = static_cast<float>(options.min_valley_mm);
  const float valley_fraction = static_cast<float>(options.valley_fraction);
  // Height steps (cliffs): an item lying partly on another stands on it, so
  // the lower one's visible part meets the upper one at a step, not in a
  // valley. A pixel whose neighbourhood (cliff_window_px) rises more than
  // max(min_cliff_mm, cliff_fraction x its own height) above it is at such
  // a step; like a valley, it cuts a seed only where that splits it.
  cv::Mat cliff_top;
  const bool cut_cliffs = options.cliff_window_px > 1;
  if (cut_cliffs) {
    cv::dilate(
        height_mm, cliff_top,
        cv::getStructuringElement(cv::MORPH_RECT, {options.cliff_window_px,
                                                   options.cliff_window_px}));
  }
  const float min_cliff = static_cast<float>(options.min_cliff_mm);
  const float cliff_fraction = static_cast<float>(options.cliff_fraction);
  // Strong colour edges (the gradient of one pixel), which no seed or
  // terrace crosses.
  cv::Mat strong_edge(h, w, CV_8UC1, cv::Scalar(0));
  {
    const float edge2 = static_cast<float>(options.min_edge_strength *
                                           options.min_edge_strength);
    for (int v = 0; v < h; ++v) {
      const auto* a = gx.ptr<cv::Vec3f>(v);
      const auto* b = gy.ptr<cv::Vec3f>(v);
      auto* out = strong_edge.ptr<uint8_t>(v);
      for (int u = 0; u < w; ++u) {
        if (a[u].dot(a[u]) + b[u].dot(b[u]) > edge2) out[u] = 255;
      }
    }
  }
  // Soft colour edges: colours more than min_soft_edge_distance apart
  // 4 px apart (a pale slice on a pale stick, whose shaded edge spreads
  // the change over a few pixels, below min_edge_strength per pixel).
  cv::Mat wide_edge(h, w, CV_8UC1, cv::Scalar(0));
  if (options.min_soft_edge_distance > 0) {
    const float wide2 = static_cast<float>(options.min_soft_edge_distance *
                                           options.min_soft_edge_distance);
    for (int v = 2; v + 2 < h; ++v) {
      const auto* row = smooth.ptr<cv::Vec3f>(v);
      const auto* up = smooth.ptr<cv::Vec3f>(v - 2);
      const auto* down = smooth.ptr<cv::Vec3f>(v + 2);
      auto* out = wide_edge.ptr<uint8_t>(v);
      for (int u = 2; u + 2 < w; ++u) {
        const cv::Vec3f dx = row[u + 2] - row[u - 2];
        const cv::Vec3f dy = down[u] - up[u];
        if (dx.dot(dx) > wide2 || dy.dot(dy) > wide2) out[u] = 255;
      }
    }
  }
  for (int v = 0; v < h; ++v) {
    const auto* edge = strong_edge.ptr<uint8_t>(v);
    const auto* in = above.ptr<uint8_t>(v);
    const auto* hv = height_mm.ptr<float>(v);
    const auto* top = local_top.ptr<float>(v);
    const auto* dip = valley.ptr<float>(v);
    const auto* soft = wide_edge.ptr<uint8_t>(v);
    auto* out = cores.ptr<uint8_t>(v);
    auto* seam = seams.ptr<uint8_t>(v);
    for (int u = 0; u < w; ++u) {
      if (in[u] && hv[u] >= 0.5f * top[u] && !edge[u]) {
        out[u] = 255;
        seam[u] =
            soft[u] ||
            dip[u] > std::max(min_valley, valley_fraction * top[u]) ||
            (cut_cliffs && cliff_top.at<float>(v, u) - hv[u] >
                               std::max(min_cliff, cliff_fraction * hv[u]));
      }
    }
  }
  const cv::Mat open3 = cv::getStructuringElement(cv::MORPH_ELLIPSE, {3, 3});
  cv::morphologyEx(cores, cores, cv::MORPH_OPEN, open3);
  // Cut the cores along the valleys, but only where that splits one core
  // into two or more substantial parts (items that touch). Elsewhere the
  // core stays whole: a small, low item next to a tall one is a valley in
  // height too, and cutting its seed would hand it to the neighbour.
  {
    cv::Mat whole;
    const int n_whole = cv::connectedComponents(cores, whole, 4, CV_32S);
    cv::Mat cut = cores & (seams == 0);
    cv::morphologyEx(cut, cut, cv::MORPH_OPEN, open3);
    cv::Mat parts, part_stats, part_centroids;
    const int n_parts = cv::connectedComponentsWithStats(
        cut, parts, part_stats, part_centroids, 4, CV_32S);
    // Substantial parts per original core.
    std::vector<int> split(n_whole, 0);
    std::vector<int> part_owner(n_parts, 0);
    for (int v = 0; v < h; ++v) {
      const auto* label = whole.ptr<int>(v);
      const auto* part = parts.ptr<int>(v);
      for (int u = 0; u < w; ++u) {
        if (part[u] > 0) part_owner[part[u]] = label[u];
      }
    }
    for (int p = 1; p < n_parts; ++p) {
      if (part_stats.at<int>(p, cv::CC_STAT_AREA) >= options.min_seed_px) {
        ++split[part_owner[p]];
      }
    }
    for (int v = 0; v < h; ++v) {
      const auto* label = whole.ptr<int>(v);
      const auto* core = cores.ptr<uint8_t>(v);
      auto* kept = cut.ptr<uint8_t>(v);
      for (int u = 0; u < w; ++u) {
        if (core[u] && split[label[u]] < 2) kept[u] = 255;
      }
    }
    cores = cut;
  }
  // Terraces: the visible part of an item partly under another is about
  // half as high as the item on it, so the half-height rule over 21 px
  // gives it no seed and the watershed would hand it to the item on top.
  // Over a window too small to reach the upper item's top it is a bump of
  // its own. The flanks of every item pass that test too, but they are thin
  // rings around a seed, which the distance from the seeds and the opening
  // take out.
  cv::Mat terraces;
  if (options.terrace_window_px > 0 && options.min_terrace_px > 0) {
    cv::Mat near_top;
    cv::dilate(
        height_mm, near_top,
        cv::getStructuringElement(cv::MORPH_RECT, {options.terrace_window_px,
                                                   options.terrace_window_px}));
    cv::Mat near_cores;
    cv::dilate(cores, near_cores,
               cv::getStructuringElement(cv::MORPH_ELLIPSE, {5, 5}));
    terraces = cv::Mat(h, w, CV_8UC1, cv::Scalar(0));
    for (int v = 0; v < h; ++v) {
      const auto* edge = strong_edge.ptr<uint8_t>(v);
      const auto* in = above.ptr<uint8_t>(v);
      const auto* hv = height_mm.ptr<float>(v);
      const auto* top = local_top.ptr<float>(v);
      const auto* near = near_top.ptr<float>(v);
      const auto* taken = near_cores.ptr<uint8_t>(v);
      auto* out = terraces.ptr<uint8_t>(v);
      for (int u = 0; u < w; ++u) {
        if (in[u] && !taken[u] && hv[u] < 0.5f * top[u] &&
            hv[u] >= 0.5f * near[u] && !edge[u]) {
          out[u] = 255;
        }
      }
    }
    cv::morphologyEx(terraces, terraces, cv::MORPH_OPEN,
                     cv::getStructuringElement(
                         cv::MORPH_ELLIPSE,
                         {options.terrace_open_px, options.terrace_open_px}));
  }
  const int n_cores =
      cv::connectedComponents(cores, regions.markers, 4, CV_32S);
  int n_seeds = n_cores;
  if (!terraces.empty()) {
    cv::Mat steps, step_stats, step_centroids;
    const int n_steps = cv::connectedComponentsWithStats(
        terraces, steps, step_stats, step_centroids, 4, CV_32S);
    std::vector<int> step_label(n_steps, 0);
    for (int s = 1; s < n_steps; ++s) {
      if (step_stats.at<int>(s, cv::CC_STAT_AREA) >= options.min_terrace_px) {
        step_label[s] = n_seeds++;
      }
    }
    for (int v = 0; v < h; ++v) {
      const auto* step = steps.ptr<int>(v);
      auto* m = regions.markers.ptr<int>(v);
      for (int u = 0; u < w; ++u) {
        if (step[u] > 0 && step_label[step[u]] > 0) m[u] = step_label[step[u]];
      }
    }
  }
  if (n_seeds <= 1) return std::nullopt;
  regions.background = n_seeds;
  return regions;
}

void GrowRegions(const cv::Mat& rgb, const FoodEvidence& evidence,
                 const cv::Mat& plate, Regions& regions) {
  // Background seed: plate well away from anything food-like, bare plate
  // however close to food, and all that is off the plate.
  cv::Mat& markers = regions.markers;
  const int background = regions.background;
  cv::Mat food_like = evidence.above | evidence.colour;
  cv::Mat near_food;
  cv::dilate(food_like, near_food,
             cv::getStructuringElement(cv::MORPH_ELLIPSE, {15, 15}));
  markers.setTo(background, ~near_food | ~plate);
  // Near food, the flood would otherwise take bare plate for whichever item
  // reaches it first: a pale item's edge against a neighbour's shadow is a
  // weaker colour edge than the shadow's own, so the item ran along it.
  if (!evidence.bare.empty()) {
    markers.setTo(background, evidence.bare & (markers == 0));
  }
  // The outlines come from colour edges: flooding the RGB image from the
  // seeds stops where item meets plate or item meets item.
  cv::Mat rgb_copy = rgb.clone();  // watershed wants continuous data
  cv::watershed(rgb_copy, markers);
}

namespace {

// How far two colours (CIELAB) are from being one surface in other light:
// more or less light on a surface scales X, Y and Z by one factor, so (L +
// 16, a, b), made of their cube roots, by one factor too (while none of X,
// Y, Z falls below 0.8856 % of white, where CIELAB's cube root becomes a
// line). The distance in (a, b) once one is scaled to the other's
// lightness, the larger of the two ways: scaled down, a colour's chroma
// shrinks, so one way alone would take a dark enough grey for a pale,
// nearly grey colour in shade.
double DistanceInOtherLight(const cv::Vec3d& a, const cv::Vec3d& b) {
  const auto one_way = [](const cv::Vec3d& from, const cv::Vec3d& to) {
    const double scale = (to[0] + 16.0) / (from[0] + 16.0);
    return std::hypot(to[1] - scale * from[1], to[2] - scale * from[2]);
  };
  return std::max(one_way(a, b), one_way(b, a));
}

// Whether one of two mean colours (CIELAB) is a highlight on a surface of
// the other (FoodDetectorOptions::max_highlight_hue_deg).
bool IsHighlightOn(const cv::Vec3d& a, const cv::Vec3d& b,
                   const cv::Vec3f& plate, const FoodDetectorOptions& options) {
  if (options.max_highlight_hue_deg <= 0.0) return false;
  constexpr double kMinHueChroma = 8.0;
  const cv::Vec3d& light = a[0] >= b[0] ? a : b;
  const cv::Vec3d& dark = a[0] >= b[0] ? b : a;
  const double light_chroma = std::hypot(light[1], light[2]);
  const double dark_chroma = std::hypot(dark[1], dark[2]);
  if (std::min(light_chroma, dark_chroma) < kMinHueChroma ||
      light_chroma > options.max_highlight_chroma_share * dark_chroma ||
      light[0] < plate[0] - options.max_highlight_below_plate_l) {
    return false;
  }
  double hue_deg =
      std::abs(std::atan2(light[2], light[1]) - std::atan2(dark[2], dark[1])) *
      180.0 / kPi;
  if (hue_deg > 180.0) hue_deg = 360.0 - hue_deg;
  return hue_deg <= options.max_highlight_hue_deg;
}

// The share of the pixels of `markers` inside the rotated rectangle `rect`
// whose label `covered(label)` accepts.
template <typename Covered>
double ShareOfRect(const cv::Mat& markers, const cv::RotatedRect& rect,
                   Covered covered) {
  const cv::Rect around =
      rect.boundingRect() & cv::Rect(0, 0, markers.cols, markers.rows);
  const double c = std::cos(rect.angle * kPi / 180);
  const double s = std::sin(rect.angle * kPi / 180);
  int inside = 0, hits = 0;
  for (int v = around.y; v < around.br().y; ++v) {
    const auto* m = markers.ptr<int>(v);
    for (int u = around.x; u < around.br().x; ++u) {
      const double x = u - rect.center.x, y = v - rect.center.y;
      if (std::abs(x * c + y * s) > rect.size.width / 2 + 0.5 ||
          std::abs(y * c - x * s) > rect.size.height / 2 + 0.5) {
        continue;
      }
      ++inside;
      hits += covered(m[u]);
    }
  }
  return inside > 0 ? static_cast<double>(hits) / inside : 0.0;
}

// A rotated rectangle's long side over its short side.
double Elongation(const cv::RotatedRect& rect) {
  return std::max(rect.size.width, rect.size.height) /
         std::max(1.0f, std::min(rect.size.width, rect.size.height));
}

}  // namespace

void MergeSplitItems(const FoodEvidence& evidence, const cv::Mat& height_mm,
                     const cv::Mat& valid, const FoodDetectorOptions& options,
                     Regions& regions) {
  const int w = height_mm.cols, h = height_mm.rows;
  const cv::Mat& lab = evidence.lab;
  cv::Mat& markers = regions.markers;
  const cv::Mat& valley = regions.valley_mm;
  const int background = regions.background;
  const int n_cores = background;
  // Merge neighbours that are one item cut in two: similar colour and no
  // valley in height along the boundary between them (touching items meet
  // low down, where their rounded sides touch).
  std::vector<cv::Vec3d> lab_sum(n_cores, cv::Vec3d(0, 0, 0));
  std::vector<int> lab_count(n_cores, 0);
  std::vector<std::vector<double>> heights(n_cores);
  for (int v = 0; v < h; ++v) {
    const auto* m = markers.ptr<int>(v);
    const auto* px = lab.ptr<cv::Vec3f>(v);
    const auto* hv = height_mm.ptr<float>(v);
    const auto* ok = valid.ptr<uint8_t>(v);
    for (int u = 0; u < w; ++u) {
      if (m[u] <= 0 || m[u] >= background) continue;
      lab_sum[m[u]] += cv::Vec3d(px[u][0], px[u][1], px[u][2]);
      ++lab_count[m[u]];
      if (ok[u]) heights[m[u]].push_back(hv[u]);
    }
  }
  // Per region: its top (the 90th percentile of its heights) and its
  // median height.
  std::vector<double> top_mm(n_cores, 0.0), median_mm(n_cores, 0.0);
  for (int i = 1; i < background; ++i) {
    std::vector<double>& hs = heights[i];
    if (hs.empty()) continue;
    const size_t q = hs.size() * 9 / 10;
    std::nth_element(hs.begin(), hs.begin() + q, hs.end());
    top_mm[i] = hs[q];
    const size_t half = hs.size() / 2;
    std::nth_element(hs.begin(), hs.begin() + half, hs.begin() + q);
    median_mm[i] = hs[half];
  }
  // Boundary statistics per pair of neighbouring regions.
  struct Seam {
    double height_sum = 0.0;
    double dip_sum = 0.0;
    int count = 0;      // with valid depth
    int all_count = 0;  // every ridge pixel between the two
    // Sums of those pixels' coordinates, their squares and products: the
    // seam's direction, for its length in the short-contact test below.
    double u_sum = 0.0, v_sum = 0.0, uu_sum = 0.0, vv_sum = 0.0, uv_sum = 0.0;
    double l_sum = 0.0;  // CIELAB L over all_count
    // The lift on the seam and valley_flank_px to either side of it, over
    // the seam pixels whose two flanks lie in the two regions.
    double seam_lift_sum = 0.0, flank_lift_sum = 0.0;
    int flank_count = 0;
    // The height on the seam and the mean height of its two flanks, over
    // the seam pixels whose two flanks lie in the two regions and where
    // all three have depth.
    double seam_height_sum = 0.0, flank_height_sum = 0.0;
    int flank_height_count = 0;
  };
  std::map<std::pair<int, int>, Seam> boundary;
  // The seam pixel (u, v) between regions a and b: its lift, and the mean
  // lift valley_flank_px away on either side, across the seam (from b's
  // neighbours of the pixel towards a's), when those two points lie in a
  // and in b.
  const int flank = options.valley_flank_px;
  const auto add_flank_lift = [&](int u, int v, int a, int b, Seam& seam) {
    if (options.min_valley_flank_share <= 0.0 &&
        options.min_seam_flank_height_share <= 0.0) {
      return;
    }
    int du = 0, dv = 0;
    for (const auto& [ou, ov] : {std::pair{-1, 0}, {1, 0}, {0, -1}, {0, 1}}) {
      const int n = markers.at<int>(v + ov, u + ou);
      const int sign = n == a ? 1 : n == b ? -1 : 0;
      du += sign * ou;
      dv += sign * ov;
    }
    const double norm = std::hypot(du, dv);
    if (norm == 0.0) return;
    const int u1 = cvRound(u + flank * du / norm);
    const int v1 = cvRound(v + flank * dv / norm);
    const int u2 = cvRound(u - flank * du / norm);
    const int v2 = cvRound(v - flank * dv / norm);
    const cv::Rect image(0, 0, w, h);
    if (!image.contains({u1, v1}) || !image.contains({u2, v2})) return;
    if (markers.at<int>(v1, u1) != a || markers.at<int>(v2, u2) != b) return;
    seam.seam_lift_sum += valley.at<float>(v, u);
    seam.flank_lift_sum +=
        0.5 * (valley.at<float>(v1, u1) + valley.at<float>(v2, u2));
    ++seam.flank_count;
    if (valid.at<uint8_t>(v, u) && valid.at<uint8_t>(v1, u1) &&
        valid.at<uint8_t>(v2, u2)) {
      seam.seam_height_sum += height_mm.at<float>(v, u);
      seam.flank_height_sum +=
          0.5 * (height_mm.at<float>(v1, u1) + height_mm.at<float>(v2, u2));
      ++seam.flank_height_count;
    }
  };
  // Per region: the ridge pixels beside it, and those of them that also
  // border the background.
  std::vector<int> ridge_beside(n_cores, 0), open_beside(n_cores, 0);
  for (int v = 1; v + 1 < h; ++v) {
    const auto* m = markers.ptr<int>(v);
    const auto* hv = height_mm.ptr<float>(v);
    const auto* ok = valid.ptr<uint8_t>(v);
    const auto* dip = valley.ptr<float>(v);
    const auto* px = lab.ptr<cv::Vec3f>(v);
    for (int u = 1; u + 1 < w; ++u) {
      if (m[u] != -1) continue;
      int found[4];
      int n_found = 0;
      bool open = false;
      for (const int n : {m[u - 1], m[u + 1], markers.at<int>(v - 1, u),
                          markers.at<int>(v + 1, u)}) {
        open |= n == background;
        if (n > 0 && n < background &&
            std::find(found, found + n_found, n) == found + n_found) {
          found[n_found++] = n;
        }
      }
      for (int a = 0; a < n_found; ++a) {
        ++ridge_beside[found[a]];
        open_beside[found[a]] += open;
      }
      for (int a = 0; a < n_found; ++a) {
        for (int b = a + 1; b < n_found; ++b) {
          auto& entry = boundary[std::minmax(found[a], found[b])];
          ++entry.all_count;
          entry.u_sum += u;
          entry.v_sum += v;
          entry.uu_sum += static_cast<double>(u) * u;
          entry.vv_sum += static_cast<double>(v) * v;
          entry.uv_sum += static_cast<double>(u) * v;
          entry.l_sum += px[u][0];
          add_flank_lift(u, v, found[a], found[b], entry);
          if (ok[u]) {
            entry.height_sum += hv[u];
            entry.dip_sum += dip[u];
            ++entry.count;
          }
        }
      }
    }
  }
  // Each region's longest seam with another region.
  std::vector<int> longest_seam(n_cores, 0);
  for (const auto& [pair, seam] : boundary) {
    longest_seam[pair.first] =
        std::max(longest_seam[pair.first], seam.all_count);
    longest_seam[pair.second] =
        std::max(longest_seam[pair.second], seam.all_count);
  }
  std::vector<int> parent(n_cores);
  for (int i = 0; i < n_cores; ++i) parent[i] = i;
  auto root = [&](int i) {
    while (parent[i] != i) i = parent[i] = parent[parent[i]];
    return i;
  };
  // Per region: its neighbours across a seam with no shaded crease, no dip
  // by the closing's lift and neither standing on the other, with that
  // seam's length (the band test below).
  std::vector<std::vector<std::pair<int, int>>> flush_with(n_cores);
  // The pairs the merge keeps apart by their seam: a shaded crease, one
  // standing on the other, or a valley along the seam.
  std::set<std::pair<int, int>> kept_apart;
  const auto colour_of = [&](int r) { return lab_sum[r] / lab_count[r]; };
  // A shaded crease: lightness `l` more than min_crease_shade_l below the
  // darker of two regions' colours.
  const auto shaded = [&](double l, const cv::Vec3d& x, const cv::Vec3d& y) {
    return options.min_crease_shade_l > 0.0 &&
           l < std::min(x[0], y[0]) - options.min_crease_shade_l;
  };
  // Whether a region borders the background little: it lies inside food.
  const auto enclosed_by_food = [&](int r) {
    return open_beside[r] <=
           (1.0 - options.min_enclosed_share) * ridge_beside[r];
  };
  // No dip by the closing's lift along a seam.
  const auto flat_seam = [&](const Seam& seam, double lower_top) {
    return seam.dip_sum / seam.count <=
           std::max(options.min_valley_mm, options.valley_fraction * lower_top);
  };
  // Per region: a larger neighbour of similar colour, open to the
  // background, across a seam with no dip (the item it is part of).
  std::vector<bool> has_kin(n_cores, false);
  if (options.enclosed_kin) {
    for (const auto& [pair, seam] : boundary) {
      const auto [a, b] = pair;
      if (seam.count < 3 || lab_count[a] == 0 || lab_count[b] == 0 ||
          !flat_seam(seam, std::min(top_mm[a], top_mm[b])) ||
          cv::norm(colour_of(a) - colour_of(b)) >=
              options.min_colour_distance) {
        continue;
      }
      if (!enclosed_by_food(b) && lab_count[b] > lab_count[a]) {
        has_kin[a] = true;
      }
      if (!enclosed_by_food(a) && lab_count[a] > lab_count[b]) {
        has_kin[b] = true;
      }
    }
  }
  for (const auto& [pair, seam] : boundary) {
    const auto [a, b] = pair;
    if (seam.count < 3 || lab_count[a] == 0 || lab_count[b] == 0) continue;
    const cv::Vec3d colour_a = colour_of(a);
    const cv::Vec3d colour_b = colour_of(b);
    const cv::Vec3d diff = colour_a - colour_b;
    // A crease between two bodies is shaded: no merge across it, whatever
    // their colour and height (FoodDetectorOptions::min_crease_shade_l).
    if (shaded(seam.l_sum / seam.all_count, colour_a, colour_b)) {
      kept_apart.insert(pair);
      continue;
    }
    const double seam_mm = seam.height_sum / seam.count;
    const double lower_top = std::min(top_mm[a], top_mm[b]);
    // One item lying on the other: the upper one's top stands well above
    // the lower one's (a terrace and the slice on it), not one item cut in
    // two, whose parts are seeded at about the same height.
    if (std::max(top_mm[a], top_mm[b]) >
        options.max_merge_top_ratio * lower_top) {
      kept_apart.insert(pair);
      continue;
    }
    // No valley between them, by the closing's lift and by height.
    const bool no_dip = flat_seam(seam, lower_top);
    // Or the seam is as high as the two regions beside it: it runs across
    // one item's profile (a celery stick cut crosswise: its floor is low
    // on the seam and beside it alike). Written for touching items meeting
    // lower down than their flanks; on the blind plates they mostly do not
    // (docs/perception.md, "A seam across a stick's profile"), so colour
    // keeps those apart. no_valley serves the inside rule below as well.
    const bool as_high_as_flanks =
        options.min_seam_flank_height_share > 0.0 &&
        seam.flank_height_count >= 3 &&
        seam.seam_height_sum >=
            options.min_seam_flank_height_share * seam.flank_height_sum;
    const bool no_valley =
        (seam_mm > 0.8 * lower_top || as_high_as_flanks) && no_dip;
    // Or the dip is a valley running across the seam, lifted nearly as much
    // beside it as on it (a celery stick's channel, cut crosswise); then
    // neither the dip nor the seam's height keeps the two apart.
    const bool valley_across =
        options.min_valley_flank_share > 0.0 && !no_dip &&
        seam.flank_count >= 3 &&
        seam.flank_lift_sum >=
            options.min_valley_flank_share * seam.seam_lift_sum;
    // Or one lies inside food, hardly touching the background, and this is
    // its longest seam: a part of the item of another colour (a kiwi's core
    // or its ring of seeds), not an item of its own, unless it has kin.
    const int seam_px = seam.all_count;  // (a lambda may not capture `seam`)
    const auto inside = [&](int r) {
      return enclosed_by_food(r) && seam_px == longest_seam[r] && !has_kin[r];
    };
    // A part of an item lies about as high as the item; a small region at
    // the foot of an item standing on another is lower by that item's
    // height (FoodDetectorOptions::max_enclosed_median_ratio).
    const bool level = options.max_enclosed_median_ratio <= 0.0 ||
                       std::max(median_mm[a], median_mm[b]) <=
                           options.max_enclosed_median_ratio *
                               std::min(median_mm[a], median_mm[b]);
    const bool enclosed = inside(a) || inside(b);
    if (!no_dip && !valley_across) kept_apart.insert(pair);
    if (no_dip) {
      flush_with[a].emplace_back(b, seam_px);
      flush_with[b].emplace_back(a, seam_px);
    }
    // Two bodies touching at a short contact, not one item cut across
    // (FoodDetectorOptions::min_contact_seam_share): not merged here. The
    // watershed draws a seam one pixel per step along its main axis, so a
    // seam at 45 degrees has 1/sqrt(2) as many pixels as it is long; its
    // length is its pixel count over the larger of |cos| and |sin| of its
    // direction (from the second moments of its pixels).
    const int smaller_px = std::min(lab_count[a], lab_count[b]);
    double seam_length = seam_px;
    if (seam_px >= 2) {
      const double n = seam_px;
      const double mu = seam.u_sum / n, mv = seam.v_sum / n;
      const double cuu = seam.uu_sum / n - mu * mu;
      const double cvv = seam.vv_sum / n - mv * mv;
      const double cuv = seam.uv_sum / n - mu * mv;
      const double angle = 0.5 * std::atan2(2.0 * cuv, cuu - cvv);
      seam_length /=
          std::max(std::fabs(std::cos(angle)), std::fabs(std::sin(angle)));
    }
    const bool contact =
        options.min_contact_seam_share > 0.0 &&
        smaller_px >= options.min_contact_part_px &&
        seam_length < options.min_contact_seam_share * std::sqrt(smaller_px);
    if (!contact && (((no_valley || valley_across) &&
                      cv::norm(diff) < options.min_colour_distance) ||
                     (no_valley && enclosed && level) ||
                     (no_dip && IsHighlightOn(colour_a, colour_b,
                                              evidence.plate_lab, options)))) {
      parent[root(a)] = root(b);
    }
  }
  // A band of another colour across an item (a halved strawberry's pale
  // core between two strips of its flesh) reaches the item's outline at
  // both ends, so it is not inside food; it is joined with the two parts
  // either side when they are of similar colour, neither seam has a dip,
  // a crease or a step, and the two seams are at least min_sandwich_share
  // of the ridge beside the band. A band smaller than a seed is a sliver
  // of the watershed between two items, not a part of one; a band darker
  // than both parts is the shaded crease between two touching items; and
  // two parts that touch across a seam the merge keeps apart (a crease, a
  // step or a dip; a short contact does not count here) are two items
  // whatever lies between them elsewhere.
  if (options.min_sandwich_share > 0.0) {
    for (int c = 1; c < background; ++c) {
      if (lab_count[c] < options.min_seed_px) continue;
      const auto& near = flush_with[c];
      for (size_t i = 0; i < near.size(); ++i) {
        for (size_t j = i + 1; j < near.size(); ++j) {
          const auto [a, seam_a] = near[i];
          const auto [b, seam_b] = near[j];
          if (!shaded(colour_of(c)[0], colour_of(a), colour_of(b)) &&
              kept_apart.count(std::pair<int, int>(std::minmax(a, b))) == 0 &&
              seam_a + seam_b >= options.min_sandwich_share * ridge_beside[c] &&
              cv::norm(colour_of(a) - colour_of(b)) <
                  options.min_colour_distance) {
            parent[root(a)] = root(c);
            parent[root(b)] = root(c);
          }
        }
      }
    }
  }
  // A stick with another item lying across it shows as two parts, one on
  // each side of the item on it; the watershed gives them two labels and
  // neither covers the stick. Two parts (each the regions the merge above
  // made one, since a short stub is often seeded in pieces) are joined
  // when: an item lying on them (its top more than max_merge_top_ratio
  // times theirs) borders both; they are of similar colour and height; the
  // straight line between their centroids runs over them and the item on
  // them only (the stick goes on underneath); they and the item on them
  // fill at least min_join_fill of the smallest rectangle around the two
  // parts (one stick is a rectangle; a round slice and a stick beside it
  // leave plate in it); and one part is not round (two whole slices either
  // side of a tall item fill such a rectangle too).
  if (options.min_join_fill <= 1.0) {
    std::vector<int> group(n_cores);
    for (int i = 0; i < n_cores; ++i) group[i] = root(i);
    // Per part: colour, heights, moments and box.
    struct Part {
      cv::Vec3d lab_sum = cv::Vec3d(0, 0, 0);
      std::vector<double> heights;
      cv::Vec6d moments = cv::Vec6d::all(0);
      int u0 = std::numeric_limits<int>::max(), v0 = u0, u1 = -1, v1 = -1;
      double top_mm = 0, u = 0, v = 0, elongation = 1;
    };
    std::vector<Part> part(n_cores);
    for (int v = 0; v < h; ++v) {
      const auto* m = markers.ptr<int>(v);
      const auto* px = lab.ptr<cv::Vec3f>(v);
      const auto* hv = height_mm.ptr<float>(v);
      const auto* ok = valid.ptr<uint8_t>(v);
      for (int u = 0; u < w; ++u) {
        if (m[u] <= 0 || m[u] >= background) continue;
        Part& p = part[group[m[u]]];
        p.lab_sum += cv::Vec3d(px[u][0], px[u][1], px[u][2]);
        if (ok[u]) p.heights.push_back(hv[u]);
        p.moments +=
            cv::Vec6d(1, u, v, double(u) * u, double(v) * v, double(u) * v);
        p.u0 = std::min(p.u0, u);
        p.u1 = std::max(p.u1, u);
        p.v0 = std::min(p.v0, v);
        p.v1 = std::max(p.v1, v);
      }
    }
    for (int i = 1; i < n_cores; ++i) {
      Part& p = part[i];
      const cv::Vec6d& mo = p.moments;
      if (mo[0] < 1) continue;
      if (!p.heights.empty()) {
        const size_t q =
            std::min(p.heights.size() - 1,
                     static_cast<size_t>(static_cast<double>(p.heights.size()) *
                                         options.join_top_quantile));
        std::nth_element(p.heights.begin(), p.heights.begin() + q,
                         p.heights.end());
        p.top_mm = p.heights[q];
      }
      p.u = mo[1] / mo[0];
      p.v = mo[2] / mo[0];
      const double cuu = mo[3] / mo[0] - p.u * p.u;
      const double cvv = mo[4] / mo[0] - p.v * p.v;
      const double cuv = mo[5] / mo[0] - p.u * p.v;
      const double mean = (cuu + cvv) / 2;
      const double spread =
          std::sqrt((cuu - cvv) * (cuu - cvv) / 4 + cuv * cuv);
      p.elongation = std::sqrt((mean + spread) / std::max(mean - spread, 1e-6));
    }
    std::vector<std::vector<int>> neighbours(n_cores);
    for (const auto& [pair, seam] : boundary) {
      const int a = group[pair.first], b = group[pair.second];
      if (seam.count < 3 || a == b ||
          std::find(neighbours[a].begin(), neighbours[a].end(), b) !=
              neighbours[a].end()) {
        continue;
      }
      neighbours[a].push_back(b);
      neighbours[b].push_back(a);
    }
    auto in = [&](int label, int a, int b, int o) {
      if (label <= 0 || label >= background) return false;
      const int g = group[label];
      return g == a || g == b || g == o;
    };
    // The share of the smallest rectangle around parts a and b that a, b,
    // the item o on them and the watershed's ridges cover.
    auto fill = [&](int a, int b, int o) {
      std::vector<cv::Point> points;
      const cv::Rect box =
          cv::Rect(cv::Point(std::min(part[a].u0, part[b].u0),
                             std::min(part[a].v0, part[b].v0)),
                   cv::Point(std::max(part[a].u1, part[b].u1) + 1,
                             std::max(part[a].v1, part[b].v1) + 1));
      for (int v = box.y; v < box.br().y; ++v) {
        const auto* m = markers.ptr<int>(v);
        for (int u = box.x; u < box.br().x; ++u) {
          if (in(m[u], a, b, -1)) points.emplace_back(u, v);
        }
      }
      return ShareOfRect(markers, cv::minAreaRect(points), [&](int label) {
        return label == -1 || in(label, a, b, o);
      });
    };
    for (int o = 1; o < background; ++o) {
      if (group[o] != o) continue;
      const std::vector<int>& near = neighbours[o];
      for (size_t i = 0; i < near.size(); ++i) {
        for (size_t j = i + 1; j < near.size(); ++j) {
          const int a = near[i], b = near[j];
          const Part& pa = part[a];
          const Part& pb = part[b];
          if (pa.moments[0] < 1 || pb.moments[0] < 1 || root(a) == root(b)) {
            continue;
          }
          const double lower = std::min(pa.top_mm, pb.top_mm);
          const double upper = std::max(pa.top_mm, pb.top_mm);
          if (upper > options.max_merge_top_ratio * lower ||
              part[o].top_mm <= options.max_merge_top_ratio * upper) {
            continue;
          }
          const cv::Vec3d diff =
              pa.lab_sum / pa.moments[0] - pb.lab_sum / pb.moments[0];
          if (cv::norm(diff) >= options.min_colour_distance ||
              std::max(pa.elongation, pb.elongation) <
                  options.min_join_elongation) {
            continue;
          }
          const double du = pb.u - pa.u, dv = pb.v - pa.v;
          const int steps = static_cast<int>(std::ceil(std::hypot(du, dv)));
          bool covered = steps > 0;
          for (int t = 0; t <= steps && covered; ++t) {
            const int u = static_cast<int>(
                std::lround(pa.u + du * t / std::max(steps, 1)));
            const int v = static_cast<int>(
                std::lround(pa.v + dv * t / std::max(steps, 1)));
            const int label = markers.at<int>(v, u);
            covered = label == -1 || in(label, a, b, o);
          }
          if (covered && fill(a, b, o) >= options.min_join_fill) {
            parent[root(a)] = root(b);
          }
        }
      }
    }
  }
  // A stick cut lengthwise (a celery's U channel: two walls and the floor
  // between, which show a valley, a step and a shaded line, as two touching
  // items do) is several long parts of one colour that together make one
  // straight band. Starting from each part at least
  // min_stick_seed_elongation long for its width, largest first,
  // neighbours of similar colour (or of the band's colour in other light)
  // at least min_stick_part_elongation long for their width are added one
  // at a time, the one that leaves the parts (and the ridges between)
  // filling the smallest rectangle around them most, while that fill is at
  // least min_stick_fill and the rectangle at least min_stick_elongation
  // long for its width. (A round slice at a stick's end can fill such a
  // rectangle too, but it is not long.)
  if (options.min_stick_seed_elongation > 0.0) {
    std::vector<int> group_of(n_cores);  // per label: its part
    for (int i = 0; i < n_cores; ++i) group_of[i] = root(i);
    std::vector<int> px_count(n_cores, 0);
    std::vector<cv::Vec3d> colour_sum(n_cores, cv::Vec3d(0, 0, 0));
    std::vector<std::vector<cv::Point>> hull(n_cores);
    for (int v = 0; v < h; ++v) {
      const auto* m = markers.ptr<int>(v);
      const auto* px = lab.ptr<cv::Vec3f>(v);
      for (int u = 0; u < w; ++u) {
        if (m[u] <= 0 || m[u] >= background) continue;
        const int g = group_of[m[u]];
        ++px_count[g];
        colour_sum[g] += cv::Vec3d(px[u][0], px[u][1], px[u][2]);
        // The ends of each row's run have the hull of all the pixels.
        if (u == 0 || u + 1 == w || m[u - 1] != m[u] || m[u + 1] != m[u]) {
          hull[g].emplace_back(u, v);  // made a hull below
        }
      }
    }
    std::vector<int> order;                        // the parts, largest first
    std::vector<double> elongation(n_cores, 0.0);  // of each part's hull
    for (int g = 1; g < n_cores; ++g) {
      if (px_count[g] < 3) continue;
      std::vector<cv::Point> points = std::move(hull[g]);
      cv::convexHull(points, hull[g]);
      if (hull[g].size() >= 3)
        elongation[g] = Elongation(cv::minAreaRect(hull[g]));
      order.push_back(g);
    }
    std::stable_sort(order.begin(), order.end(),
                     [&](int a, int b) { return px_count[a] > px_count[b]; });
    std::vector<std::set<int>> beside(n_cores);
    for (const auto& [pair, seam] : boundary) {
      const int a = root(pair.first), b = root(pair.second);
      if (a == b) continue;
      beside[a].insert(b);
      beside[b].insert(a);
    }
    std::vector<int> band_of(n_cores, 0);      // the band a part is in, or 0
    std::vector<uint8_t> in_band(n_cores, 0);  // per label: in the trial
    int band = 0;
    for (const int g : order) {
      if (band_of[g] != 0 || hull[g].size() < 3 ||
          elongation[g] < options.min_stick_seed_elongation) {
        continue;
      }
      ++band;
      band_of[g] = band;
      std::vector<int> members = {g};
      std::vector<cv::Point> band_hull = hull[g];
      cv::Vec3d band_colour = colour_sum[g];
      int band_px = px_count[g];
      while (true) {
        std::set<int> candidates;
        for (const int m : members) {
          for (const int n : beside[m]) {
            if (band_of[n] == 0 && px_count[n] > 0) candidates.insert(n);
          }
        }
        // The parts the band may take: long, of its colour (or of its
        // colour in other light: a surface facing the light another way),
        // in no band.
        const cv::Vec3d colour = band_colour / band_px;
        const auto may_join = [&](int n) {
          if (band_of[n] != 0 || px_count[n] == 0 || hull[n].size() < 3 ||
              elongation[n] < options.min_stick_part_elongation) {
            return false;
          }
          const cv::Vec3d part = colour_sum[n] / px_count[n];
          return cv::norm(colour - part) < options.min_colour_distance ||
                 DistanceInOtherLight(colour, part) <
                     options.max_stick_shade_distance;
        };
        // What fills the rectangle: the band's parts and, when
        // stick_fill_counts_long_parts, every part it may take (a wall of
        // the stick beyond the floor that the rectangle takes in).
        std::vector<uint8_t> fills_part(n_cores, 0);
        for (int p = 1; p < n_cores; ++p) {
          fills_part[p] = band_of[p] == band ||
                          (options.stick_fill_counts_long_parts && may_join(p));
        }
        int best = 0;
        double best_fill = options.min_stick_fill;
        std::vector<cv::Point> best_hull;
        for (const int n : candidates) {
          if (!may_join(n)) continue;
          std::vector<cv::Point> points = band_hull;
          points.insert(points.end(), hull[n].begin(), hull[n].end());
          std::vector<cv::Point> joined_hull;
          cv::convexHull(points, joined_hull);
          const cv::RotatedRect rect = cv::minAreaRect(joined_hull);
          if (Elongation(rect) < options.min_stick_elongation) continue;
          for (int i = 1; i < n_cores; ++i) {
            in_band[i] = group_of[i] == n || fills_part[group_of[i]];
          }
          const double fill = ShareOfRect(markers, rect, [&](int label) {
            return label == -1 ||
                   (label > 0 && label < background && in_band[label]);
          });
          if (fill >= best_fill) {
            best_fill = fill;
            best = n;
            best_hull = std::move(joined_hull);
          }
        }
        if (best == 0) break;
        members.push_back(best);
        band_of[best] = band;
        band_hull = std::move(best_hull);
        band_colour += colour_sum[best];
        band_px += px_count[best];
      }
      for (const int m : members) parent[root(m)] = root(g);
    }
  }
  for (int v = 0; v < h; ++v) {
    auto* m = markers.ptr<int>(v);
    for (int u = 0; u < w; ++u) {
      if (m[u] > 0 && m[u] < background) m[u] = root(m[u]);
    }
  }
}

namespace {

// Area over the area of the convex hull of the largest outline of `mask`
// (CV_8UC1, 0/255); `contour` receives that outline. 1 for an empty mask.
double Solidity(const cv::Mat& mask, std::vector<cv::Point>* contour) {
  std::vector<std::vector<cv::Point>> contours;
  cv::findContours(mask, contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_NONE);
  if (contours.empty()) return 1.0;
  size_t largest = 0;
  for (size_t i = 1; i < contours.size(); ++i) {
    if (contours[i].size() > contours[largest].size()) largest = i;
  }
  std::vector<cv::Point> hull;
  cv::convexHull(contours[largest], hull);
  const double hull_area = cv::contourArea(hull);
  const double area = cv::contourArea(contours[largest]);
  if (contour != nullptr) *contour = std::move(contours[largest]);
  if (hull_area <= 0.0) return 1.0;
  return std::min(1.0, area / hull_area);
}

// The pixels (255) of `frame` that belong to crumbs of region `label`:
// regions of at most `max_px` pixels (by `sizes`) with pixels in `inner`
// (the region's box, in `frame`'s coordinates) that border `label` and no
// region but `label`, other regions of at most `max_px` pixels and the
// background (8-neighbours of the ridge pixels around them, looked for
// within their `boxes`). Only their pixels within `inner` and within the
// convex hull of `label`'s own pixels. `max_px` 0: none.
cv::Mat Crumbs(const cv::Mat& markers, const cv::Rect& frame,
               const cv::Rect& inner, int label, int background,
               const std::vector<int>& sizes,
               const std::vector<cv::Rect>& boxes, int max_px) {
  cv::Mat crumbs(frame.size(), CV_8UC1, cv::Scalar(0));
  if (max_px <= 0) return crumbs;
  const cv::Mat window = markers(frame);
  const auto small = [&](int m) {
    return m > 0 && m < background && m != label && sizes[m] <= max_px;
  };
  std::set<int> candidates;
  for (int v = inner.y; v < inner.br().y; ++v) {
    const int* m = window.ptr<int>(v);
    for (int u = inner.x; u < inner.br().x; ++u) {
      if (small(m[u])) candidates.insert(m[u]);
    }
  }
  const cv::Rect image(0, 0, markers.cols, markers.rows);
  std::set<int> taken;
  for (const int c : candidates) {
    // The ridge pixels beside c: what else they border.
    const cv::Rect around =
        (boxes[c] + cv::Size(2, 2) - cv::Point(1, 1)) & image;
    bool mine = false, theirs = false;
    for (int v = around.y; v < around.br().y && !theirs; ++v) {
      for (int u = around.x; u < around.br().x; ++u) {
        if (markers.at<int>(v, u) != -1) continue;
        bool beside_c = false, beside_label = false, beside_other = false;
        for (int dv = -1; dv <= 1; ++dv) {
          for (int du = -1; du <= 1; ++du) {
            if (!image.contains({u + du, v + dv})) continue;
            const int m = markers.at<int>(v + dv, u + du);
            beside_c |= m == c;
            beside_label |= m == label;
            beside_other |= m > 0 && m < background && m != label && !small(m);
          }
        }
        if (!beside_c) continue;
        mine |= beside_label;
        theirs |= beside_other;
      }
    }
    if (mine && !theirs) taken.insert(c);
  }
  if (taken.empty()) return crumbs;
  // Only within the region's own convex hull: a crumb fills a notch, it
  // does not widen the outline.
  cv::Mat hull_mask(frame.size(), CV_8UC1, cv::Scalar(0));
  std::vector<cv::Point> own, hull;
  cv::findNonZero(window == label, own);
  cv::convexHull(own, hull);
  cv::fillConvexPoly(hull_mask, hull, cv::Scalar(255));
  for (int v = inner.y; v < inner.br().y; ++v) {
    const int* m = window.ptr<int>(v);
    const uint8_t* in_hull = hull_mask.ptr<uint8_t>(v);
    uint8_t* out = crumbs.ptr<uint8_t>(v);
    for (int u = inner.x; u < inner.br().x; ++u) {
      if (in_hull[u] && taken.count(m[u]) > 0) out[u] = 255;
    }
  }
  return crumbs;
}

}  // namespace

void SplitAtWaists(const FoodDetectorOptions& options, Regions& regions) {
  if (options.max_waist_solidity <= 0.0) return;
  cv::Mat& markers = regions.markers;
  const int n_items = regions.background;
  // Each region's pixels and a box around them (for crumbs), kept up to
  // date as regions are cut (a part keeps the box of the whole).
  std::vector<int> sizes(regions.background + 1, 0);
  std::vector<cv::Rect> boxes(regions.background + 1);
  if (options.max_waist_crumb_px > 0) {
    for (int v = 0; v < markers.rows; ++v) {
      const int* m = markers.ptr<int>(v);
      for (int u = 0; u < markers.cols; ++u) {
        if (m[u] <= 0 || m[u] >= regions.background) continue;
        ++sizes[m[u]];
        boxes[m[u]] |= cv::Rect(u, v, 1, 1);
      }
    }
  }
  for (int label = 1; label < n_items; ++label) {
    const cv::Mat mask = markers == label;
    const cv::Rect box = cv::boundingRect(mask);
    if (box.area() == 0) continue;
    // Work in the item's box, with a 1 px margin so outlines close.
    const cv::Rect frame = (box + cv::Size(2, 2) - cv::Point(1, 1)) &
                           cv::Rect(0, 0, markers.cols, markers.rows);
    cv::Mat item = mask(frame).clone();
    const cv::Mat window = markers(frame);
    const cv::Rect inner = box - frame.tl();
    // Crumbs: small regions that border this region and no other but small
    // ones, their pixels within its box and its own convex hull
    // (FoodDetectorOptions::max_waist_crumb_px). They count as the
    // region's in the solidity tests, and keep their labels.
    const cv::Mat crumbs =
        Crumbs(markers, frame, inner, label, regions.background, sizes, boxes,
               options.max_waist_crumb_px);
    item |= crumbs;
    if (options.waist_fills_inner_seams) {
      // The seams between parts the merge joined are still ridge pixels;
      // those that touch nothing but the item (and other ridge pixels;
      // 8-neighbours) are the item, not notches in it. Only within the
      // item's box, whose pixels have all their neighbours in the frame.
      cv::Mat other = (window != label) & (window != -1) & ~crumbs;
      cv::dilate(other, other, cv::Mat());
      cv::Mat inside_box = item(inner);
      inside_box |= (window(inner) == -1) & ~other(inner);
    }
    const int area = cv::countNonZero(item);
    std::vector<cv::Point> outline;
    if (Solidity(item, &outline) >= options.max_waist_solidity) continue;
    if (outline.size() < 8) continue;
    std::vector<int> hull;
    cv::convexHull(outline, hull, /*clockwise=*/false, /*returnPoints=*/false);
    std::vector<cv::Vec4i> defects;
    try {
      cv::convexityDefects(outline, hull, defects);
    } catch (const cv::Exception&) {
      continue;  // a self-touching outline: leave the region whole
    }
    const bool stick =
        Elongation(cv::minAreaRect(outline)) >= options.min_stick_elongation;
    std::vector<cv::Point> deep;
    for (const cv::Vec4i& d : defects) {
      if (d[3] / 256.0 >= options.min_waist_depth_px) {
        deep.push_back(outline[d[2]]);
      }
    }
    // The cut between two concavities that leaves the most convex parts.
    double best = options.min_waist_solidity;
    cv::Mat best_parts;
    int best_second = 0;
    // The cut that leaves a thin strip beside the most convex body.
    double best_tail_body = options.min_waist_solidity;
    cv::Mat tail_parts;
    int tail_second = 0;
    for (size_t i = 0; i < deep.size(); ++i) {
      for (size_t j = i + 1; j < deep.size(); ++j) {
        cv::Mat cut = item.clone();
        cv::line(cut, deep[i], deep[j], cv::Scalar(0), 2);
        cv::Mat parts;
        const int n = cv::connectedComponents(cut, parts, 4, CV_32S);
        std::vector<int> part_px(n, 0);
        for (int v = 0; v < parts.rows; ++v) {
          const int* p = parts.ptr<int>(v);
          for (int u = 0; u < parts.cols; ++u) ++part_px[p[u]];
        }
        // The two largest parts besides the outside (label 0).
        int first = 0, second = 0;
        for (int c = 1; c < n; ++c) {
          if (first == 0 || part_px[c] > part_px[first]) {
            second = first;
            first = c;
          } else if (second == 0 || part_px[c] > part_px[second]) {
            second = c;
          }
        }
        if (second == 0 ||
            part_px[second] < options.min_waist_part_share * area) {
          continue;
        }
        std::vector<cv::Point> first_outline, second_outline;
        const double first_solidity = Solidity(parts == first, &first_outline);
        const double worst = std::min(
            first_solidity, Solidity(parts == second, &second_outline));
        if (worst > best) {
          // A waist is narrower than both parts: a cut as wide as a part,
          // across a region long for its width, is across a stick, not
          // between two items.
          const double cut_px = cv::norm(deep[i] - deep[j]);
          const auto width = [](const std::vector<cv::Point>& part) {
            const cv::Size2f size = cv::minAreaRect(part).size;
            return std::min(size.width, size.height);
          };
          if (options.max_waist_cut_share <= 0.0 || !stick ||
              cut_px <=
                  options.max_waist_cut_share *
                      std::min(width(first_outline), width(second_outline))) {
            best = worst;
            best_parts = parts;
            best_second = second;
          }
        } else if (options.max_tail_width_px > 0.0 &&
                   first_solidity > best_tail_body) {
          // Or a compact convex body and a thin strip: the strip is of
          // another item (FoodDetectorOptions::max_tail_width_px).
          const cv::RotatedRect body = cv::minAreaRect(first_outline);
          const cv::RotatedRect strip = cv::minAreaRect(second_outline);
          const double strip_length =
              std::max(strip.size.width, strip.size.height);
          if (Elongation(body) <= options.max_tail_body_elongation &&
              Elongation(strip) >= options.min_stick_elongation &&
              part_px[second] <= options.max_tail_width_px * strip_length) {
            best_tail_body = first_solidity;
            tail_parts = parts;
            tail_second = second;
          }
        }
      }
    }
    if (best_parts.empty() && !tail_parts.empty()) {
      best_parts = tail_parts;
      best_second = tail_second;
    }
    if (best_parts.empty()) continue;
    // The second part takes the background's label, the background the
    // next; the cut and any crumbs left by it become ridge pixels.
    const int new_label = regions.background;
    const int new_background = regions.background + 1;
    for (int v = 0; v < markers.rows; ++v) {
      int* m = markers.ptr<int>(v);
      for (int u = 0; u < markers.cols; ++u) {
        if (m[u] == regions.background) m[u] = new_background;
      }
    }
    int moved = 0, taken = 0;  // pixels to the new label, of them the region's
    for (int v = 0; v < frame.height; ++v) {
      const int* p = best_parts.ptr<int>(v);
      const uint8_t* inside = item.ptr<uint8_t>(v);
      const uint8_t* crumb = crumbs.ptr<uint8_t>(v);
      int* m = markers.ptr<int>(frame.y + v) + frame.x;
      for (int u = 0; u < frame.width; ++u) {
        if (!inside[u] || crumb[u]) continue;
        if (p[u] == best_second) {
          taken += m[u] == label;
          ++moved;
          m[u] = new_label;
        } else if (p[u] == 0) {
          m[u] = -1;
        }
      }
    }
    regions.background = new_background;
    sizes.resize(new_background + 1, 0);
    boxes.resize(new_background + 1);
    sizes[label] -= taken;
    sizes[new_label] = moved;
    boxes[new_label] = boxes[label];
  }
}

namespace {

// The centroid of an item's pixels `points` (inside `box`), unless it falls
// off them: then the centroid of the largest of the item's pieces (8-
// connected). A stick seen on both sides of an item lying across it is
// aimed at its longer stub, not at the item on it.
cv::Point2d CentreOnItem(const std::vector<cv::Point>& points,
                         const cv::Rect& box) {
  cv::Point2d sum(0, 0);
  cv::Mat mask(box.size(), CV_8UC1, cv::Scalar(0));
  for (const cv::Point& p : points) {
    sum += cv::Point2d(p);
    mask.at<uint8_t>(p - box.tl()) = 255;
  }
  const cv::Point2d centroid = sum / static_cast<double>(points.size());
  const cv::Point at(cvRound(centroid.x), cvRound(centroid.y));
  if (box.contains(at) && mask.at<uint8_t>(at - box.tl()) != 0) {
    return centroid;
  }
  cv::Mat pieces, stats, centroids;
  const int n = cv::connectedComponentsWithStats(mask, pieces, stats, centroids,
                                                 8, CV_32S);
  // One piece (a curved one): its centroid is the item's; leave it.
  if (n < 3) return centroid;
  int largest = 1;
  for (int c = 2; c < n; ++c) {
    if (stats.at<int>(c, cv::CC_STAT_AREA) >
        stats.at<int>(largest, cv::CC_STAT_AREA)) {
      largest = c;
    }
  }
  return cv::Point2d(box.x + centroids.at<double>(largest, 0),
                     box.y + centroids.at<double>(largest, 1));
}

}  // namespace

std::vector<DetectedFood> DescribeItems(const Regions& regions,
                                        const FoodEvidence& evidence,
                                        const cv::Mat& raw_depth,
                                        const cv::Rect& roi, const Plane& plane,
                                        const CameraIntrinsics& k,
                                        const FoodDetectorOptions& options) {
  const cv::Mat& markers = regions.markers;
  const cv::Mat& above = evidence.above;
  const cv::Mat& colour = evidence.colour;
  const int w = markers.cols, h = markers.rows;
  const int background = regions.background;
  const int n_cores = background;
  std::vector<DetectedFood> items;
  // Per item: its pixels, depths and evidence. Watershed leaves its ridge
  // pixels (-1) unlabelled; those that look like food join a neighbour.
  struct Accumulator {
    std::vector<cv::Point> points;
    std::vector<double> depths_mm;
    double evidence = 0.0;
    int ridge_px = 0;  // ridge pixels joined
  };
  std::vector<Accumulator> acc(n_cores);
  for (int v = 0; v < h; ++v) {
    const auto* m = markers.ptr<int>(v);
    const auto* a = above.ptr<uint8_t>(v);
    const auto* c = colour.ptr<uint8_t>(v);
    const auto* raw = raw_depth.ptr<uint16_t>(v);
    for (int u = 0; u < w; ++u) {
      int label = m[u];
      if (label == -1 && (a[u] || c[u])) {
        for (const auto& [du, dv] :
             {std::pair{-1, 0}, {1, 0}, {0, -1}, {0, 1}}) {
          const int uu = u + du, vv = v + dv;
          if (uu < 0 || vv < 0 || uu >= w || vv >= h) continue;
          const int n = markers.at<int>(vv, uu);
          if (n > 0 && n < background) {
            label = n;
            break;
          }
        }
      }
      if (label <= 0 || label >= background) continue;
      Accumulator& item = acc[label];
      item.points.emplace_back(u, v);
      item.ridge_px += m[u] == -1;
      if (raw[u] > 0) item.depths_mm.push_back(raw[u]);
      item.evidence += ((a[u] ? 1.0 : 0.0) + (c[u] ? 1.0 : 0.0)) / 2.0;
    }
  }

  for (int label = 1; label < background; ++label) {
    Accumulator& item = acc[label];
    if (item.points.empty()) continue;
    DetectedFood food;
    for (cv::Point& p : item.points) p += roi.tl();
    const cv::Rect box = cv::boundingRect(item.points);
    food.bbox = {box.x, box.y, box.width, box.height};
    food.area_px = static_cast<int>(item.points.size());
    const cv::Point2d centre_px = CentreOnItem(item.points, box);
    food.center_u_px = centre_px.x;
    food.center_v_px = centre_px.y;
    double z_mm = Median(item.depths_mm);
    if (z_mm <= 0) {
      // No depth on the item at all: the plate's depth along its centre ray
      // is the best estimate left.
      const cv::Vec3d ray = Deproject(k, food.center_u_px, food.center_v_px, 1);
      z_mm = -plane.d / plane.n.dot(ray);
    }
    food.depth_m = z_mm / 1000.0;
    const double pixel_area_m2 = (food.depth_m / k.fx) * (food.depth_m / k.fy);
    // Sized by the pixels its seed grew, not the ridge it was handed: a
    // sliver's ridge can be a third of it.
    if ((food.area_px - item.ridge_px) * pixel_area_m2 <
        options.min_item_area_m2) {
      continue;
    }
    const cv::Vec3d centre =
        Deproject(k, food.center_u_px, food.center_v_px, z_mm) / 1000.0;
    food.center_x_m = centre[0];
    food.center_y_m = centre[1];
    food.center_z_m = centre[2];
    food.major_axis_angle_rad = MajorAxisAngle(item.points);
    food.score = item.evidence / food.area_px;
    items.push_back(food);
  }
  std::sort(items.begin(), items.end(),
            [](const DetectedFood& a, const DetectedFood& b) {
              if (a.score != b.score) return a.score > b.score;
              if (a.bbox.y != b.bbox.y) return a.bbox.y < b.bbox.y;
              return a.bbox.x < b.bbox.x;
            });
  return items;
}

}  // namespace bitewise::perception::detection
