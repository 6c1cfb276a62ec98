// Blind plates: see blind_plates.h. Written from a physical description
// only (plate, food, D415, light); every shape, colour and artefact model
// here is this file's own.
//
// Units: millimetres; world frame: origin at the plate centre on the well
// surface, z up. Each item is a rigid solid with a signed distance bound in
// its own (local) frame, placed by a rotation R and translation t
// (world = R * local + t).
#include "experiments/blind_plates.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "services/domain/random.h"

namespace bitewise::experiments {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kInf = std::numeric_limits<double>::infinity();

// ---------------------------------------------------------------------------
// Small vector algebra.

struct V3 {
  double x = 0.0, y = 0.0, z = 0.0;
};
inline V3 operator+(V3 a, V3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
inline V3 operator-(V3 a, V3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline V3 operator-(V3 a) { return {-a.x, -a.y, -a.z}; }
inline V3 operator*(V3 a, double s) { return {a.x * s, a.y * s, a.z * s}; }
inline double Dot(V3 a, V3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline V3 Cross(V3 a, V3 b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline double Length(V3 a) { return std::sqrt(Dot(a, a)); }
inline V3 Normalize(V3 a) {
  const double n = Length(a);
  return n > 0.0 ? a * (1.0 / n) : V3{0.0, 0.0, 1.0};
}
inline V3 Mul(V3 a, V3 b) { return {a.x * b.x, a.y * b.y, a.z * b.z}; }
inline double Clamp(double v, double lo, double hi) {
  return v < lo ? lo : (v > hi ? hi : v);
}
inline double Mix(double a, double b, double t) { return a + (b - a) * t; }
inline V3 Mix(V3 a, V3 b, double t) { return a + (b - a) * t; }
inline double Smoothstep(double e0, double e1, double x) {
  const double t = Clamp((x - e0) / (e1 - e0), 0.0, 1.0);
  return t * t * (3.0 - 2.0 * t);
}
inline double Fract(double x) { return x - std::floor(x); }
// sqrt(a^2 + b^2) without std::hypot's overflow care (slow, not needed at
// millimetre scales).
inline double Hypot(double a, double b) { return std::sqrt(a * a + b * b); }
inline double Luminance(V3 c) {
  return 0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z;
}

// Rotation matrix stored by rows.
struct M3 {
  V3 r0{1.0, 0.0, 0.0}, r1{0.0, 1.0, 0.0}, r2{0.0, 0.0, 1.0};
};
inline V3 Apply(const M3& m, V3 v) {
  return {Dot(m.r0, v), Dot(m.r1, v), Dot(m.r2, v)};
}
inline V3 ApplyT(const M3& m, V3 v) {
  return m.r0 * v.x + m.r1 * v.y + m.r2 * v.z;
}
M3 MatMul(const M3& a, const M3& b) {
  M3 out;
  out.r0 = b.r0 * a.r0.x + b.r1 * a.r0.y + b.r2 * a.r0.z;
  out.r1 = b.r0 * a.r1.x + b.r1 * a.r1.y + b.r2 * a.r1.z;
  out.r2 = b.r0 * a.r2.x + b.r1 * a.r2.y + b.r2 * a.r2.z;
  return out;
}
// Right-handed rotation by `angle` about the unit vector `axis`.
M3 Rotation(V3 axis, double angle) {
  const V3 k = Normalize(axis);
  const double c = std::cos(angle), s = std::sin(angle), v = 1.0 - c;
  M3 m;
  m.r0 = {c + k.x * k.x * v, k.x * k.y * v - k.z * s, k.x * k.z * v + k.y * s};
  m.r1 = {k.y * k.x * v + k.z * s, c + k.y * k.y * v, k.y * k.z * v - k.x * s};
  m.r2 = {k.z * k.x * v - k.y * s, k.z * k.y * v + k.x * s, c + k.z * k.z * v};
  return m;
}

// Ray against a sphere: the parameter interval inside it, if any.
bool RaySphere(V3 o, V3 d, V3 c, double r, double* t0, double* t1) {
  const V3 oc = o - c;
  const double b = Dot(oc, d);
  const double cc = Dot(oc, oc) - r * r;
  const double disc = b * b - cc;
  if (disc <= 0.0) return false;
  const double s = std::sqrt(disc);
  *t0 = -b - s;
  *t1 = -b + s;
  return true;
}

// ---------------------------------------------------------------------------
// Randomness: the project's portable draws on a mt19937_64.

class Draw {
 public:
  explicit Draw(uint64_t seed) : engine_(seed) {}
  double U() { return random::Uniform01(engine_); }
  double U(double lo, double hi) { return lo + (hi - lo) * U(); }
  int Index(int n) { return random::UniformIndex(engine_, n); }
  bool Chance(double p) { return U() < p; }
  double Normal() { return random::StandardNormal(engine_); }
  // A cheap unit-variance bell (sum of four 16-bit uniforms), for the
  // million per-pixel sensor-noise draws.
  double FastNormal() {
    const uint64_t bits = engine_();
    double sum = 0.0;
    for (int k = 0; k < 4; ++k) {
      sum +=
          (static_cast<double>((bits >> (16 * k)) & 0xffffu) + 0.5) / 65536.0;
    }
    return (sum - 2.0) * 1.7320508075688772;
  }
  uint32_t Bits32() { return static_cast<uint32_t>(engine_() >> 32); }

 private:
  random::Engine engine_;
};

// ---------------------------------------------------------------------------
// Procedural texture noise (hash-based value noise).

inline uint32_t HashU32(uint32_t x) {
  x ^= x >> 16;
  x *= 0x7feb352du;
  x ^= x >> 15;
  x *= 0x846ca68bu;
  x ^= x >> 16;
  return x;
}
inline double Hash01(int64_t i, int64_t j, int64_t k, uint32_t seed) {
  uint32_t h = HashU32(static_cast<uint32_t>(k) * 0xcb1ab31fu ^ seed);
  h = HashU32(static_cast<uint32_t>(j) * 0xd8163841u ^ h);
  h = HashU32(static_cast<uint32_t>(i) * 0x8da6b343u ^ h);
  return static_cast<double>(h) * (1.0 / 4294967296.0);
}
inline double Fade(double t) {
  return t * t * t * (t * (t * 6.0 - 15.0) + 10.0);
}

// Value noise in [0, 1], one feature per unit cell.
double Noise(V3 p, uint32_t seed) {
  const double fx = std::floor(p.x), fy = std::floor(p.y), fz = std::floor(p.z);
  const int64_t ix = static_cast<int64_t>(fx), iy = static_cast<int64_t>(fy),
                iz = static_cast<int64_t>(fz);
  const double ux = Fade(p.x - fx), uy = Fade(p.y - fy), uz = Fade(p.z - fz);
  double c[2][2][2];
  for (int a = 0; a < 2; ++a)
    for (int b = 0; b < 2; ++b)
      for (int e = 0; e < 2; ++e)
        c[a][b][e] = Hash01(ix + a, iy + b, iz + e, seed);
  const double x00 = Mix(c[0][0][0], c[1][0][0], ux);
  const double x10 = Mix(c[0][1][0], c[1][1][0], ux);
  const double x01 = Mix(c[0][0][1], c[1][0][1], ux);
  const double x11 = Mix(c[0][1][1], c[1][1][1], ux);
  return Mix(Mix(x00, x10, uy), Mix(x01, x11, uy), uz);
}

// Fractal sum of `octaves` noises, in [0, 1].
double Fbm(V3 p, int octaves, uint32_t seed) {
  double sum = 0.0, amp = 0.5, norm = 0.0;
  for (int o = 0; o < octaves; ++o) {
    sum += amp * Noise(p, seed + 977u * static_cast<uint32_t>(o));
    norm += amp;
    amp *= 0.5;
    p = p * 2.03 + V3{17.1, 5.3, 11.7};
  }
  return sum / norm;
}

// Distance to the nearest of the jittered points (one per cube of side
// `cell`): small dots such as strawberry seeds.
double NearestDot(V3 p, double cell, uint32_t seed) {
  const V3 q = p * (1.0 / cell);
  const int64_t ix = static_cast<int64_t>(std::floor(q.x));
  const int64_t iy = static_cast<int64_t>(std::floor(q.y));
  const int64_t iz = static_cast<int64_t>(std::floor(q.z));
  double best = kInf;
  for (int64_t a = ix - 1; a <= ix + 1; ++a)
    for (int64_t b = iy - 1; b <= iy + 1; ++b)
      for (int64_t e = iz - 1; e <= iz + 1; ++e) {
        const V3 f{
            static_cast<double>(a) + 0.15 + 0.7 * Hash01(a, b, e, seed),
            static_cast<double>(b) + 0.15 + 0.7 * Hash01(a, b, e, seed ^ 0x51u),
            static_cast<double>(e) + 0.15 +
                0.7 * Hash01(a, b, e, seed ^ 0xa7u)};
        const V3 d = q - f;
        best = std::min(best, Dot(d, d));
      }
  return std::sqrt(best) * cell;
}

// ---------------------------------------------------------------------------
// Colour. Albedos are written as the sRGB values a photo of the thing shows
// under neutral light and converted to linear reflectance.

double SrgbToLinear(double v) {
  const double c = Clamp(v / 255.0, 0.0, 1.0);
  return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4);
}
V3 Srgb(double r, double g, double b) {
  return {SrgbToLinear(r), SrgbToLinear(g), SrgbToLinear(b)};
}
// An sRGB colour drawn per channel from [lo, hi].
V3 SrgbBetween(Draw& rng, V3 lo, V3 hi) {
  const double t = rng.U();  // one shade parameter keeps hue coherent
  return Srgb(Mix(lo.x, hi.x, Clamp(t + rng.U(-0.15, 0.15), 0.0, 1.0)),
              Mix(lo.y, hi.y, Clamp(t + rng.U(-0.15, 0.15), 0.0, 1.0)),
              Mix(lo.z, hi.z, Clamp(t + rng.U(-0.15, 0.15), 0.0, 1.0)));
}

// ---------------------------------------------------------------------------
// Food pieces: shape (signed distance bound, local frame, resting with +z
// up) and surface colour.

enum FoodKind {
  kCarrot = 0,
  kCelery,
  kStrawberry,
  kCantaloupe,
  kBanana,
  kKiwi,
  kTomato,
  kGrape,
  kNumFoods
};

enum class Cut {
  kRoundStick,   // carrot: tapered cylinder along x
  kSquareStick,  // carrot: rounded box along x
  kDisc,         // carrot coin, banana slice, kiwi slice: elliptic disc
  kCeleryStick,  // U-section extruded along x
  kBerryWhole,   // round cone along x (tip at -x), calyx end cut flat
  kBerryHalf,    // the whole berry's z <= 0 half, cut face up
  kChunk,        // melon: rounded box, maybe one slanted face
  kKiwiHalf,     // half ellipsoid, cut face up (or down when flipped)
  kEllipsoid,    // cherry tomato, grape
};

struct Material {
  V3 albedo;
  double ks = 0.0;  // specular reflectance: Fresnel F0, 2-5 % for water,
                    // wax and glaze (energy-normalised Blinn-Phong)
  double shininess = 20.0;  // Blinn-Phong exponent
  double wrap = 0.0;        // diffuse wrap: light bleeding through flesh
  double bump = 0.0;        // normal jitter of a rough wet surface
};

struct Piece {
  FoodKind food = kCarrot;
  Cut cut = Cut::kDisc;
  bool flat = false;  // may be shingled (slice, coin, berry half, celery)
  // Geometry (mm). Discs/ellipsoids: semi-axes rx, ry, rz. Sticks and
  // celery: half length hx, half section ry, rz. Strawberry: r_tip,
  // r_shoulder, cone_h (centre distance), cut_x (calyx plane).
  double hx = 0.0, rx = 0.0, ry = 0.0, rz = 0.0, round = 0.0, taper = 0.0;
  double r_tip = 0.0, r_shoulder = 0.0, cone_h = 0.0, cut_x = 0.0;
  double wall = 0.0, wall_bottom = 0.0, ridge_amp = 0.0, ridge_period = 3.0;
  double bend = 0.0;
  V3 slant_n{0.0, 0.0, 1.0};
  double slant_off = kInf;
  bool flip = false;        // celery U opening down; kiwi half dome up
  bool cap = false;         // strawberry calyx present
  double step_scale = 0.9;  // sphere-tracing safety (Lipschitz bound)
  // Colour: up to four base colours and a few pattern parameters (meaning
  // per food, see Shade()).
  V3 col[4];
  double par[4] = {0.0, 0.0, 0.0, 0.0};
  V3 feature_dir{0.0, 0.0, 1.0};
  double ks = 0.1, shininess = 30.0, wrap = 0.0, bump = 0.0;
  uint32_t tex = 0;
};

inline double Extrude(double d2, double dz) {
  return std::min(std::max(d2, dz), 0.0) +
         Hypot(std::max(d2, 0.0), std::max(dz, 0.0));
}
// 1-Lipschitz lower bound of the distance to an ellipse (exact on it).
inline double EllipseBound(double x, double y, double a, double b) {
  return (Hypot(x / a, y / b) - 1.0) * std::min(a, b);
}
inline double EllipsoidBound(V3 p, V3 r) {
  return (Length({p.x / r.x, p.y / r.y, p.z / r.z}) - 1.0) *
         std::min(r.x, std::min(r.y, r.z));
}
inline double RoundBox(V3 p, V3 half, double r) {
  const V3 q{std::fabs(p.x) - half.x + r, std::fabs(p.y) - half.y + r,
             std::fabs(p.z) - half.z + r};
  const V3 qp{std::max(q.x, 0.0), std::max(q.y, 0.0), std::max(q.z, 0.0)};
  return Length(qp) + std::min(std::max(q.x, std::max(q.y, q.z)), 0.0) - r;
}
// Convex hull of two spheres on one axis: radius r1 at axial 0, r2 at
// axial h; `axial`, `radial` are the point's cylinder coordinates. The
// side's outward normal in (radial, axial) is n = (a, b), b = (r1-r2)/h.
inline double RoundCone(double axial, double radial, double r1, double r2,
                        double h) {
  const double b = (r1 - r2) / h;
  const double a = std::sqrt(std::max(0.0, 1.0 - b * b));
  const double k = -b * radial + a * axial;
  if (k < 0.0) return Hypot(radial, axial) - r1;
  if (k > a * h) return Hypot(radial, axial - h) - r2;
  return a * radial + b * axial - r1;
}

// A smooth bump per period, 0 at the period's ends and 1 in its middle
// (like (1 - cos)/2, without the cosine's cost).
inline double Ridge(double x) {
  const double u = Fract(x);
  const double v = u * (1.0 - u);
  return 16.0 * v * v;
}

// Celery section coordinates after the flip and the bend.
inline V3 CeleryFrame(const Piece& s, V3 p) {
  if (s.flip) p.z = -p.z;
  p.y -= s.bend * p.x * p.x;
  return p;
}
// The celery section's outer and inner ellipse bounds (U opening up, top
// at z = rz, bottom at z = -rz).
inline void CeleryParts(const Piece& s, V3 q, double* outer, double* inner) {
  const double depth = 2.0 * s.rz;
  const double groove = s.ridge_amp * Ridge(q.y / s.ridge_period);
  *outer = EllipseBound(q.y, q.z - s.rz, s.ry, depth) + groove;
  *inner = EllipseBound(q.y, q.z - s.rz, s.ry - s.wall, depth - s.wall_bottom);
}

double PieceSdf(const Piece& s, V3 p) {
  switch (s.cut) {
    case Cut::kRoundStick: {
      const double radial = Hypot(p.y, p.z);
      const double slope = s.ry * s.taper / s.hx;
      const double r = s.ry * (1.0 - s.taper * p.x / s.hx) - s.round;
      const double side = (radial - r) / std::sqrt(1.0 + slope * slope);
      return Extrude(side, std::fabs(p.x) - (s.hx - s.round)) - s.round;
    }
    case Cut::kSquareStick:
      return RoundBox(p, {s.hx, s.ry, s.rz}, s.round);
    case Cut::kDisc: {
      const double d2 = EllipseBound(p.x, p.y, s.rx - s.round, s.ry - s.round);
      return Extrude(d2, std::fabs(p.z) - (s.rz - s.round)) - s.round;
    }
    case Cut::kCeleryStick: {
      const V3 q = CeleryFrame(s, p);
      double outer, inner;
      CeleryParts(s, q, &outer, &inner);
      const double section = std::max(std::max(outer, -inner), q.z - s.rz);
      return Extrude(section, std::fabs(q.x) - s.hx);
    }
    case Cut::kBerryWhole:
    case Cut::kBerryHalf: {
      const double axial = p.x + 0.5 * s.cone_h;
      double d =
          RoundCone(axial, Hypot(p.y, p.z), s.r_tip, s.r_shoulder, s.cone_h);
      d = std::max(d, p.x - s.cut_x);
      if (s.cut == Cut::kBerryHalf) d = std::max(d, p.z);
      return d;
    }
    case Cut::kChunk: {
      const double d = RoundBox(p, {s.rx, s.ry, s.rz}, s.round);
      return std::max(d, Dot(p, s.slant_n) - s.slant_off);
    }
    case Cut::kKiwiHalf: {
      const double e = EllipsoidBound(p, {s.rx, s.ry, s.rz});
      return std::max(e, s.flip ? -p.z : p.z);
    }
    case Cut::kEllipsoid:
      return EllipsoidBound(p, {s.rx, s.ry, s.rz});
  }
  return kInf;
}

// Outward normal by the tetrahedron of central differences.
V3 PieceNormal(const Piece& s, V3 p) {
  constexpr double h = 0.02;
  const V3 k0{1, -1, -1}, k1{-1, -1, 1}, k2{-1, 1, -1}, k3{1, 1, 1};
  const V3 g = k0 * PieceSdf(s, p + k0 * h) + k1 * PieceSdf(s, p + k1 * h) +
               k2 * PieceSdf(s, p + k2 * h) + k3 * PieceSdf(s, p + k3 * h);
  return Normalize(g);
}

// Radius of the strawberry's round cone at local x (for the cut pattern).
double BerryRadiusAt(const Piece& s, double x) {
  const double axial = x + 0.5 * s.cone_h;
  const double t = Clamp(axial / s.cone_h, 0.0, 1.0);
  return Mix(s.r_tip, s.r_shoulder, t);
}

// Carrot flesh by the distance from the root's own axis (fraction of the
// root radius): pale core, a darker cambium ring, orange cortex, skin.
V3 CarrotFlesh(const Piece& s, double frac, V3 p, double angle) {
  const double core = s.par[0];
  V3 c = Mix(s.col[1], s.col[0], Smoothstep(core - 0.05, core + 0.03, frac));
  const double ring = std::exp(-std::pow((frac - core) / 0.035, 2.0));
  c = c * (1.0 - 0.3 * ring);
  const double streak = Noise(
      {std::cos(angle) * 5.0, std::sin(angle) * 5.0, frac * 3.0 + p.z * 0.05},
      s.tex);
  c = c * (0.9 + 0.2 * streak);
  if (frac > 0.95) c = Mix(c, s.col[2], Smoothstep(0.95, 1.0, frac));
  return c;
}

Material Shade(const Piece& s, V3 p, V3 n) {
  Material m;
  m.ks = s.ks;
  m.shininess = s.shininess;
  m.wrap = s.wrap;
  m.bump = s.bump;
  switch (s.food) {
    case kCarrot: {
      if (s.cut == Cut::kDisc) {
        const double frac = Hypot(p.x / s.rx, p.y / s.ry);
        const double angle = std::atan2(p.y / s.ry, p.x / s.rx);
        m.albedo = CarrotFlesh(s, frac, p, angle);
        if (std::fabs(n.z) < 0.6) {  // the skin around the coin
          const double grooves =
              Noise({p.x * 0.8, p.y * 0.8, p.z * 2.5}, s.tex);
          m.albedo = s.col[2] * (0.82 + 0.3 * grooves);
          m.ks = 0.02;
          m.shininess = 30.0;
        }
      } else {
        // A stick cut from a root of radius par[1] whose axis runs
        // parallel to the stick at (y, z) = (par[2], par[3]).
        const double dy = p.y - s.par[2], dz = p.z - s.par[3];
        const double frac = Hypot(dy, dz) / s.par[1];
        const double along = Noise({p.x * 0.12, dy * 1.2, dz * 1.2}, s.tex + 3);
        m.albedo = CarrotFlesh(s, frac, {0.0, 0.0, p.x}, std::atan2(dz, dy)) *
                   (0.88 + 0.24 * along);
      }
      break;
    }
    case kCelery: {
      const V3 q = CeleryFrame(s, p);
      double outer, inner;
      CeleryParts(s, q, &outer, &inner);
      const double lip = std::fabs(q.z - s.rz);
      const double end = std::fabs(std::fabs(q.x) - s.hx);
      const double streak = Noise({q.x * 0.08, q.y * 1.5, q.z * 1.5}, s.tex);
      if (end < 0.25 && end < std::fabs(outer) && end < std::fabs(inner)) {
        m.albedo = s.col[2] * (0.9 + 0.1 * streak);
        const double bundle = NearestDot(q * 1.0, 1.6, s.tex + 11);
        if (bundle < 0.35 && outer > -1.2) m.albedo = s.col[0] * 0.9;
      } else if (lip < std::fabs(outer) && lip < std::fabs(inner)) {
        m.albedo = Mix(s.col[0], s.col[1], 0.6) * (0.92 + 0.12 * streak);
      } else if (std::fabs(inner) < std::fabs(outer)) {
        m.albedo = s.col[1] * (0.9 + 0.15 * streak);
        m.ks = 0.02;
      } else {
        const double ridge = 1.0 - Ridge(q.y / s.ridge_period);
        m.albedo = s.col[0] * (0.8 + 0.15 * ridge + 0.15 * streak);
      }
      break;
    }
    case kStrawberry: {
      const double x_tip = -0.5 * s.cone_h - s.r_tip;
      const double along = Clamp((p.x - x_tip) / (s.cut_x - x_tip), 0.0, 1.0);
      V3 c = s.col[0] * (0.9 + 0.2 * Fbm(p * 0.25, 2, s.tex));
      c = Mix(c, s.col[1], s.par[0] * Smoothstep(0.7, 1.0, along));
      const bool on_cut_face =
          s.cut == Cut::kBerryHalf && p.z > -0.15 && n.z > 0.7;
      const bool on_calyx_plane = p.x > s.cut_x - 0.15 && n.x > 0.7;
      if (on_cut_face) {
        // The cut face: a red rim under the skin, lighter red-pink flesh
        // with streaks running to the seeds, a pale pith along the axis.
        const double r = std::max(BerryRadiusAt(s, p.x), 1.0);
        const double under_skin = r - std::fabs(p.y);  // mm
        const double lines =
            Noise({p.x * 0.25, std::fabs(p.y) * 1.2, 0.0}, s.tex + 5);
        const V3 flesh = Mix(s.col[0], Srgb(236, 120, 118), 0.55);
        const V3 pith = Srgb(246, 212, 204);
        c = Mix(s.col[0], flesh, Smoothstep(1.5, 3.5, under_skin));
        // The pith: widest under the calyx, ending short of the tip.
        const double x_tip = -0.5 * s.cone_h - s.r_tip;
        const double half_len = 0.45 * (s.cut_x - x_tip);
        const double u = (p.x - (s.cut_x - half_len)) / half_len;
        const double pith_w =
            0.3 * s.r_shoulder * std::sqrt(std::max(0.0, 1.0 - u * u));
        const double off = std::fabs(p.y) + 1.2 * (lines - 0.5);
        c = Mix(c, Mix(flesh, pith, 0.5),
                Smoothstep(pith_w + 3.0, pith_w, off));
        c = Mix(c, pith, Smoothstep(pith_w + 0.6, pith_w - 0.6, off));
        m.ks = 0.03;
        m.shininess = 200.0;
        m.bump = 0.05;
      } else if (on_calyx_plane) {
        c = s.cap ? s.col[3] * 0.8 : Mix(Srgb(245, 205, 195), s.col[0], 0.35);
      } else {
        const double seed = NearestDot(p, 2.4, s.tex + 7);
        if (seed < 0.42) {
          c = s.col[2];
          m.ks = 0.02;
        } else if (seed < 0.85) {
          c = c * 0.72;
        }
        if (s.cap) {
          // Sepals spread from the calyx over the shoulder.
          const double angle = std::atan2(p.z, p.y);
          const double lobe = std::pow(
              std::fabs(std::cos(angle * s.par[1] * 0.5 + s.par[2])), 3.0);
          const double reach = s.par[3] * (0.35 + 0.65 * lobe);
          if (s.cut_x - p.x < reach) {
            c = s.col[3] * (0.85 + 0.3 * Noise(p * 0.8, s.tex + 9));
            m.ks = 0.02;
          }
        }
      }
      m.albedo = c;
      break;
    }
    case kCantaloupe: {
      V3 c = s.col[0] * (0.9 + 0.18 * Fbm(p * 0.45, 2, s.tex));
      if (s.par[0] >= 0.0) {
        const int face = static_cast<int>(s.par[0]);
        double depth = 0.0;
        switch (face) {
          case 0:
            depth = s.rx - p.x;
            break;
          case 1:
            depth = s.rx + p.x;
            break;
          case 2:
            depth = s.ry - p.y;
            break;
          case 3:
            depth = s.ry + p.y;
            break;
          default:
            depth = s.rz - p.z;
            break;
        }
        const double rind = s.par[1];
        if (depth < 1.0) {
          const double net = std::fabs(Noise(p * 0.55, s.tex + 21) - 0.5);
          c = net < 0.07 ? s.col[2] : s.col[1] * (0.85 + 0.3 * Noise(p, s.tex));
          m.ks = 0.01;
          m.shininess = 20.0;
          m.wrap = 0.0;
        } else if (depth < rind) {
          c = Mix(s.col[3], c, Smoothstep(rind - 1.5, rind, depth));
        }
      }
      m.albedo = c;
      break;
    }
    case kBanana: {
      const double frac = Hypot(p.x / s.rx, p.y / s.ry);
      const double angle = std::atan2(p.y / s.ry, p.x / s.rx);
      V3 c = s.col[0] * (0.94 + 0.1 * Noise(p * 0.6, s.tex));
      if (std::fabs(n.z) > 0.6) {
        const double lobe =
            s.par[0] * (1.0 + 0.35 * std::cos(3.0 * (angle - s.par[1])));
        c = Mix(s.col[1], c, Smoothstep(lobe - 0.04, lobe + 0.04, frac));
        if (frac < lobe * 0.8) {
          const double dot = NearestDot({p.x, p.y, 0.0}, 1.3, s.tex + 4);
          if (dot < 0.22) c = s.col[2];
        }
        c = Mix(c, c * 1.04, Smoothstep(0.8, 0.98, frac));
      } else {
        c = c * (0.9 + 0.12 * Noise({angle * 4.0, p.z * 1.5, 0.0}, s.tex + 2));
      }
      m.albedo = c;
      break;
    }
    case kKiwi: {
      const bool face = s.cut == Cut::kDisc
                            ? std::fabs(n.z) > 0.6
                            : (!s.flip && p.z > -0.15 && n.z > 0.7);
      const double frac = Hypot(p.x / s.rx, p.y / s.ry);
      if (!face || frac > 0.97) {
        const double fuzz = Fbm(p * 1.3, 2, s.tex + 1);
        m.albedo = s.col[3] * (0.75 + 0.45 * fuzz);
        m.ks = 0.01;
        m.shininess = 20.0;
        m.wrap = 0.0;
        m.bump = 0.0;
        break;
      }
      const double angle = std::atan2(p.y / s.ry, p.x / s.rx);
      const double core = s.par[0];
      V3 c = s.col[0];
      const double rays =
          Noise({std::cos(angle) * 9.0, std::sin(angle) * 9.0, frac * 1.5},
                s.tex + 3);
      c = c * (0.88 + 0.25 * rays);
      c = Mix(c, Mix(s.col[0], s.col[1], 0.5),
              0.4 * Smoothstep(0.9, 0.7, frac) *
                  Smoothstep(core + 0.3, core + 0.15, frac));
      c = Mix(s.col[1], c, Smoothstep(core - 0.03, core + 0.05, frac));
      // Two rows of small black seeds around the core, elongated radially.
      const int count = static_cast<int>(s.par[1]);
      const double cell = 2.0 * kPi / count;
      const double ring_in = core + 0.06, ring_out = core + 0.24;
      const int ci = static_cast<int>(std::floor((angle + kPi) / cell));
      for (int k = ci - 1; k <= ci + 1 && frac < ring_out + 0.08; ++k) {
        for (int row = 0; row < 2; ++row) {
          const int kk = (k + count) % count;
          const double h1 = Hash01(kk, row, 1, s.tex),
                       h2 = Hash01(kk, row, 2, s.tex);
          const double a = -kPi + (k + 0.15 + 0.7 * h1) * cell;
          const double fr =
              Mix(ring_in, ring_out, row == 0 ? 0.25 * h2 : 0.5 + 0.45 * h2);
          const V3 centre{fr * s.rx * std::cos(a), fr * s.ry * std::sin(a),
                          0.0};
          const V3 radial{std::cos(a), std::sin(a), 0.0};
          const V3 off{p.x - centre.x, p.y - centre.y, 0.0};
          const double dr = Dot(off, radial);
          const double dt = off.x * -radial.y + off.y * radial.x;
          if ((dr / 0.95) * (dr / 0.95) + (dt / 0.5) * (dt / 0.5) < 1.0)
            c = s.col[2];
        }
      }
      m.albedo = c;
      break;
    }
    case kTomato: {
      V3 c = s.col[0] * (0.94 + 0.1 * Fbm(p * 0.3, 2, s.tex));
      if (s.par[0] > 0.5) {
        const double k =
            Dot(Normalize(Mul(p, {1.0 / s.rx, 1.0 / s.ry, 1.0 / s.rz})),
                s.feature_dir);
        if (k > 0.992) {
          c = s.col[1];
        } else if (k > 0.96) {
          c = Mix(c, s.col[2], 0.5 * Smoothstep(0.96, 0.985, k));
        }
      }
      m.albedo = c;
      break;
    }
    case kGrape: {
      V3 c = s.col[0] * (0.92 + 0.14 * Fbm(p * 0.35, 2, s.tex));
      if (s.par[0] > 0.0) {
        c = Mix(c, s.col[1], s.par[0] * Fbm(p * 0.9, 2, s.tex + 1));
      }
      const double k =
          Normalize(Mul(p, {1.0 / s.rx, 1.0 / s.ry, 1.0 / s.rz})).x;
      if (k > 0.985) c = s.col[2];
      m.albedo = c;
      break;
    }
    default:
      m.albedo = {0.5, 0.5, 0.5};
  }
  return m;
}

// ---------------------------------------------------------------------------
// Drawing one piece of a food, as a caregiver cuts it.

Piece MakePiece(FoodKind food, Draw& rng) {
  Piece s;
  s.food = food;
  s.tex = rng.Bits32();
  switch (food) {
    case kCarrot: {
      s.col[0] = SrgbBetween(rng, {222, 92, 10}, {246, 148, 48});
      s.col[1] = Mix(s.col[0], Srgb(250, 192, 85), rng.U(0.3, 0.6));
      s.col[2] = s.col[0] * rng.U(0.7, 0.88);
      s.par[0] = rng.U(0.38, 0.58);
      s.ks = 0.025;
      s.shininess = 150.0;
      s.wrap = 0.15;
      s.bump = 0.05;
      if (rng.Chance(0.5)) {
        s.hx = rng.U(25.0, 40.0);
        const double section = rng.U(8.0, 13.0);
        if (rng.Chance(0.5)) {
          // A thin peeled root or its tip: round, tapering, its own axis.
          s.cut = Cut::kRoundStick;
          s.ry = s.rz = 0.5 * section;
          s.taper = rng.U(0.0, 0.12);
          s.round = 1.0;
          s.par[1] = s.ry;
        } else {
          // Cut lengthwise from a thick root whose axis lies beside it.
          s.cut = Cut::kSquareStick;
          s.ry = 0.5 * section * rng.U(0.9, 1.1);
          s.rz = 0.5 * section * rng.U(0.85, 1.05);
          s.round = 1.2;
          const double corner = Hypot(s.ry, s.rz);
          s.par[1] = std::max(rng.U(11.0, 17.0), corner + 1.0);
          const double off = rng.U(0.0, s.par[1] - corner);
          const double a = rng.U(0.0, 2.0 * kPi);
          s.par[2] = off * std::cos(a);
          s.par[3] = off * std::sin(a);
        }
      } else {
        s.cut = Cut::kDisc;
        s.flat = true;
        s.rx = rng.U(10.0, 15.0);
        s.ry = s.rx * rng.U(0.85, 1.0);
        s.rz = rng.U(2.5, 4.0);
        s.round = 0.8;
      }
      break;
    }
    case kCelery: {
      s.cut = Cut::kCeleryStick;
      s.flat = true;
      s.hx = rng.U(25.0, 45.0);
      s.ry = rng.U(5.0, 10.0);
      s.rz = rng.U(3.0, 6.0);
      s.wall = std::min(rng.U(2.0, 3.2), s.ry - 1.5);
      s.wall_bottom = std::min(rng.U(2.5, 4.0), 2.0 * s.rz - 1.5);
      s.ridge_amp = rng.U(0.2, 0.45);
      s.ridge_period = rng.U(2.4, 3.6);
      s.bend = (rng.Chance(0.5) ? 1.0 : -1.0) * rng.U(0.0, 3.0) / (s.hx * s.hx);
      s.flip = rng.Chance(0.25);
      s.step_scale = 0.7;
      s.col[0] = SrgbBetween(rng, {100, 148, 58}, {178, 208, 122});
      s.col[1] = Mix(s.col[0], Srgb(226, 236, 196), rng.U(0.5, 0.75));
      s.col[2] = Mix(s.col[0], Srgb(232, 240, 212), 0.6);
      s.ks = 0.035;
      s.shininess = 60.0;
      s.wrap = 0.1;
      s.bump = 0.04;
      break;
    }
    case kStrawberry: {
      const double length = rng.U(25.0, 40.0);
      s.r_shoulder = 0.5 * length * rng.U(0.7, 0.9);
      s.r_tip = rng.U(2.5, 4.5);
      s.cap = rng.Chance(0.6);
      const double trim = s.cap ? rng.U(1.0, 2.5) : rng.U(2.5, 5.0);
      s.cone_h = std::max(length - s.r_tip - s.r_shoulder + trim,
                          s.r_shoulder - s.r_tip + 2.0);
      s.cut_x = 0.5 * s.cone_h + s.r_shoulder - trim;
      if (rng.Chance(0.45)) {
        s.cut = Cut::kBerryHalf;
        s.flat = true;
      } else {
        s.cut = Cut::kBerryWhole;
      }
      s.col[0] = SrgbBetween(rng, {150, 8, 18}, {226, 46, 50});
      s.col[1] = Srgb(rng.U(225, 245), rng.U(175, 210), rng.U(150, 180));
      s.par[0] = rng.Chance(0.35) ? rng.U(0.3, 0.8) : 0.0;
      s.col[2] = SrgbBetween(rng, {178, 148, 48}, {226, 202, 92});
      s.col[3] = SrgbBetween(rng, {48, 92, 28}, {104, 144, 58});
      s.par[1] = 8 + rng.Index(4);
      s.par[2] = rng.U(0.0, kPi);
      s.par[3] = rng.U(3.0, 6.0);
      s.ks = 0.04;
      s.shininess = 500.0;
      s.wrap = 0.2;
      s.bump = 0.04;
      break;
    }
    case kCantaloupe: {
      s.cut = Cut::kChunk;
      s.rx = rng.U(9.0, 15.0);
      s.ry = rng.U(9.0, 15.0);
      s.rz = rng.U(9.0, 15.0);
      s.round = rng.U(1.2, 2.5);
      if (rng.Chance(0.4)) {
        const double tilt = rng.U(0.45, 0.9), az = rng.U(0.0, 2.0 * kPi);
        s.slant_n = {std::sin(tilt) * std::cos(az),
                     std::sin(tilt) * std::sin(az), std::cos(tilt)};
        const V3 corner{s.slant_n.x > 0 ? s.rx : -s.rx,
                        s.slant_n.y > 0 ? s.ry : -s.ry, s.rz};
        s.slant_off = Dot(corner, s.slant_n) - rng.U(3.0, 7.0);
      }
      s.par[0] = rng.Chance(0.4) ? rng.Index(5) : -1.0;
      s.par[1] = rng.U(2.5, 4.5);
      s.col[0] = SrgbBetween(rng, {238, 148, 78}, {255, 196, 128});
      s.col[1] = SrgbBetween(rng, {160, 158, 102}, {206, 196, 146});
      s.col[2] = Srgb(216, 206, 172);
      s.col[3] = SrgbBetween(rng, {168, 194, 118}, {212, 222, 162});
      s.ks = 0.025;
      s.shininess = 150.0;
      s.wrap = 0.35;
      s.bump = 0.06;
      break;
    }
    case kBanana: {
      s.cut = Cut::kDisc;
      s.flat = true;
      s.rx = rng.U(12.5, 17.5);
      s.ry = s.rx * rng.U(0.9, 1.0);
      s.rz = rng.U(4.0, 7.5);
      s.round = std::min(rng.U(1.2, 2.0), s.rz - 0.5);
      s.par[0] = rng.U(0.15, 0.25);
      s.par[1] = rng.U(0.0, 2.0 * kPi);
      s.col[0] = SrgbBetween(rng, {234, 224, 168}, {250, 243, 206});
      s.col[1] = Mix(s.col[0], Srgb(214, 194, 128), rng.U(0.35, 0.65));
      s.col[2] = Srgb(122, 96, 60);
      s.ks = 0.02;
      s.shininess = 60.0;
      s.wrap = 0.25;
      s.bump = 0.04;
      break;
    }
    case kKiwi: {
      s.rx = rng.U(20.0, 27.5);
      s.ry = s.rx * rng.U(0.78, 0.95);
      if (rng.Chance(0.75)) {
        s.cut = Cut::kDisc;
        s.flat = true;
        s.rz = rng.U(3.0, 6.0);
        s.round = 0.6;
      } else {
        s.cut = Cut::kKiwiHalf;
        s.rz = rng.U(24.0, 32.0);
        s.flip = rng.Chance(0.3);
      }
      s.col[0] = SrgbBetween(rng, {98, 148, 18}, {162, 202, 62});
      s.col[1] = Srgb(rng.U(222, 242), rng.U(224, 240), rng.U(165, 200));
      s.col[2] = Srgb(26, 20, 12);
      s.col[3] = SrgbBetween(rng, {92, 68, 38}, {142, 106, 62});
      s.par[0] = rng.U(0.17, 0.27);
      s.par[1] = 50 + rng.Index(40);
      s.ks = 0.03;
      s.shininess = 200.0;
      s.wrap = 0.3;
      s.bump = 0.06;
      break;
    }
    case kTomato: {
      s.cut = Cut::kEllipsoid;
      s.rx = rng.U(10.0, 15.0);
      s.ry = s.rx * rng.U(0.95, 1.03);
      s.rz = s.rx * rng.U(0.85, 0.95);
      s.par[0] = rng.Chance(0.6) ? 1.0 : 0.0;
      const double tilt = rng.U(0.0, 1.2), az = rng.U(0.0, 2.0 * kPi);
      s.feature_dir = {std::sin(tilt) * std::cos(az),
                       std::sin(tilt) * std::sin(az), std::cos(tilt)};
      s.col[0] = SrgbBetween(rng, {184, 20, 14}, {236, 62, 36});
      s.col[1] = Srgb(96, 120, 46);
      s.col[2] = Srgb(222, 142, 42);
      s.ks = 0.05;
      s.shininess = 2000.0;
      s.bump = 0.004;
      s.wrap = 0.15;
      break;
    }
    case kGrape:
    default: {
      s.cut = Cut::kEllipsoid;
      s.rx = rng.U(8.0, 12.5);
      s.ry = s.rx * rng.U(0.72, 0.9);
      s.rz = s.ry * rng.U(0.93, 1.0);
      if (rng.Chance(0.5)) {
        s.col[0] = SrgbBetween(rng, {148, 184, 68}, {196, 216, 116});
        s.ks = 0.045;
        s.shininess = 1000.0;
        s.bump = 0.006;
        s.wrap = 0.45;
      } else {
        s.col[0] = SrgbBetween(rng, {58, 14, 38}, {132, 42, 72});
        s.col[1] = Srgb(150, 122, 152);
        s.par[0] = rng.U(0.2, 0.55);
        s.ks = 0.03;
        s.shininess = 60.0;
        s.wrap = 0.2;
      }
      s.col[2] = Srgb(112, 90, 52);
      break;
    }
  }
  return s;
}

// Local bounding box (min and max corners) of a piece.
void PieceBox(const Piece& s, V3* lo, V3* hi) {
  V3 h;
  switch (s.cut) {
    case Cut::kRoundStick:
      h = {s.hx, s.ry * (1.0 + s.taper), s.ry * (1.0 + s.taper)};
      break;
    case Cut::kSquareStick:
      h = {s.hx, s.ry, s.rz};
      break;
    case Cut::kCeleryStick:
      h = {s.hx, s.ry + std::fabs(s.bend) * s.hx * s.hx, s.rz};
      break;
    case Cut::kBerryWhole:
    case Cut::kBerryHalf: {
      *lo = {-0.5 * s.cone_h - s.r_tip, -s.r_shoulder, -s.r_shoulder};
      *hi = {s.cut_x, s.r_shoulder, s.r_shoulder};
      return;
    }
    default:
      h = {s.rx, s.ry, s.rz};
  }
  *lo = -h;
  *hi = h;
}

// ---------------------------------------------------------------------------
// Items: a piece, its surface samples (for contact and support), and its
// pose.

struct Pose {
  M3 R;
  V3 t;
};

struct Item {
  Piece piece;
  std::vector<V3> pts;     // points on the surface, local frame
  std::vector<V3> coarse;  // every fourth of them, for quick searches
  V3 com;                  // centroid of the solid, local frame
  double radius = 0.0;     // bounding sphere about the local origin
  std::array<double, 3> size{};
  M3 base;  // the piece's own roll/flip before the yaw
  Pose pose;
  int lies_on = -1;
};

V3 SdfGradient(const Piece& s, V3 p) {
  constexpr double h = 0.01;
  return {
      (PieceSdf(s, p + V3{h, 0, 0}) - PieceSdf(s, p - V3{h, 0, 0})) / (2 * h),
      (PieceSdf(s, p + V3{0, h, 0}) - PieceSdf(s, p - V3{0, h, 0})) / (2 * h),
      (PieceSdf(s, p + V3{0, 0, h}) - PieceSdf(s, p - V3{0, 0, h})) / (2 * h)};
}

Item MakeItem(const Piece& piece, Draw& rng) {
  Item it;
  it.piece = piece;
  V3 lo, hi;
  PieceBox(piece, &lo, &hi);
  lo = lo - V3{1.0, 1.0, 1.0};
  hi = hi + V3{1.0, 1.0, 1.0};
  constexpr double kStep = 1.1;
  V3 sum;
  int inside = 0;
  V3 ext_lo{kInf, kInf, kInf}, ext_hi{-kInf, -kInf, -kInf};
  for (double x = lo.x; x <= hi.x; x += kStep) {
    for (double y = lo.y; y <= hi.y; y += kStep) {
      for (double z = lo.z; z <= hi.z; z += kStep) {
        V3 p{x, y, z};
        const double d = PieceSdf(piece, p);
        if (d < 0.0) {
          sum = sum + p;
          ++inside;
        }
        if (std::fabs(d) > 0.5 * kStep) continue;
        // Newton steps onto the surface.
        for (int k = 0; k < 4; ++k) {
          const double f = PieceSdf(piece, p);
          if (std::fabs(f) < 1e-3) break;
          const V3 g = SdfGradient(piece, p);
          const double gg = Dot(g, g);
          if (gg < 1e-8) break;
          p = p - g * (f / gg);
        }
        if (std::fabs(PieceSdf(piece, p)) > 0.02) continue;
        it.pts.push_back(p);
        ext_lo = {std::min(ext_lo.x, p.x), std::min(ext_lo.y, p.y),
                  std::min(ext_lo.z, p.z)};
        ext_hi = {std::max(ext_hi.x, p.x), std::max(ext_hi.y, p.y),
                  std::max(ext_hi.z, p.z)};
      }
    }
  }
  for (size_t k = 0; k < it.pts.size(); k += 4) it.coarse.push_back(it.pts[k]);
  it.com = inside > 0 ? sum * (1.0 / inside) : V3{};
  for (const V3& p : it.pts) it.radius = std::max(it.radius, Length(p));
  it.radius += 0.6;
  const double ex = ext_hi.x - ext_lo.x, ey = ext_hi.y - ext_lo.y;
  it.size = {std::max(ex, ey), std::min(ex, ey), ext_hi.z - ext_lo.z};
  // The piece's own roll: round things show any side up.
  switch (piece.cut) {
    case Cut::kRoundStick:
    case Cut::kBerryWhole:
      it.base = Rotation({1, 0, 0}, rng.U(0.0, 2.0 * kPi));
      break;
    case Cut::kEllipsoid:
      if (piece.food == kGrape) {
        it.base = Rotation({1, 0, 0}, rng.U(-0.4, 0.4));
      }
      break;
    default:
      break;
  }
  return it;
}

// True when neither item's samples lie deeper than -margin inside the other
// (margin > 0: a gap of at least margin; margin < 0: a tolerance).
bool Clear(const Item& a, const Pose& pa, const Item& b, const Pose& pb,
           double margin, bool coarse = false) {
  const V3 dc = pa.t - pb.t;
  const double reach = a.radius + b.radius + std::max(margin, 0.0);
  if (Dot(dc, dc) > reach * reach) return true;
  const double rb = b.radius + std::max(margin, 0.0);
  for (const V3& p : coarse ? a.coarse : a.pts) {
    const V3 w = Apply(pa.R, p) + pa.t - pb.t;
    if (Dot(w, w) > rb * rb) continue;
    if (PieceSdf(b.piece, ApplyT(pb.R, w)) < margin) return false;
  }
  const double ra = a.radius + std::max(margin, 0.0);
  for (const V3& p : coarse ? b.coarse : b.pts) {
    const V3 w = Apply(pb.R, p) + pb.t - pa.t;
    if (Dot(w, w) > ra * ra) continue;
    if (PieceSdf(a.piece, ApplyT(pa.R, w)) < margin) return false;
  }
  return true;
}

// Smallest distance bound from `a`'s samples to `b`'s surface.
double Gap(const Item& a, const Pose& pa, const Item& b) {
  double best = kInf;
  const V3 dc = pa.t - b.pose.t;
  if (Length(dc) > a.radius + b.radius + 2.0) return best;
  for (const V3& p : a.pts) {
    const V3 w = Apply(pa.R, p) + pa.t - b.pose.t;
    if (Dot(w, w) > (b.radius + 2.0) * (b.radius + 2.0)) continue;
    best = std::min(best, PieceSdf(b.piece, ApplyT(b.pose.R, w)));
  }
  return best;
}

bool InWell(const Item& a, const Pose& pa, double well_radius) {
  const double limit = (well_radius - 1.0) * (well_radius - 1.0);
  for (const V3& p : a.pts) {
    const V3 w = Apply(pa.R, p) + pa.t;
    if (w.x * w.x + w.y * w.y > limit) return false;
  }
  return true;
}

constexpr double kTolerance = 0.03;  // allowed sample penetration, mm

// Lowest height of `pose` (rotation and x, y given) at which the item rests
// on the well (z >= 0) without penetrating any of `items` (`coarse`: on a
// quarter of the surface samples, for searches).
double DropZ(const Item& a, Pose pose, const std::vector<Item>& items,
             bool coarse = false) {
  double zmin = kInf;
  for (const V3& p : a.pts) zmin = std::min(zmin, Apply(pose.R, p).z);
  double lo = -zmin;
  std::vector<const Item*> near;
  for (const Item& b : items) {
    if (Hypot(b.pose.t.x - pose.t.x, b.pose.t.y - pose.t.y) <
        a.radius + b.radius) {
      near.push_back(&b);
    }
  }
  auto is_free = [&](double z) {
    pose.t.z = z;
    for (const Item* b : near) {
      if (!Clear(a, pose, *b, b->pose, -kTolerance, coarse)) return false;
    }
    return true;
  };
  if (is_free(lo)) return lo;
  double hi = lo;
  for (const Item* b : near) {
    hi = std::max(hi, b->pose.t.z + b->radius + a.radius + 0.5);
  }
  while (hi - lo > 0.01) {
    const double mid = 0.5 * (lo + hi);
    if (is_free(mid)) {
      hi = mid;
    } else {
      lo = mid;
    }
  }
  return hi;
}

// Over rotations by [a0, a1] (step) about the horizontal `axis` applied to
// `base`: the resting pose at (x, y) with the lowest centre of mass.
Pose Settle(const Item& a, const M3& base, double x, double y, V3 axis,
            double a0, double a1, double step,
            const std::vector<Item>& obstacles, bool coarse = false) {
  Pose best;
  double best_com = kInf;
  for (double ang = a0; ang <= a1 + 1e-9; ang += step) {
    Pose pose;
    pose.R = ang == 0.0 ? base : MatMul(Rotation(axis, ang), base);
    pose.t = {x, y, 0.0};
    pose.t.z = DropZ(a, pose, obstacles, coarse);
    const double com = Apply(pose.R, a.com).z + pose.t.z;
    if (com < best_com - 1e-6) {
      best_com = com;
      best = pose;
    }
    if (step <= 0.0) break;
  }
  return best;
}

// The item alone on the well at yaw `yaw`, in its stable pose.
Pose RestPose(const Item& a, double yaw) {
  const M3 yaw_m = Rotation({0, 0, 1}, yaw);
  const M3 base = MatMul(yaw_m, a.base);
  const V3 axis = Apply(yaw_m, {0, 1, 0});
  static const std::vector<Item> kNone;
  switch (a.piece.cut) {
    case Cut::kBerryWhole:
    case Cut::kBerryHalf: {
      const Pose coarse = Settle(a, base, 0, 0, axis, -0.6, 0.6, 0.04, kNone);
      // Refine around the coarse optimum.
      Pose best = coarse;
      double best_com = Apply(coarse.R, a.com).z + coarse.t.z;
      for (double ang = -0.04; ang <= 0.04 + 1e-9; ang += 0.01) {
        Pose p = Settle(a, MatMul(Rotation(axis, ang), coarse.R), 0, 0, axis,
                        0.0, 0.0, 0.0, kNone);
        const double com = Apply(p.R, a.com).z + p.t.z;
        if (com < best_com - 1e-6) {
          best_com = com;
          best = p;
        }
      }
      return best;
    }
    case Cut::kRoundStick:
      return Settle(a, base, 0, 0, axis, -0.1, 0.1, 0.01, kNone);
    default:
      return Settle(a, base, 0, 0, axis, 0.0, 0.0, 0.0, kNone);
  }
}

bool ClearOfAll(const Item& a, const Pose& pose, const std::vector<Item>& items,
                double margin) {
  for (const Item& b : items) {
    if (!Clear(a, pose, b, b.pose, margin)) return false;
  }
  return true;
}

// Horizontal distance from b's centre along `dir` at which `a` (resting in
// `rest`) just touches b.
double TouchDistance(const Item& a, const Pose& rest, const Item& b, V3 dir) {
  double lo = 0.0, hi = a.radius + b.radius + 0.5;
  Pose pose = rest;
  while (hi - lo > 0.01) {
    const double mid = 0.5 * (lo + hi);
    pose.t = {b.pose.t.x + dir.x * mid, b.pose.t.y + dir.y * mid, rest.t.z};
    if (Clear(a, pose, b, b.pose, -kTolerance)) {
      hi = mid;
    } else {
      lo = mid;
    }
  }
  return hi;
}

// Up to `attempts` poses from `draw`: the first inside the well and clear
// of every other item by `clearance` mm is taken.
template <typename DrawPose>
bool PlaceFirstClear(Item& a, const std::vector<Item>& items,
                     double well_radius, double clearance, int attempts,
                     DrawPose draw) {
  for (int attempt = 0; attempt < attempts; ++attempt) {
    const Pose pose = draw();
    if (!InWell(a, pose, well_radius)) continue;
    if (!ClearOfAll(a, pose, items, clearance)) continue;
    a.pose = pose;
    return true;
  }
  return false;
}

bool PlaceApart(Item& a, const std::vector<Item>& items, double well_radius,
                Draw& rng) {
  return PlaceFirstClear(a, items, well_radius, 2.5, 120, [&] {
    Pose pose = RestPose(a, rng.U(0.0, 2.0 * kPi));
    const double r = (well_radius - 4.0) * std::sqrt(rng.U());
    const double th = rng.U(0.0, 2.0 * kPi);
    pose.t.x = r * std::cos(th);
    pose.t.y = r * std::sin(th);
    return pose;
  });
}

bool PlaceTouching(Item& a, const std::vector<int>& targets,
                   const std::vector<Item>& items, double well_radius,
                   Draw& rng) {
  if (targets.empty()) return false;
  return PlaceFirstClear(a, items, well_radius, -kTolerance, 30, [&] {
    const Item& b = items[targets[rng.Index(static_cast<int>(targets.size()))]];
    Pose pose = RestPose(a, rng.U(0.0, 2.0 * kPi));
    const double psi = rng.U(0.0, 2.0 * kPi);
    const V3 dir{std::cos(psi), std::sin(psi), 0.0};
    const double d = TouchDistance(a, pose, b, dir) + 0.1;
    pose.t = {b.pose.t.x + dir.x * d, b.pose.t.y + dir.y * d, pose.t.z};
    return pose;
  });
}

// A flat piece partly on a flat item: centre 40-80 % of the touching
// distance away, dropped onto it and tipped about the horizontal axis
// across the offset until its centre of mass is lowest.
bool PlaceShingled(Item& a, const std::vector<int>& targets,
                   const std::vector<Item>& items, double well_radius,
                   Draw& rng) {
  if (targets.empty()) return false;
  for (int attempt = 0; attempt < 20; ++attempt) {
    const int j = targets[rng.Index(static_cast<int>(targets.size()))];
    const Item& b = items[j];
    const Pose rest = RestPose(a, rng.U(0.0, 2.0 * kPi));
    const double psi = rng.U(0.0, 2.0 * kPi);
    const V3 dir{std::cos(psi), std::sin(psi), 0.0};
    const double d = TouchDistance(a, rest, b, dir) * rng.U(0.4, 0.8);
    const double x = b.pose.t.x + dir.x * d, y = b.pose.t.y + dir.y * d;
    const V3 axis{-dir.y, dir.x, 0.0};  // +angle lifts the side toward b
    {
      Pose flat = rest;
      flat.t = {x, y, rest.t.z};
      if (!InWell(a, flat, well_radius + 4.0)) continue;
    }
    // Coarse samples find the angle; the full set gives the final height.
    Pose pose = Settle(a, rest.R, x, y, axis, 0.0, 0.64, 0.08, items, true);
    for (double step : {0.04, 0.02}) {
      const Pose centre = pose;
      double best_com = Apply(pose.R, a.com).z + pose.t.z;
      for (double ang : {-step, step}) {
        Pose p = Settle(a, MatMul(Rotation(axis, ang), centre.R), x, y, axis,
                        0.0, 0.0, 0.0, items, true);
        const double com = Apply(p.R, a.com).z + p.t.z;
        if (com < best_com - 1e-6) {
          best_com = com;
          pose = p;
        }
      }
    }
    pose.t.z = DropZ(a, pose, items);
    if (!InWell(a, pose, well_radius)) continue;
    // It must rest on b (it may lean on others too).
    if (Gap(a, pose, b) > 0.3) continue;
    a.pose = pose;
    a.lies_on = j;
    return true;
  }
  return false;
}

// ---------------------------------------------------------------------------
// The scene around the food: plate, table, camera, light.

struct Scene {
  // Plate: well radius, outer radius, rim height over the well, and the
  // table's depth below the well surface (positive).
  double plate_r = 120.0, well_r = 95.0, rim_h = 15.0, base_z = 8.0;
  double rim_slope = 1.0;  // largest |dH/dr| of the rim
  V3 plate_albedo;
  double plate_ks = 0.05, plate_shininess = 40.0;
  uint32_t plate_tex = 0;
  // Table and placemat.
  int table_pattern = 0;
  V3 table_a, table_b;
  double table_scale = 10.0, table_angle = 0.0;
  uint32_t table_tex = 0;
  bool mat = false;
  int mat_pattern = 0;
  V3 mat_a, mat_b;
  double mat_cx = 0.0, mat_cy = 0.0, mat_hx = 0.0, mat_hy = 0.0,
         mat_angle = 0.0, mat_scale = 3.0;
  // Camera: centre, image axes (x right, y down, z forward), intrinsics.
  V3 cam, ax, ay, az;
  double axis_distance = 350.0;
  sim::PinholeIntrinsics in;
  // Light (linear radiance units; exposure maps them to the sensor).
  // A light's size also widens the highlight it leaves on a glossy
  // surface: *_lobe is the Blinn-Phong exponent of the source's own disc,
  // combined with the surface's (1/n = 1/n_surface + 1/n_source).
  V3 lamp_pos, lamp_col;
  double lamp_soft = 30.0, lamp_lobe = 1000.0;
  V3 win_dir, win_col;
  double win_soft = 8.0, win_lobe = 25.0;
  V3 sky_col;
  double exposure = 1.0;
  V3 gains{1.0, 1.0, 1.0};
  double vignette = 0.1;
  double blur_sigma = 0.6;
};

// Height of the plate's top surface at radius r (inside the plate).
inline double PlateHeight(const Scene& sc, double r) {
  if (r <= sc.well_r) return 0.0;
  const double u = std::min(1.0, (r - sc.well_r) / (sc.plate_r - sc.well_r));
  return sc.rim_h * 0.5 * (1.0 - std::cos(kPi * u));
}
inline double PlateSlope(const Scene& sc, double r) {
  if (r <= sc.well_r || r >= sc.plate_r) return 0.0;
  const double w = sc.plate_r - sc.well_r;
  return sc.rim_h * 0.5 * kPi / w * std::sin(kPi * (r - sc.well_r) / w);
}

Scene MakeScene(Draw& rng) {
  Scene sc;
  sc.in = sim::D415Intrinsics();
  // Plate.
  sc.plate_r = 0.5 * rng.U(220.0, 270.0);
  const double rim_w = rng.U(20.0, 30.0);
  sc.well_r = sc.plate_r - rim_w;
  sc.rim_h = rng.U(10.0, 20.0);
  sc.base_z = rng.U(5.0, 12.0);
  sc.rim_slope = 1.05 * sc.rim_h * 0.5 * kPi / rim_w;
  const V3 white = Srgb(238, 238, 234), cream = Srgb(240, 228, 200),
           grey = Srgb(205, 207, 210);
  const double which = rng.U();
  sc.plate_albedo = which < 0.5   ? Mix(white, cream, rng.U(0.0, 0.5))
                    : which < 0.8 ? Mix(cream, white, rng.U(0.0, 0.4))
                                  : Mix(grey, white, rng.U(0.0, 0.6));
  sc.plate_albedo = sc.plate_albedo * rng.U(0.88, 1.0);
  sc.plate_ks = rng.U(0.035, 0.055);
  sc.plate_shininess = rng.U(30.0, 90.0);
  sc.plate_tex = rng.Bits32();
  // Table (wood, laminate, cloth) and maybe a placemat of any colour.
  sc.table_pattern = rng.Index(4);
  {
    const double hue = rng.U(), sat = rng.U(0.1, 0.8), val = rng.U(40, 230);
    auto hsv = [](double h, double s, double v) {
      const double r = Clamp(std::fabs(h * 6.0 - 3.0) - 1.0, 0.0, 1.0);
      const double g = Clamp(2.0 - std::fabs(h * 6.0 - 2.0), 0.0, 1.0);
      const double b = Clamp(2.0 - std::fabs(h * 6.0 - 4.0), 0.0, 1.0);
      return Srgb(v * Mix(1.0, r, s), v * Mix(1.0, g, s), v * Mix(1.0, b, s));
    };
    if (sc.table_pattern == 1) {  // wood
      sc.table_a = SrgbBetween(rng, {120, 72, 38}, {205, 158, 105});
      sc.table_b = sc.table_a * rng.U(0.55, 0.8);
    } else {
      sc.table_a = hsv(hue, sat, val);
      sc.table_b =
          hsv(Fract(hue + rng.U(-0.08, 0.08)), sat, val * rng.U(0.6, 0.95));
    }
    sc.table_scale = rng.U(2.0, 12.0);
    sc.table_angle = rng.U(0.0, kPi);
    sc.table_tex = rng.Bits32();
    sc.mat = rng.Chance(0.5);
    sc.mat_pattern = rng.Index(3);
    sc.mat_a = hsv(rng.U(), rng.U(0.0, 0.9), rng.U(50, 235));
    sc.mat_b = sc.mat_a * rng.U(0.6, 0.95);
    sc.mat_hx = rng.U(180.0, 230.0);
    sc.mat_hy = rng.U(130.0, 170.0);
    sc.mat_cx = rng.U(-60.0, 60.0);
    sc.mat_cy = rng.U(-40.0, 40.0);
    sc.mat_angle = rng.U(-0.3, 0.3);
    sc.mat_scale = rng.U(1.5, 4.0);
  }
  // Camera on the wrist: 30-40 cm along a view axis tilted up to 10 deg,
  // aimed a few cm off the plate centre, any roll.
  sc.axis_distance = rng.U(300.0, 400.0);
  const double aim_r = 35.0 * std::sqrt(rng.U()), aim_a = rng.U(0.0, 2.0 * kPi);
  const V3 aim{aim_r * std::cos(aim_a), aim_r * std::sin(aim_a), 0.0};
  const double tilt = (10.0 * kPi / 180.0) * std::sqrt(rng.U());
  const double tilt_a = rng.U(0.0, 2.0 * kPi);
  sc.az = {std::sin(tilt) * std::cos(tilt_a), std::sin(tilt) * std::sin(tilt_a),
           -std::cos(tilt)};
  sc.cam = aim - sc.az * sc.axis_distance;
  const V3 e1 = Normalize(Cross(sc.az, {0.0, 1.0, 0.0}));
  const V3 e2 = Cross(sc.az, e1);
  const double roll = rng.U(0.0, 2.0 * kPi);
  sc.ax = e1 * std::cos(roll) + e2 * std::sin(roll);
  sc.ay = Cross(sc.az, sc.ax);
  // Light: a ceiling lamp (warm or neutral), a window (cool, directional,
  // low), the sky/room as an ambient term from above.
  const double lamp_r = rng.U(0.0, 900.0), lamp_a = rng.U(0.0, 2.0 * kPi);
  sc.lamp_pos = {lamp_r * std::cos(lamp_a), lamp_r * std::sin(lamp_a),
                 rng.U(1400.0, 2200.0)};
  sc.lamp_col = V3{1.0, rng.U(0.86, 0.97), rng.U(0.7, 0.93)} * rng.U(0.8, 1.2);
  sc.lamp_soft = rng.U(18.0, 40.0);
  sc.lamp_lobe = rng.U(150.0, 1500.0);
  const double win_el = rng.U(20.0, 50.0) * kPi / 180.0;
  const double win_az = rng.U(0.0, 2.0 * kPi);
  sc.win_dir = {std::cos(win_el) * std::cos(win_az),
                std::cos(win_el) * std::sin(win_az), std::sin(win_el)};
  sc.win_col = V3{rng.U(0.85, 0.95), rng.U(0.93, 0.98), 1.0} * rng.U(0.4, 1.6);
  sc.win_soft = rng.U(3.5, 8.0);
  sc.win_lobe = rng.U(12.0, 40.0);
  sc.sky_col = V3{rng.U(0.85, 0.95), rng.U(0.92, 0.98), 1.0} * rng.U(0.25, 0.5);
  // Exposure: an unshadowed spot of the well lands at 195-232 of 255.
  const V3 to_lamp = Normalize(sc.lamp_pos);
  const V3 e_flat =
      sc.lamp_col * to_lamp.z + sc.win_col * sc.win_dir.z + sc.sky_col;
  const double target = SrgbToLinear(rng.U(195.0, 232.0));
  sc.exposure = target / (Luminance(Mul(sc.plate_albedo, e_flat)) * 1.0);
  // White balance: the camera mostly corrects the light's colour, with a
  // residual that varies from plate to plate.
  const double lum = Luminance(e_flat);
  const V3 cast{e_flat.x / lum, e_flat.y / lum, e_flat.z / lum};
  const double correct = rng.U(0.6, 0.95);
  sc.gains = {std::pow(cast.x, -correct) * rng.U(0.95, 1.05),
              std::pow(cast.y, -correct),
              std::pow(cast.z, -correct) * rng.U(0.95, 1.05)};
  const double g_lum = Luminance(Mul(sc.gains, cast));
  sc.gains = sc.gains * (1.0 / g_lum);
  sc.vignette = rng.U(0.05, 0.18);
  sc.blur_sigma = rng.U(0.45, 0.8);
  return sc;
}

struct GroundHit {
  double t = kInf;
  V3 n{0.0, 0.0, 1.0};
  bool plate = false;
};

// The ray against the plate (heightfield well and rim, outer wall) and the
// table plane beyond it.
GroundHit HitGround(const Scene& sc, V3 o, V3 d) {
  GroundHit hit;
  const double t_table = (-sc.base_z - o.z) / d.z;
  const double t_top = (sc.rim_h - o.z) / d.z;
  const double a = d.x * d.x + d.y * d.y;
  const double b = 2.0 * (o.x * d.x + o.y * d.y);
  const double c = o.x * o.x + o.y * o.y - sc.plate_r * sc.plate_r;
  const double disc = b * b - 4.0 * a * c;
  if (a > 1e-14 && disc > 0.0) {
    const double sq = std::sqrt(disc);
    const double t1 = (-b - sq) / (2.0 * a), t2 = (-b + sq) / (2.0 * a);
    if (t1 > 0.0 && t1 > t_top && t1 < t_table) {  // the plate's outer wall
      const V3 p = o + d * t1;
      hit.t = t1;
      hit.n = Normalize({p.x, p.y, 0.0});
      hit.plate = true;
      return hit;
    }
    const double s0 = std::max(t1, t_top), s1 = std::min(t2, t_table);
    if (s0 < s1) {
      const double t0 = -o.z / d.z;
      const V3 p0 = o + d * t0;
      const double slope = std::sqrt(a) / std::fabs(d.z);
      if (Hypot(p0.x, p0.y) + slope * sc.rim_h < sc.well_r) {
        hit.t = t0;
        hit.plate = true;
        return hit;
      }
      const double denom = std::fabs(d.z) + sc.rim_slope * std::sqrt(a);
      double t = s0;
      for (int k = 0; k < 400 && t <= s1 + 1e-6; ++k) {
        const V3 p = o + d * t;
        const double r = Hypot(p.x, p.y);
        const double g = p.z - PlateHeight(sc, r);
        if (g < 1e-3) {
          const double sl = PlateSlope(sc, r);
          const double inv_r = r > 1e-9 ? 1.0 / r : 0.0;
          hit.t = t;
          hit.n = Normalize({-sl * p.x * inv_r, -sl * p.y * inv_r, 1.0});
          hit.plate = true;
          return hit;
        }
        t += std::max(g / denom, 1e-3);
      }
    }
  }
  hit.t = t_table;
  return hit;
}

bool TraceItem(const Item& it, V3 o, V3 d, double tmin, double tmax,
               double* t_out) {
  double t0, t1;
  if (!RaySphere(o, d, it.pose.t, it.radius, &t0, &t1)) return false;
  t0 = std::max(t0, tmin);
  t1 = std::min(t1, tmax);
  if (t0 >= t1) return false;
  const V3 lo = ApplyT(it.pose.R, o - it.pose.t);
  const V3 ld = ApplyT(it.pose.R, d);
  const double scale = it.piece.step_scale;
  double t = t0;
  for (int k = 0; k < 200; ++k) {
    const double dist = PieceSdf(it.piece, lo + ld * t);
    if (dist < 0.004) {
      *t_out = t;
      return true;
    }
    t += std::max(dist * scale, 0.002);
    if (t > t1) return false;
  }
  return false;
}

// Penumbra-estimating shadow ray toward a light, against the candidate
// items except `owner` (a piece's own shading already faces the light).
double SoftShadow(const std::vector<Item>& items, const std::vector<int>& cand,
                  int owner, V3 p, V3 l, double k) {
  double res = 1.0;
  for (int i : cand) {
    if (i == owner) continue;
    const Item& it = items[i];
    double t0, t1;
    if (!RaySphere(p, l, it.pose.t, it.radius + 3.0, &t0, &t1)) continue;
    t0 = std::max(t0, 0.05);
    if (t1 <= t0) continue;
    const V3 lo = ApplyT(it.pose.R, p - it.pose.t);
    const V3 ld = ApplyT(it.pose.R, l);
    double t = t0;
    for (int s = 0; s < 96 && t < t1; ++s) {
      const double h = PieceSdf(it.piece, lo + ld * t);
      if (h < 0.005) return 0.0;
      res = std::min(res, k * h / t);
      t += Clamp(h * it.piece.step_scale, 0.05, 4.0);
    }
  }
  res = Clamp(res, 0.0, 1.0);
  return res * res * (3.0 - 2.0 * res);
}

// Ambient occlusion from the items' distance bounds along the normal.
double Occlusion(const std::vector<Item>& items, const std::vector<int>& cand,
                 V3 p, V3 n) {
  if (cand.empty()) return 1.0;
  double occ = 0.0, w = 1.0;
  for (int k = 1; k <= 5; ++k) {
    const double h = 1.3 * k;
    const V3 q = p + n * h;
    double d = h;
    for (int i : cand) {
      const Item& it = items[i];
      const V3 dq = q - it.pose.t;
      if (Dot(dq, dq) > (it.radius + h) * (it.radius + h)) continue;
      d = std::min(d, PieceSdf(it.piece, ApplyT(it.pose.R, dq)));
    }
    occ += std::max(0.0, h - d) * w;
    w *= 0.6;
  }
  return Clamp(1.0 - 0.13 * occ, 0.0, 1.0);
}

// Is surface point p (normal n) in view of an eye at `eye`? Items and the
// plate rim can hide it.
bool SeenFrom(const Scene& sc, const std::vector<Item>& items,
              const std::vector<int>& cand, V3 p, V3 n, V3 eye) {
  const V3 o = p + n * 0.12;
  V3 d = eye - o;
  const double len = Length(d);
  d = d * (1.0 / len);
  for (int i : cand) {
    double t;
    if (TraceItem(items[i], o, d, 0.0, len, &t)) return false;
  }
  if (d.z <= 0.0) return true;
  const double dxy = Hypot(d.x, d.y);
  const double slope = dxy / d.z;
  const double r0 = Hypot(o.x, o.y);
  const double rise = sc.rim_h - o.z;
  if (rise <= 0.0) return true;
  if (r0 + slope * rise < sc.well_r) return true;
  if (r0 - slope * (rise + sc.base_z) > sc.plate_r) return true;
  const double t_end = rise / d.z;
  double t = 0.0;
  if (r0 > sc.plate_r) {
    // From the table: the plate's outer wall is in the way if the segment
    // reaches the plate's radius below the rim top.
    const double a = d.x * d.x + d.y * d.y, b = 2.0 * (o.x * d.x + o.y * d.y);
    const double c = o.x * o.x + o.y * o.y - sc.plate_r * sc.plate_r;
    const double disc = b * b - 4.0 * a * c;
    if (disc <= 0.0) return true;
    t = (-b - std::sqrt(disc)) / (2.0 * a);
    if (t < 0.0 || t > t_end) return true;
    return false;
  }
  // Inside the plate's radius: the gap above the rim shrinks at most at
  // rate rim_slope * dxy - d.z per unit length.
  const double closing = sc.rim_slope * dxy - d.z;
  if (closing <= 0.0) return true;
  t = 0.3;
  for (int k = 0; k < 200 && t < t_end; ++k) {
    const V3 q = o + d * t;
    const double r = Hypot(q.x, q.y);
    if (r > sc.plate_r) return true;
    const double g = q.z - PlateHeight(sc, r);
    if (g < -0.05) return false;
    t += std::max(std::fabs(g) / closing, 0.05);
  }
  return true;
}

V3 TableAlbedo(const Scene& sc, V3 p) {
  // Placemat: a rotated rectangle under the plate.
  if (sc.mat) {
    const double c = std::cos(sc.mat_angle), s = std::sin(sc.mat_angle);
    const double u = c * (p.x - sc.mat_cx) + s * (p.y - sc.mat_cy);
    const double v = -s * (p.x - sc.mat_cx) + c * (p.y - sc.mat_cy);
    if (std::fabs(u) < sc.mat_hx && std::fabs(v) < sc.mat_hy) {
      const double n = Noise({u * 0.3, v * 0.3, 0.0}, sc.table_tex + 5);
      switch (sc.mat_pattern) {
        case 0:  // plain with grain
          return sc.mat_a * (0.93 + 0.12 * n);
        case 1: {  // woven
          const double wx = std::sin(u * 2.0 * kPi / sc.mat_scale);
          const double wy = std::sin(v * 2.0 * kPi / sc.mat_scale);
          return Mix(sc.mat_a, sc.mat_b, 0.5 + 0.5 * wx * wy) *
                 (0.95 + 0.1 * n);
        }
        default: {  // stripes
          const double st = std::sin(u * 2.0 * kPi / (sc.mat_scale * 6.0));
          return Mix(sc.mat_a, sc.mat_b, Smoothstep(-0.2, 0.2, st)) *
                 (0.95 + 0.1 * n);
        }
      }
    }
  }
  const double c = std::cos(sc.table_angle), s = std::sin(sc.table_angle);
  const double u = c * p.x + s * p.y, v = -s * p.x + c * p.y;
  switch (sc.table_pattern) {
    case 1: {  // wood grain
      const double warp = Fbm({u * 0.01, v * 0.08, 0.0}, 3, sc.table_tex);
      const double ring = Fract(v / sc.table_scale + 4.0 * warp);
      const double grain = Noise({u * 0.2, v * 3.0, 0.0}, sc.table_tex + 1);
      return Mix(sc.table_a, sc.table_b,
                 Smoothstep(0.4, 0.9, ring) * 0.8 + 0.2 * grain);
    }
    case 2: {  // speckled laminate
      const double sp = Noise({u * 0.9, v * 0.9, 0.0}, sc.table_tex + 2);
      return Mix(sc.table_a, sc.table_b, Smoothstep(0.55, 0.75, sp));
    }
    case 3: {  // tablecloth weave
      const double wx = std::sin(u * 2.0 * kPi / (0.3 * sc.table_scale));
      const double wy = std::sin(v * 2.0 * kPi / (0.3 * sc.table_scale));
      return Mix(sc.table_a, sc.table_b, 0.5 + 0.5 * wx * wy);
    }
    default:
      return sc.table_a *
             (0.94 + 0.1 * Fbm({u * 0.02, v * 0.02, 0.0}, 2, sc.table_tex));
  }
}

// Pixel rectangle (inclusive) that a set of spheres projects into.
struct Rect {
  int x0 = 1, y0 = 1, x1 = 0, y1 = 0;
  bool Has(int x, int y) const {
    return x >= x0 && x <= x1 && y >= y0 && y <= y1;
  }
};

Rect ProjectSpheres(const Scene& sc,
                    const std::vector<std::pair<V3, double>>& spheres) {
  double u0 = kInf, v0 = kInf, u1 = -kInf, v1 = -kInf;
  for (const auto& [c, r] : spheres) {
    for (int k = 0; k < 8; ++k) {
      const V3 q = c + V3{(k & 1) ? r : -r, (k & 2) ? r : -r, (k & 4) ? r : -r};
      const V3 w = q - sc.cam;
      const double z = Dot(w, sc.az);
      if (z <= 1.0) return Rect{0, 0, sc.in.width - 1, sc.in.height - 1};
      const double u = sc.in.fx * Dot(w, sc.ax) / z + sc.in.cx;
      const double v = sc.in.fy * Dot(w, sc.ay) / z + sc.in.cy;
      u0 = std::min(u0, u);
      u1 = std::max(u1, u);
      v0 = std::min(v0, v);
      v1 = std::max(v1, v);
    }
  }
  Rect r;
  r.x0 = std::max(0, static_cast<int>(std::floor(u0)) - 1);
  r.y0 = std::max(0, static_cast<int>(std::floor(v0)) - 1);
  r.x1 = std::min(sc.in.width - 1, static_cast<int>(std::ceil(u1)) + 1);
  r.y1 = std::min(sc.in.height - 1, static_cast<int>(std::ceil(v1)) + 1);
  return r;
}

// Screen region in which `it` can shadow a surface lit from direction l.
Rect ShadowRect(const Scene& sc, const Item& it, V3 l) {
  const double r = it.radius + 3.0;
  const double s = (it.pose.t.z + r + sc.base_z) / std::max(l.z, 0.05);
  return ProjectSpheres(sc, {{it.pose.t, r}, {it.pose.t - l * s, r}});
}

// ---------------------------------------------------------------------------
// Arrangement.

std::vector<Item> Arrange(const Scene& sc, const BlindPlateOptions& options,
                          Draw& rng) {
  const int lo = std::max(0, options.min_items);
  const int hi = std::max(lo, options.max_items);
  const int count = lo + rng.Index(hi - lo + 1);
  std::vector<Item> items;
  int failures = 0;
  while (static_cast<int>(items.size()) < count && failures < 12) {
    const double u_overlap = rng.U(), u_same = rng.U(), u_touch = rng.U();
    FoodKind food = static_cast<FoodKind>(rng.Index(kNumFoods));
    bool placed = false;
    for (int tries = 0; tries < 3 && !placed; ++tries) {
      if (tries == 2) food = static_cast<FoodKind>(rng.Index(kNumFoods));
      Item a = MakeItem(MakePiece(food, rng), rng);
      std::vector<int> flat, same, any;
      for (int k = 0; k < static_cast<int>(items.size()); ++k) {
        any.push_back(k);
        if (items[k].piece.flat) flat.push_back(k);
        if (items[k].piece.food == food) same.push_back(k);
      }
      if (u_overlap < options.overlap_probability && a.piece.flat) {
        placed = PlaceShingled(a, flat, items, sc.well_r, rng);
      }
      if (!placed && u_same < options.same_food_touch_probability) {
        placed = PlaceTouching(a, same, items, sc.well_r, rng);
      }
      if (!placed && u_touch < options.touch_probability) {
        placed = PlaceTouching(a, any, items, sc.well_r, rng);
      }
      if (!placed) placed = PlaceApart(a, items, sc.well_r, rng);
      if (!placed) placed = PlaceTouching(a, any, items, sc.well_r, rng);
      if (placed) items.push_back(std::move(a));
    }
    if (!placed) ++failures;
  }
  return items;
}

// ---------------------------------------------------------------------------
// Image processing helpers.

void GaussianBlur3(std::vector<float>& img, int w, int h, double sigma) {
  constexpr int kR = 2;
  double k[2 * kR + 1];
  double sum = 0.0;
  for (int i = -kR; i <= kR; ++i) {
    k[i + kR] = std::exp(-0.5 * i * i / (sigma * sigma));
    sum += k[i + kR];
  }
  for (double& v : k) v /= sum;
  std::vector<float> tmp(img.size());
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      for (int c = 0; c < 3; ++c) {
        double acc = 0.0;
        for (int i = -kR; i <= kR; ++i) {
          const int xx = std::clamp(x + i, 0, w - 1);
          acc += k[i + kR] * img[(y * w + xx) * 3 + c];
        }
        tmp[(y * w + x) * 3 + c] = static_cast<float>(acc);
      }
    }
  }
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      for (int c = 0; c < 3; ++c) {
        double acc = 0.0;
        for (int i = -kR; i <= kR; ++i) {
          const int yy = std::clamp(y + i, 0, h - 1);
          acc += k[i + kR] * tmp[(yy * w + x) * 3 + c];
        }
        img[(y * w + x) * 3 + c] = static_cast<float>(acc);
      }
    }
  }
}

}  // namespace

