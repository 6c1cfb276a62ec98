// The simulated D415: ray casts the plate scene into an RGB image and an
// aligned depth image with the sensor's typical defects (depth noise growing
// with distance, 1 mm quantisation, stereo occlusion holes beside raised
// edges, speckle dropouts), so perception is tested on frames that look like
// the real camera's rather than on clean masks.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <utility>
#include <vector>

#include "services/domain/random.h"
#include "services/sim/scene.h"

namespace bitewise::sim {
namespace {

constexpr double kPi = 3.14159265358979323846;
// The flat well of the plate ends at this fraction of the radius; the rim
// rises from there to rim_height_m at the edge.
constexpr double kWellFraction = 0.8;
// The plate stands this far above the mat (the mat is below plate surface).
constexpr double kPlateThicknessM = 0.014;
// D415 stereo baseline; occlusion holes appear left of raised edges.
constexpr double kStereoBaselineM = 0.055;
// Depth noise at the nominal working distance; grows with distance squared.
constexpr double kDepthNoiseMmAt35cm = 0.6;
constexpr double kSpeckleHoleFraction = 0.004;
// Items with this length/width ratio or more are drawn as rounded sticks.
constexpr double kStickAspect = 1.8;

// Deterministic per-item value noise in [-1, 1]: a hash of lattice points,
// smoothly interpolated. No global state, so textures never depend on the
// order items are drawn in.
double Hash01(uint64_t seed, int64_t ix, int64_t iy) {
  uint64_t h = seed ^ (static_cast<uint64_t>(ix) * 0x9E3779B97F4A7C15ULL) ^
               (static_cast<uint64_t>(iy) * 0xC2B2AE3D27D4EB4FULL);
  h ^= h >> 33;
  h *= 0xFF51AFD7ED558CCDULL;
  h ^= h >> 33;
  h *= 0xC4CEB9FE1A85EC53ULL;
  h ^= h >> 33;
  return static_cast<double>(h >> 11) * (1.0 / 9007199254740992.0);
}

double ValueNoise(uint64_t seed, double x, double y) {
  const double fx = std::floor(x), fy = std::floor(y);
  const auto ix = static_cast<int64_t>(fx), iy = static_cast<int64_t>(fy);
  double tx = x - fx, ty = y - fy;
  tx = tx * tx * (3 - 2 * tx);
  ty = ty * ty * (3 - 2 * ty);
  const double a = Hash01(seed, ix, iy), b = Hash01(seed, ix + 1, iy);
  const double c = Hash01(seed, ix, iy + 1), d = Hash01(seed, ix + 1, iy + 1);
  return 2.0 * ((a * (1 - tx) + b * tx) * (1 - ty) +
                (c * (1 - tx) + d * tx) * ty) -
         1.0;
}

// An item's shape: a superellipse footprint (exponent 2 = ellipse, 4 =
// rounded stick) with a dome on top.
struct ItemShape {
  const SceneItem* item;
  double a, b;  // half axes
  double exponent;
  double cos_yaw, sin_yaw;
  double bound_m;  // radius of a circle around the footprint
};

ItemShape ShapeOf(const SceneItem& item) {
  ItemShape s;
  s.item = &item;
  s.a = std::max(item.length_m, item.width_m) / 2;
  s.b = std::min(item.length_m, item.width_m) / 2;
  s.exponent = s.a / std::max(s.b, 1e-6) >= kStickAspect ? 4.0 : 2.0;
  s.cos_yaw = std::cos(item.yaw_rad);
  s.sin_yaw = std::sin(item.yaw_rad);
  s.bound_m = s.a;
  return s;
}

// Footprint function: < 1 inside, 1 on the outline.
double Footprint(const ItemShape& s, double x_m, double y_m) {
  const double dx = x_m - s.item->x_m, dy = y_m - s.item->y_m;
  const double u = (dx * s.cos_yaw + dy * s.sin_yaw) / s.a;
  const double v = (-dx * s.sin_yaw + dy * s.cos_yaw) / s.b;
  const double u2 = u * u, v2 = v * v;
  return s.exponent == 2.0 ? u2 + v2 : u2 * u2 + v2 * v2;
}

// Height of the item's surface above the plate at (x, y); negative outside.
double ItemHeight(const ItemShape& s, double x_m, double y_m) {
  const double q = Footprint(s, x_m, y_m);
  if (q >= 1.0) return -1.0;
  const double r = std::sqrt(1.0 - q);
  return s.item->base_m +
         s.item->height_m * (s.exponent == 2.0 ? r : std::sqrt(r));
}

double PlateHeight(const PlateScene& scene, double x_m, double y_m) {
  const double r = std::hypot(x_m, y_m);
  const double well = kWellFraction * scene.plate_radius_m;
  if (r <= well) return 0.0;
  if (r <= scene.plate_radius_m) {
    const double t = (r - well) / (scene.plate_radius_m - well);
    return scene.rim_height_m * t * t * (3 - 2 * t);
  }
  return -kPlateThicknessM;
}

struct Hit {
  double height_m = 0.0;
  int item = -1;  // index into scene.items, -1 for plate or mat
  double x_m = 0.0, y_m = 0.0;
};

double EncodeSrgb(double linear) {
  linear = std::clamp(linear, 0.0, 1.0);
  return linear <= 0.0031308 ? 12.92 * linear
                             : 1.055 * std::pow(linear, 1.0 / 2.4) - 0.055;
}

}  // namespace

PinholeIntrinsics D415Intrinsics() { return PinholeIntrinsics(); }

RenderedFrame RenderPlate(const PlateScene& scene,
                          const PinholeIntrinsics& intrinsics,
                          uint64_t noise_seed) {
  const int w = intrinsics.width, h = intrinsics.height;
  const double cam = scene.camera_height_m;
  std::vector<ItemShape> shapes;
  shapes.reserve(scene.items.size());
  for (const SceneItem& item : scene.items) shapes.push_back(ShapeOf(item));

  // Ray cast: the camera ray through pixel (u, v) meets height z at plate
  // coordinates ((u - cx) (cam - z) / fx, (v - cy) (cam - z) / fy).
  std::vector<Hit> hits(static_cast<size_t>(w) * h);
  std::vector<int> footprint(shapes.size(), 0);
  for (int v = 0; v < h; ++v) {
    const double ry = (v - intrinsics.cy) / intrinsics.fy;
    for (int u = 0; u < w; ++u) {
      const double rx = (u - intrinsics.cx) / intrinsics.fx;
      Hit best;
      // Plate and mat: a few fixed-point steps converge since the rim is
      // shallow.
      double z = 0.0;
      for (int it = 0; it < 4; ++it) {
        z = PlateHeight(scene, rx * (cam - z), ry * (cam - z));
      }
      best.height_m = z;
      best.x_m = rx * (cam - z);
      best.y_m = ry * (cam - z);
      for (size_t i = 0; i < shapes.size(); ++i) {
        const ItemShape& s = shapes[i];
        // Cull with the distance from the item's centre to the ray's
        // segment between the item's top and the plate.
        const double item_top = s.item->base_m + s.item->height_m;
        const double top = cam - item_top;
        const double ax = rx * top - s.item->x_m, ay = ry * top - s.item->y_m;
        const double bx = rx * cam - s.item->x_m, by = ry * cam - s.item->y_m;
        const double sx = bx - ax, sy = by - ay;
        const double t = std::clamp(
            -(ax * sx + ay * sy) / std::max(sx * sx + sy * sy, 1e-18), 0.0,
            1.0);
        if (std::hypot(ax + t * sx, ay + t * sy) > s.bound_m * 1.02) continue;
        // The first point along the ray (from the camera down) that lies
        // inside the dome: march down in height, then bisect.
        auto inside = [&](double zz) {
          return zz >= s.item->base_m &&
                 ItemHeight(s, rx * (cam - zz), ry * (cam - zz)) >= zz;
        };
        constexpr int kSteps = 16;
        double hit_z = -1.0;
        double above = item_top;
        for (int k = 1; k <= kSteps; ++k) {
          const double zz =
              s.item->base_m + s.item->height_m * (kSteps - k) / kSteps;
          if (!inside(zz)) {
            above = zz;
            continue;
          }
          double lo = zz, hi = above;  // inside at lo, outside at hi
          for (int it = 0; it < 12; ++it) {
            const double mid = 0.5 * (lo + hi);
            (inside(mid) ? lo : hi) = mid;
          }
          hit_z = lo;
          break;
        }
        if (hit_z >= 0.0) ++footprint[i];
        if (hit_z > best.height_m) {
          best.height_m = hit_z;
          best.item = static_cast<int>(i);
          best.x_m = rx * (cam - hit_z);
          best.y_m = ry * (cam - hit_z);
        }
      }
      hits[static_cast<size_t>(v) * w + u] = best;
    }
  }

  RenderedFrame frame;
  frame.intrinsics = intrinsics;
  frame.rgb.resize(static_cast<size_t>(w) * h * 3);
  frame.depth_mm.resize(static_cast<size_t>(w) * h);
  std::mt19937_64 rng(noise_seed);
  random::Normal gauss;

  // Light from the upper left, as from a window or ceiling lamp.
  const double lx = -0.35, ly = -0.45, lz = 0.82;
  const double lnorm = std::sqrt(lx * lx + ly * ly + lz * lz);
  auto surface_height = [&](const Hit& hit, double x, double y) {
    if (hit.item >= 0) {
      return std::max(0.0, ItemHeight(shapes[hit.item], x, y));
    }
    return PlateHeight(scene, x, y);
  };

  for (int v = 0; v < h; ++v) {
    for (int u = 0; u < w; ++u) {
      const size_t idx = static_cast<size_t>(v) * w + u;
      const Hit& hit = hits[idx];
      // Surface normal from the height field's gradient.
      const double e = 0.0005;
      const double gx = (surface_height(hit, hit.x_m + e, hit.y_m) -
                         surface_height(hit, hit.x_m - e, hit.y_m)) /
                        (2 * e);
      const double gy = (surface_height(hit, hit.x_m, hit.y_m + e) -
                         surface_height(hit, hit.x_m, hit.y_m - e)) /
                        (2 * e);
      // Height grows towards the camera (-z camera), so the outward normal
      // in plate coordinates is (-gx, -gy, 1).
      const double nn = std::sqrt(gx * gx + gy * gy + 1.0);
      const double lambert =
          std::max(0.0, (-gx * lx - gy * ly + lz) / (nn * lnorm));
      std::array<double, 3> base{};
      double texture = 0.0;
      if (hit.item >= 0) {
        const SceneItem& item = scene.items[hit.item];
        base = item.rgb;
        // Two octaves of texture in item coordinates, so it turns with the
        // item, plus seed-like speckles.
        const double sx = hit.x_m * 900.0, sy = hit.y_m * 900.0;
        texture = 0.10 * ValueNoise(item.texture_seed, sx, sy) +
                  0.06 * ValueNoise(item.texture_seed + 1, 3 * sx, 3 * sy);
        if (ValueNoise(item.texture_seed + 2, 4 * sx, 4 * sy) > 0.8) {
          texture -= 0.18;
        }
      } else if (std::hypot(hit.x_m, hit.y_m) <= scene.plate_radius_m) {
        base = scene.plate_rgb;
        texture = 0.015 *
                  ValueNoise(noise_seed + 7, hit.x_m * 200.0, hit.y_m * 200.0);
      } else {
        base = scene.mat_rgb;
        // A woven mat: fine cross-hatching and blotches.
        texture =
            0.08 * std::sin(hit.x_m * 2200.0) * std::sin(hit.y_m * 2200.0) +
            0.06 * ValueNoise(noise_seed + 11, hit.x_m * 60.0, hit.y_m * 60.0);
      }
      // Soft contact shadow of items on the plate and mat.
      double shadow = 1.0;
      if (hit.item < 0) {
        for (const ItemShape& s : shapes) {
          const double sx = hit.x_m - 0.004, sy = hit.y_m - 0.005;
          const double q = Footprint(s, sx, sy);
          if (q < 1.6)
            shadow =
                std::min(shadow, 0.82 + 0.18 * std::max(0.0, (q - 1.0) / 0.6));
        }
      }
      const double shade = (0.45 + 0.55 * lambert) * shadow;
      for (int c = 0; c < 3; ++c) {
        const double linear =
            base[c] * shade * (1.0 + texture) + 0.008 * gauss(rng);
        frame.rgb[idx * 3 + c] =
            static_cast<uint8_t>(std::lround(255.0 * EncodeSrgb(linear)));
      }
      const double z_m = cam - hit.height_m;
      const double sigma_mm = kDepthNoiseMmAt35cm * (z_m / 0.35) * (z_m / 0.35);
      const double ripple_mm =
          0.4 * ValueNoise(noise_seed + 3, u / 40.0, v / 40.0);
      const double depth_mm = z_m * 1000.0 + ripple_mm + sigma_mm * gauss(rng);
      frame.depth_mm[idx] =
          static_cast<uint16_t>(std::clamp(std::lround(depth_mm), 0L, 65535L));
    }
  }

  // Stereo occlusion: the left imager cannot match surface points hidden
  // from the right one, so a band left of every raised edge has no depth.
  // Its width is the disparity jump, f * B * (1/z_near - 1/z_far).
  std::vector<uint16_t> clean = frame.depth_mm;
  const double fb = intrinsics.fx * kStereoBaselineM * 1000.0;  // px * mm
  for (int v = 0; v < h; ++v) {
    const uint16_t* row = &clean[static_cast<size_t>(v) * w];
    for (int u = 0; u < w; ++u) {
      const double zu = row[u];
      if (zu <= 0) continue;
      for (int k = 1; k <= 12 && u + k < w; ++k) {
        const double zk = row[u + k];
        if (zk <= 0 || zk >= zu - 3.0) continue;
        if (fb * (1.0 / zk - 1.0 / zu) >= k) {
          frame.depth_mm[static_cast<size_t>(v) * w + u] = 0;
          break;
        }
      }
    }
  }
  // Speckle dropouts and a few larger holes (specular glints).
  for (uint16_t& d : frame.depth_mm) {
    if (random::Canonical(rng) < kSpeckleHoleFraction) d = 0;
  }
  const int blobs = 2 + static_cast<int>(random::Canonical(rng) * 3);
  for (int b = 0; b < blobs; ++b) {
    const int bu = static_cast<int>(random::Canonical(rng) * w);
    const int bv = static_cast<int>(random::Canonical(rng) * h);
    const int r = 2 + static_cast<int>(random::Canonical(rng) * 3);
    for (int y = std::max(0, bv - r); y <= std::min(h - 1, bv + r); ++y) {
      for (int x = std::max(0, bu - r); x <= std::min(w - 1, bu + r); ++x) {
        if ((x - bu) * (x - bu) + (y - bv) * (y - bv) <= r * r) {
          frame.depth_mm[static_cast<size_t>(y) * w + x] = 0;
        }
      }
    }
  }

  // Ground truth from the noiseless hit map.
  frame.truth.resize(scene.items.size());
  std::vector<std::array<int, 4>> extent(scene.items.size(), {w, h, -1, -1});
  for (int v = 0; v < h; ++v) {
    for (int u = 0; u < w; ++u) {
      const int i = hits[static_cast<size_t>(v) * w + u].item;
      if (i < 0) continue;
      auto& e = extent[i];
      e[0] = std::min(e[0], u);
      e[1] = std::min(e[1], v);
      e[2] = std::max(e[2], u);
      e[3] = std::max(e[3], v);
      ++frame.truth[i].visible_pixels;
    }
  }
  for (size_t i = 0; i < scene.items.size(); ++i) {
    ItemTruth& t = frame.truth[i];
    t.id = scene.items[i].id;
    t.footprint_pixels = footprint[i];
    if (t.visible_pixels > 0) {
      t.x = extent[i][0];
      t.y = extent[i][1];
      t.width = extent[i][2] - extent[i][0] + 1;
      t.height = extent[i][3] - extent[i][1] + 1;
    }
  }
  return frame;
}

namespace {

// Whether two items' footprints come closer than `gap_m` (negative gap
// allows nothing; zero means touching is still acceptable). Tested on
// points around each outline, which is exact enough at millimetre scale.
// Whether a and b, each pushed out by `gap_m`, overlap: an outline point of
// one inside the other, or (with `containment`) the centre of one inside the
// other. RandomPlate checks outlines only, which misses two items of about
// the same size almost on top of each other; it keeps that flaw so that the
// simulated world's plates (and every experiment on them) stay as they
// were, until the experiments are rerun. CrowdedPlate checks both.
bool Overlaps(const SceneItem& a, const SceneItem& b, double gap_m,
              bool containment = false) {
  const ItemShape sa = ShapeOf(a), sb = ShapeOf(b);
  if (std::hypot(a.x_m - b.x_m, a.y_m - b.y_m) >
      sa.bound_m + sb.bound_m + gap_m) {
    return false;
  }
  // One inside the other (the outlines below would not cross).
  if (containment && (Footprint(sa, b.x_m, b.y_m) < 1.0 ||
                      Footprint(sb, a.x_m, a.y_m) < 1.0)) {
    return true;
  }
  for (const auto& [s, other] : {std::pair{&sa, &sb}, std::pair{&sb, &sa}}) {
    for (int k = 0; k < 96; ++k) {
      const double t = 2 * kPi * k / 96;
      const double ct = std::cos(t), st = std::sin(t);
      // Superellipse outline point, pushed out by the gap.
      const double e = 2.0 / s->exponent;
      const double pu =
          (s->a + gap_m) * std::copysign(std::pow(std::abs(ct), e), ct);
      const double pv =
          (s->b + gap_m) * std::copysign(std::pow(std::abs(st), e), st);
      const double x = s->item->x_m + pu * s->cos_yaw - pv * s->sin_yaw;
      const double y = s->item->y_m + pu * s->sin_yaw + pv * s->cos_yaw;
      if (Footprint(*other, x, y) < 1.0) return true;
    }
  }
  return false;
}

}  // namespace

domain::RgbdFrame ToRgbdFrame(RenderedFrame rendered, uint64_t sequence,
                              double capture_s) {
  domain::RgbdFrame frame;
  frame.intrinsics = rendered.intrinsics;
  frame.rgb = std::move(rendered.rgb);
  frame.depth_mm = std::move(rendered.depth_mm);
  frame.sequence = sequence;
  frame.capture_s = capture_s;
  return frame;
}

namespace {

// One item of `food`: size, orientation, colour and texture drawn as every
// plate draws them (`gauss` lives as long as the plate, so the stream of
// draws is the plate's).
SceneItem DrawItem(const FoodType* food, uint32_t id, random::Normal& gauss,
                   std::mt19937_64& rng) {
  auto between = [&](const std::array<double, 2>& range) {
    return range[0] + (range[1] - range[0]) * random::Canonical(rng);
  };
  SceneItem item;
  item.id = id;
  item.food = food;
  double length = between(food->length_m), width = between(food->width_m);
  if (width > length) std::swap(width, length);
  item.length_m = length;
  item.width_m = width;
  item.height_m = between(food->height_m);
  item.yaw_rad = kPi * (2 * random::Canonical(rng) - 1);
  // Ripeness shifts all channels together; the rest varies per channel.
  const double ripeness = food->rgb_spread * gauss(rng);
  for (int c = 0; c < 3; ++c) {
    item.rgb[c] = std::clamp(
        food->rgb[c] + ripeness + 0.5 * food->rgb_spread * gauss(rng), 0.02,
        0.98);
  }
  item.texture_seed = rng();
  return item;
}

// Items stay inside the well, clear of the rim; separate items keep a gap
// so that they are distinguishable.
constexpr double kRimClearanceM = 0.004;
constexpr double kGapM = 0.004;

// Places `item` at `fraction` of the distance at which it would just touch
// `anchor`, along `dir`. Returns false if that is outside `reach`.
bool PlaceAgainst(SceneItem& item, const SceneItem& anchor, double dir,
                  double fraction, double reach) {
  double lo = 0.0, hi = anchor.length_m / 2 + item.length_m / 2 + 0.01;
  for (int it = 0; it < 30; ++it) {
    const double mid = 0.5 * (lo + hi);
    item.x_m = anchor.x_m + mid * std::cos(dir);
    item.y_m = anchor.y_m + mid * std::sin(dir);
    (Overlaps(item, anchor, 0.0) ? lo : hi) = mid;
  }
  item.x_m = anchor.x_m + fraction * hi * std::cos(dir);
  item.y_m = anchor.y_m + fraction * hi * std::sin(dir);
  return std::hypot(item.x_m, item.y_m) <= reach;
}

// Whether `item` keeps the gap to every placed item but `except`.
bool ClearOfOthers(const SceneItem& item, const std::vector<SceneItem>& placed,
                   const SceneItem* except, bool containment) {
  for (const SceneItem& other : placed) {
    if (&other != except && Overlaps(item, other, kGapM, containment)) {
      return false;
    }
  }
  return true;
}

// Anywhere in the well, clear of every placed item.
bool PlaceApart(SceneItem& item, const std::vector<SceneItem>& placed,
                double reach, bool containment, std::mt19937_64& rng) {
  for (int attempt = 0; attempt < 2000; ++attempt) {
    const double r = reach * std::sqrt(random::Canonical(rng));
    const double t = 2 * kPi * random::Canonical(rng);
    item.x_m = r * std::cos(t);
    item.y_m = r * std::sin(t);
    if (ClearOfOthers(item, placed, nullptr, containment)) return true;
  }
  return false;
}

}  // namespace

PlateScene RandomPlate(const std::vector<const FoodType*>& foods,
                       bool allow_touching, std::mt19937_64& rng) {
  PlateScene scene;
  random::Normal gauss;
  const double well = kWellFraction * scene.plate_radius_m - kRimClearanceM;
  uint32_t next_id = 1;
  for (const FoodType* food : foods) {
    SceneItem item = DrawItem(food, next_id++, gauss, rng);
    const double reach = well - item.length_m / 2;
    bool placed = false;
    // Touch a neighbour half of the time when allowed: slide out from a
    // placed item along a random direction until the two just separate.
    if (allow_touching && !scene.items.empty() &&
        random::Canonical(rng) < 0.5) {
      for (int attempt = 0; attempt < 40 && !placed; ++attempt) {
        const SceneItem& anchor = scene.items[static_cast<size_t>(
            random::Canonical(rng) * scene.items.size())];
        const double dir = 2 * kPi * random::Canonical(rng);
        if (!PlaceAgainst(item, anchor, dir, 1.0, reach)) continue;
        placed = ClearOfOthers(item, scene.items, &anchor, false);
      }
    }
    if (!placed) placed = PlaceApart(item, scene.items, reach, false, rng);
    // A plate too full for this item: it is left off rather than drawn
    // intersecting another one.
    if (placed) scene.items.push_back(item);
  }
  return scene;
}

PlateScene CrowdedPlate(const std::vector<const FoodType*>& foods,
                        const PlateCrowding& crowding, std::mt19937_64& rng) {
  PlateScene scene;
  random::Normal gauss;
  const double well = kWellFraction * scene.plate_radius_m - kRimClearanceM;
  uint32_t next_id = 1;
  for (const FoodType* food : foods) {
    SceneItem item = DrawItem(food, next_id++, gauss, rng);
    const double reach = well - item.length_m / 2;
    const double draw = random::Canonical(rng);
    // The anchors this item may lean on or touch, by the rule drawn.
    std::vector<size_t> anchors;
    double fraction = 1.0;
    if (draw < crowding.overlap_probability &&
        item.height_m <= crowding.max_overlap_height_m) {
      for (size_t i = 0; i < scene.items.size(); ++i) {
        if (scene.items[i].base_m == 0.0 &&
            scene.items[i].height_m <= crowding.max_overlap_height_m) {
          anchors.push_back(i);
        }
      }
      fraction = 0.4 + 0.4 * random::Canonical(rng);
    } else if (draw < crowding.overlap_probability +
                          crowding.same_food_touch_probability) {
      for (size_t i = 0; i < scene.items.size(); ++i) {
        if (scene.items[i].food == food) anchors.push_back(i);
      }
    } else if (draw < crowding.overlap_probability +
                          crowding.same_food_touch_probability +
                          crowding.touch_probability) {
      for (size_t i = 0; i < scene.items.size(); ++i) anchors.push_back(i);
    }
    bool placed = false;
    for (int attempt = 0; attempt < 40 && !placed && !anchors.empty();
         ++attempt) {
      const SceneItem& anchor = scene.items[anchors[static_cast<size_t>(
          random::Canonical(rng) * anchors.size())]];
      const double dir = 2 * kPi * random::Canonical(rng);
      if (!PlaceAgainst(item, anchor, dir, fraction, reach)) continue;
      placed = ClearOfOthers(item, scene.items, &anchor, true);
      // Lying on the anchor: its underside rests on the anchor's top.
      item.base_m = fraction < 1.0 ? anchor.height_m : 0.0;
    }
    if (!placed) {
      item.base_m = 0.0;
      placed = PlaceApart(item, scene.items, reach, true, rng);
    }
    if (placed) scene.items.push_back(item);
  }
  return scene;
}

}  // namespace bitewise::sim