const std::vector<std::string>& BlindPlateFoods() {
  static const std::vector<std::string>* const kFoods =
      new std::vector<std::string>{"carrot",        "celery", "strawberry",
                                   "cantaloupe",    "banana", "kiwi",
                                   "cherry_tomato", "grape"};
  return *kFoods;
}

BlindPlate RenderBlindPlate(uint64_t seed, const BlindPlateOptions& options) {
  Draw scene_rng(random::MixSeed(seed, 1));
  Draw noise_rng(random::MixSeed(seed, 2));
  const Scene sc = MakeScene(scene_rng);
  const std::vector<Item> items = Arrange(sc, options, scene_rng);
  const int n_items = static_cast<int>(items.size());
  const int w = sc.in.width, h = sc.in.height;

  BlindPlate out;
  out.axis_distance_mm = sc.axis_distance;
  out.frame.intrinsics = sc.in;
  for (const Item& it : items) {
    out.food.push_back(BlindPlateFoods()[it.piece.food]);
    out.lies_on_another.push_back(it.lies_on >= 0);
    out.lies_on_index.push_back(it.lies_on);
    out.size_mm.push_back(it.size);
  }

  // Screen regions: where each item can be hit, shadow, or occlude light.
  std::vector<Rect> hit_rect, lamp_rect, win_rect, ao_rect, stereo_rect;
  for (const Item& it : items) {
    hit_rect.push_back(ProjectSpheres(sc, {{it.pose.t, it.radius}}));
    lamp_rect.push_back(ShadowRect(sc, it, Normalize(sc.lamp_pos - it.pose.t)));
    win_rect.push_back(ShadowRect(sc, it, sc.win_dir));
    ao_rect.push_back(ProjectSpheres(sc, {{it.pose.t, it.radius + 7.0}}));
    const V3 to_eye = Normalize(sc.cam + sc.ax * 70.0 - it.pose.t);
    Rect r = ShadowRect(sc, it, to_eye);
    r.x0 = std::max(0, r.x0 - 3);
    r.y0 = std::max(0, r.y0 - 3);
    r.x1 = std::min(w - 1, r.x1 + 3);
    r.y1 = std::min(h - 1, r.y1 + 3);
    stereo_rect.push_back(r);
  }

  const size_t npix = static_cast<size_t>(w) * h;
  out.label.assign(npix, -1);
  std::vector<double> depth(npix, 0.0);
  std::vector<float> lin(npix * 3, 0.0f);
  std::vector<uint8_t> flags(npix,
                             0);  // 1 glare, 2 dark, 4 unseen by an imager
  std::vector<int> footprint(n_items, 0);
  // The D415's colour camera sits at the outer end of the stereo pair:
  // the left imager (depth reference) 15 mm to its right, the right imager
  // a 55 mm baseline further. The left imager lies between the colour
  // camera and the right imager, so what both of those see it sees too:
  // only the right imager's view is traced.
  const V3 right_eye = sc.cam + sc.ax * 70.0;
  std::vector<int> cand, lamp_cand, win_cand, ao_cand, stereo_cand;
  const double cx = sc.in.cx, cy = sc.in.cy;
  const double r_max2 = cx * cx + cy * cy;

  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const size_t idx = static_cast<size_t>(y) * w + x;
      const V3 d = Normalize(sc.ax * ((x - cx) / sc.in.fx) +
                             sc.ay * ((y - cy) / sc.in.fy) + sc.az);
      const GroundHit ground = HitGround(sc, sc.cam, d);
      cand.clear();
      lamp_cand.clear();
      win_cand.clear();
      ao_cand.clear();
      stereo_cand.clear();
      for (int i = 0; i < n_items; ++i) {
        if (stereo_rect[i].Has(x, y)) stereo_cand.push_back(i);
        if (hit_rect[i].Has(x, y)) cand.push_back(i);
        if (lamp_rect[i].Has(x, y)) lamp_cand.push_back(i);
        if (win_rect[i].Has(x, y)) win_cand.push_back(i);
        if (ao_rect[i].Has(x, y)) ao_cand.push_back(i);
      }
      int label = -1;
      double t_hit = ground.t;
      for (int i : cand) {
        double t;
        if (TraceItem(items[i], sc.cam, d, 0.0, ground.t, &t)) {
          ++footprint[i];
          if (t < t_hit) {
            t_hit = t;
            label = i;
          }
        }
      }
      out.label[idx] = static_cast<int16_t>(label);
      const V3 p = sc.cam + d * t_hit;
      depth[idx] = Dot(p - sc.cam, sc.az);

      // Surface: normal and material.
      V3 n;
      Material m;
      if (label >= 0) {
        const Item& it = items[label];
        const V3 pl = ApplyT(it.pose.R, p - it.pose.t);
        const V3 nl = PieceNormal(it.piece, pl);
        m = Shade(it.piece, pl, nl);
        V3 nb = nl;
        if (m.bump > 0.0) {
          const V3 q = pl * 0.7;
          nb = Normalize(nl + V3{Noise(q, it.piece.tex + 31) - 0.5,
                                 Noise(q, it.piece.tex + 32) - 0.5,
                                 Noise(q, it.piece.tex + 33) - 0.5} *
                                  (2.0 * m.bump));
        }
        n = Apply(it.pose.R, nb);
      } else if (ground.plate) {
        n = ground.n;
        m.albedo =
            sc.plate_albedo * (0.985 + 0.03 * Noise(p * 0.04, sc.plate_tex));
        m.ks = sc.plate_ks;
        m.shininess = sc.plate_shininess;
      } else {
        n = ground.n;
        m.albedo = TableAlbedo(sc, p);
        m.ks = sc.table_pattern == 1 ? 0.04 : 0.02;
        m.shininess = 15.0;
      }
      if (Dot(n, d) > 0.0) n = n - d * (2.0 * Dot(n, d));  // grazing flip

      // Light.
      const V3 view = -d;
      const V3 ps = p + n * 0.05;
      const V3 l_lamp = Normalize(sc.lamp_pos - p);
      const double vis_lamp =
          lamp_cand.empty()
              ? 1.0
              : SoftShadow(items, lamp_cand, label, ps, l_lamp, sc.lamp_soft);
      const double vis_win =
          win_cand.empty()
              ? 1.0
              : SoftShadow(items, win_cand, label, ps, sc.win_dir, sc.win_soft);
      const double ao = Occlusion(items, ao_cand, p, n);
      auto diffuse = [&](V3 l) {
        return std::max(0.0, (Dot(n, l) + m.wrap) / (1.0 + m.wrap));
      };
      const V3 irradiance = sc.lamp_col * (diffuse(l_lamp) * vis_lamp) +
                            sc.win_col * (diffuse(sc.win_dir) * vis_win) +
                            sc.sky_col * ((0.6 + 0.4 * n.z) * ao);
      auto specular = [&](V3 l, double vis, double lobe) {
        const double nl = Dot(n, l);
        if (nl <= 0.0 || vis <= 0.0) return 0.0;
        const double shin = 1.0 / (1.0 / m.shininess + 1.0 / lobe);
        const double nh = std::max(0.0, Dot(n, Normalize(l + view)));
        return m.ks * (shin + 8.0) / 8.0 * std::pow(nh, shin) * nl * vis;
      };
      const V3 spec = sc.lamp_col * specular(l_lamp, vis_lamp, sc.lamp_lobe) +
                      sc.win_col * specular(sc.win_dir, vis_win, sc.win_lobe) +
                      sc.sky_col * (m.ks * 0.5 * ao);
      const double r2 = ((x - cx) * (x - cx) + (y - cy) * (y - cy)) / r_max2;
      const double gain = sc.exposure * (1.0 - sc.vignette * r2);
      const V3 colour = Mul(Mul(m.albedo, irradiance) + spec, sc.gains) * gain;
      lin[idx * 3 + 0] = static_cast<float>(colour.x);
      lin[idx * 3 + 1] = static_cast<float>(colour.y);
      lin[idx * 3 + 2] = static_cast<float>(colour.z);
      // Glare: a saturated highlight, or the IR projector (beside the
      // camera) mirrored straight back by a glossy surface facing it: tiny
      // spots on round glossy food, a small patch on a glazed plate.
      const bool facing = label >= 0 ? m.ks >= 0.04 && Dot(n, view) > 0.996
                                     : ground.plate && Dot(n, view) > 0.99985;
      if (Luminance(spec) * gain > 0.8 || facing) flags[idx] |= 1;
      if (Luminance(colour) < 0.012) flags[idx] |= 2;
      if (options.sensor_artifacts &&
          !SeenFrom(sc, items, stereo_cand, p, n, right_eye)) {
        flags[idx] |= 4;
      }
    }
  }

  // Truth from the label image.
  out.frame.truth.resize(n_items);
  std::vector<int> x0(n_items, w), y0(n_items, h), x1(n_items, -1),
      y1(n_items, -1), visible(n_items, 0);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const int l = out.label[static_cast<size_t>(y) * w + x];
      if (l < 0) continue;
      ++visible[l];
      x0[l] = std::min(x0[l], x);
      y0[l] = std::min(y0[l], y);
      x1[l] = std::max(x1[l], x);
      y1[l] = std::max(y1[l], y);
    }
  }
  for (int i = 0; i < n_items; ++i) {
    sim::ItemTruth& t = out.frame.truth[i];
    t.id = static_cast<uint32_t>(i);
    t.visible_pixels = visible[i];
    t.footprint_pixels = footprint[i];
    if (visible[i] > 0) {
      t.x = x0[i];
      t.y = y0[i];
      t.width = x1[i] - x0[i] + 1;
      t.height = y1[i] - y0[i] + 1;
    }
  }

  // Colour: lens blur, sRGB encoding, sensor noise.
  GaussianBlur3(lin, w, h, sc.blur_sigma);
  out.frame.rgb.resize(npix * 3);
  const double s0 = noise_rng.U(0.8, 1.6), s1 = noise_rng.U(0.008, 0.02);
  constexpr int kLut = 4096;
  std::vector<double> encode(kLut + 2);
  for (int i = 0; i <= kLut + 1; ++i) {
    const double c = std::min(1.0, static_cast<double>(i) / kLut);
    encode[i] =
        255.0 *
        (c <= 0.0031308 ? 12.92 * c : 1.055 * std::pow(c, 1.0 / 2.4) - 0.055);
  }
  for (size_t k = 0; k < npix * 3; ++k) {
    const double c = Clamp(lin[k], 0.0, 1.0) * kLut;
    const int i = static_cast<int>(c);
    double v = Mix(encode[i], encode[i + 1], c - i);
    if (options.sensor_artifacts) {
      v += noise_rng.FastNormal() * std::sqrt(s0 * s0 + s1 * v);
    }
    out.frame.rgb[k] = static_cast<uint8_t>(Clamp(std::round(v), 0.0, 255.0));
  }

  // Depth: active stereo seen from the left imager, aligned to colour.
  out.frame.depth_mm.assign(npix, 0);
  if (!options.sensor_artifacts) {
    for (size_t k = 0; k < npix; ++k) {
      out.frame.depth_mm[k] =
          static_cast<uint16_t>(Clamp(std::round(depth[k]), 0.0, 65535.0));
    }
    return out;
  }
  std::vector<double> z = depth;
  std::vector<uint8_t> invalid(npix, 0);
  // Edges: a pixel on a depth step takes a value between the surfaces, the
  // nearer surface's (stereo matching fattens foregrounds), or none.
  for (int y = 1; y < h - 1; ++y) {
    for (int x = 1; x < w - 1; ++x) {
      double zmin = kInf, zmax = -kInf;
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) {
          const double v = depth[static_cast<size_t>(y + dy) * w + x + dx];
          zmin = std::min(zmin, v);
          zmax = std::max(zmax, v);
        }
      }
      if (zmax - zmin < 4.0) continue;
      const size_t idx = static_cast<size_t>(y) * w + x;
      const double r = noise_rng.U();
      if (r < 0.25) {
        invalid[idx] = 1;
      } else if (r < 0.5) {
        z[idx] = Mix(zmin, zmax, noise_rng.U());
      } else if (r < 0.75) {
        z[idx] = zmin;
      }
    }
  }
  // Noise growing with the square of distance, partly correlated.
  const double sigma350 = noise_rng.U(0.3, 1.0);
  constexpr int kCell = 12;
  const int gw = w / kCell + 2, gh = h / kCell + 2;
  std::vector<double> coarse(static_cast<size_t>(gw) * gh);
  for (double& v : coarse) v = noise_rng.Normal();
  const double p_hole = noise_rng.U(0.002, 0.008);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const size_t idx = static_cast<size_t>(y) * w + x;
      const double gx = static_cast<double>(x) / kCell,
                   gy = static_cast<double>(y) / kCell;
      const int ix = static_cast<int>(gx), iy = static_cast<int>(gy);
      const double fx = gx - ix, fy = gy - iy;
      const double c00 = coarse[iy * gw + ix], c10 = coarse[iy * gw + ix + 1];
      const double c01 = coarse[(iy + 1) * gw + ix],
                   c11 = coarse[(iy + 1) * gw + ix + 1];
      const double corr = Mix(Mix(c00, c10, fx), Mix(c01, c11, fx), fy);
      const double q = z[idx] / 350.0;
      const double sigma = sigma350 * q * q;
      z[idx] += sigma * (0.8 * noise_rng.FastNormal() + 0.6 * corr);
      const uint8_t f = flags[idx];
      if (f & 4) invalid[idx] = 1;                           // occlusion band
      if ((f & 1) && noise_rng.U() < 0.6) invalid[idx] = 1;  // glare
      if ((f & 2) && noise_rng.U() < 0.5) invalid[idx] = 1;  // too dark
      if (noise_rng.U() < p_hole) invalid[idx] = 1;          // scattered
    }
  }
  // A few small blobs of missing depth.
  const int blobs = 3 + noise_rng.Index(12);
  for (int b = 0; b < blobs; ++b) {
    const double bx = noise_rng.U(0.0, w), by = noise_rng.U(0.0, h);
    const double br = noise_rng.U(1.0, 3.5);
    for (int y = std::max(0, static_cast<int>(by - br));
         y <= std::min(h - 1, static_cast<int>(by + br)); ++y) {
      for (int x = std::max(0, static_cast<int>(bx - br));
           x <= std::min(w - 1, static_cast<int>(bx + br)); ++x) {
        if ((x - bx) * (x - bx) + (y - by) * (y - by) <= br * br) {
          invalid[static_cast<size_t>(y) * w + x] = 1;
        }
      }
    }
  }
  for (size_t k = 0; k < npix; ++k) {
    if (invalid[k]) continue;
    out.frame.depth_mm[k] =
        static_cast<uint16_t>(Clamp(std::round(z[k]), 1.0, 65535.0));
  }
  return out;
}

}  // namespace bitewise::experiments
