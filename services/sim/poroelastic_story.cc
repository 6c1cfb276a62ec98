// The poroelastic story: plant tissue as a fluid-saturated solid that
// cracks when the elastic energy it can release pays for new crack surface.
// Under each tine sits a lumped finite-element column (six layers of Biot
// poroelastic tissue, the tine's stress bulb): an undrained, turgid response
// (skeleton plus pore fluid) that relaxes as juice flows out by Darcy's law
// into the crack and sideways. The tine's tapered tip grows its contact as
// it sinks. A crack runs ahead of the tip when the released energy per unit
// area reaches the tissue's toughness (Griffith/Kendall for a punch), and
// arrests at a lower energy (unstable in crisp tissue: a sawtooth; stable in
// pastes: smooth cutting); toughness varies cell by cell; cells squeezed
// past a strain collapse; closed crack faces rub on the shafts. A berry's
// skin is a pre-tensioned membrane that bursts when its tension reaches the
// Griffith strength of its flaws, venting the berry. The item squashes
// viscoelastically on the plate in series. The arm is impedance controlled
// (1 kHz, 2-5 kN/m, 15-40 mm/s); the gripper holding the fork slips above
// its friction limit. The sensor, a wrist ATI Mini40 16-24 cm above the
// tines, feels the tool's inertia, a tilted, off-centre fork, arm vibration
// and the fork ringing at cracks, through a two-pole low-pass, EtherCAT
// cycles of 500 Hz-2 kHz (stale frames), counts, noise, offset and drift.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "services/domain/random.h"
#include "services/domain/wrench.h"
#include "services/sim/trace_stories.h"

namespace bitewise::sim {
namespace {

using Engine = std::mt19937_64;

constexpr double kPi = 3.14159265358979323846;
constexpr double kGravity = 9.81;
constexpr int kLayers = 6;          // finite elements in the stress bulb
constexpr double kStepS = 5e-5;     // physics step (20 kHz)
constexpr double kControlS = 1e-3;  // impedance controller period
constexpr double kMaxDepthM = 0.04;

using random::LogUniform;
using random::Uniform;

struct Vec3 {
  double x = 0.0, y = 0.0, z = 0.0;
};
Vec3 operator+(const Vec3& a, const Vec3& b) {
  return {a.x + b.x, a.y + b.y, a.z + b.z};
}
Vec3 operator*(double s, const Vec3& a) { return {s * a.x, s * a.y, s * a.z}; }
Vec3 Cross(const Vec3& a, const Vec3& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
Vec3 Normalized(const Vec3& a) {
  const double n = std::sqrt(a.x * a.x + a.y * a.y + a.z * a.z);
  return (1.0 / n) * a;
}
// A random unit vector in the plane spanned by orthonormal e1, e2.
Vec3 InPlane(const Vec3& e1, const Vec3& e2, double angle) {
  return std::cos(angle) * e1 + std::sin(angle) * e2;
}

// The tissue under the tines (flesh, for a berry).
struct Tissue {
  double drained_pa;       // E_d, the skeleton's drained modulus
  double fluid_pa;         // M, the pore fluid's (turgor's) Biot modulus
  double consolidation_s;  // drainage time over the stress bulb
  double lateral_drain;    // sideways drainage relative to the bulb
  double gc_init;          // J/m^2, toughness of the intact surface
  double gc_prop;          // J/m^2, toughness of the tissue below
  double arrest;           // energy left when a crack stops, of the critical
  double toughness_cv;     // cell-to-cell scatter of the toughness
  double cell_m;           // length over which the toughness is one value
  double friction;         // tine shaft on crack faces
  double wedge_strain;     // crack faces' pressure on the shafts / E_d
  double crush_strain;     // u / H at which the cells under a tip collapse
};

struct Skin {
  bool present = false;
  double fail_tension = 0.0;      // N/m, Griffith strength * thickness
  double pre_tension = 0.0;       // N/m, from the berry's pressure
  double stiffness = 0.0;         // E_s t_s, N/m
  double concentration = 1.0;     // tension at the tine / mean tension
  double dimple_m = 0.0;          // radius of the dimple round a tine
  double residual_tension = 0.0;  // N/m, of the torn flaps on the shafts
  double friction = 0.0;
  double softening = 1.0;  // the squashed berry's stiffness once vented
};

struct Body {
  bool hertz = false;      // a whole berry (F ~ delta^1.5) or a cut piece
  double stiffness = 0.0;  // N/m or N/m^1.5
  double damping = 0.0;    // N s/m
};

struct Item {
  Tissue tissue;
  Skin skin;
  Body body;
  std::vector<double> toughness_field;  // multiplier per cell along depth
};

Tissue DrawTissue(HapticCategory category, Engine& rng) {
  Tissue t;
  switch (category) {
    case HapticCategory::kHard:
      // Crisp parenchyma (carrot, celery, apple): 2-8 MPa skeleton, turgor
      // adding 30-150% when undrained, low permeability (relaxation over
      // seconds), toughness 100-400 J/m^2, unstable cracks that arrest at
      // 10-40% of the critical energy; cells that collapse only when
      // squeezed by 80-120% of the bulb's depth (fracture comes first).
      t.drained_pa = LogUniform(rng, 2e6, 8e6);
      t.fluid_pa = t.drained_pa * Uniform(rng, 0.3, 1.5);
      t.consolidation_s = LogUniform(rng, 0.2, 2.0);
      t.gc_init = LogUniform(rng, 100.0, 400.0);
      t.gc_prop = t.gc_init * Uniform(rng, 0.6, 1.0);
      t.arrest = Uniform(rng, 0.1, 0.4);
      t.toughness_cv = Uniform(rng, 0.2, 0.4);
      t.cell_m = Uniform(rng, 0.2e-3, 0.6e-3);
      t.friction = Uniform(rng, 0.3, 0.6);
      t.wedge_strain = Uniform(rng, 0.02, 0.06);
      t.crush_strain = Uniform(rng, 0.8, 1.2);
      break;
    case HapticCategory::kMedium:
      // Juicy flesh (strawberry, cantaloupe, kiwi): 0.15-1 MPa, permeable
      // (30-300 ms), a tougher surface layer (40-200 J/m^2) over crushable
      // cells at 25-60% of it: one bioyield, then ragged, stable cutting.
      t.drained_pa = LogUniform(rng, 0.15e6, 1.0e6);
      t.fluid_pa = t.drained_pa * Uniform(rng, 0.5, 2.0);
      t.consolidation_s = LogUniform(rng, 0.03, 0.3);
      t.gc_init = LogUniform(rng, 40.0, 200.0);
      t.gc_prop = t.gc_init * Uniform(rng, 0.25, 0.6);
      t.arrest = Uniform(rng, 0.5, 0.85);
      t.toughness_cv = Uniform(rng, 0.15, 0.3);
      t.cell_m = Uniform(rng, 0.1e-3, 0.3e-3);
      t.friction = Uniform(rng, 0.2, 0.5);
      t.wedge_strain = Uniform(rng, 0.02, 0.06);
      t.crush_strain = Uniform(rng, 0.8, 1.2);
      break;
    case HapticCategory::kSoft:
      // Pastes (banana, avocado, ripe peach): 30-150 kPa, 10-60 J/m^2 and a
      // tip blunt next to their fracture length, so cracks grow as fast as
      // the tine goes (arrest near the critical energy), and the weak cells
      // collapse at 60-100% strain and flow aside: no failure. The paste is
      // uniform at the tine's scale and closes round the shafts (wedging
      // 5-15%), dragging on them.
      t.drained_pa = LogUniform(rng, 0.03e6, 0.15e6);
      t.fluid_pa = t.drained_pa * Uniform(rng, 0.3, 1.5);
      t.consolidation_s = LogUniform(rng, 0.01, 0.1);
      t.gc_init = LogUniform(rng, 10.0, 60.0);
      t.gc_prop = t.gc_init * Uniform(rng, 0.85, 1.0);
      t.arrest = Uniform(rng, 0.92, 1.0);
      t.toughness_cv = Uniform(rng, 0.03, 0.08);
      t.cell_m = Uniform(rng, 0.05e-3, 0.2e-3);
      t.friction = Uniform(rng, 0.1, 0.4);
      t.wedge_strain = Uniform(rng, 0.05, 0.15);
      t.crush_strain = Uniform(rng, 0.6, 1.0);
      break;
    case HapticCategory::kHardSkin:
    default:
      // A berry's flesh (grape, cherry tomato pulp): soft and watery.
      t.drained_pa = LogUniform(rng, 0.02e6, 0.1e6);
      t.fluid_pa = t.drained_pa * Uniform(rng, 0.5, 2.0);
      t.consolidation_s = LogUniform(rng, 0.01, 0.08);
      t.gc_init = LogUniform(rng, 5.0, 25.0);
      t.gc_prop = t.gc_init * Uniform(rng, 0.8, 1.0);
      t.arrest = Uniform(rng, 0.7, 0.95);
      t.toughness_cv = Uniform(rng, 0.1, 0.2);
      t.cell_m = Uniform(rng, 0.1e-3, 0.3e-3);
      t.friction = Uniform(rng, 0.2, 0.4);
      t.wedge_strain = Uniform(rng, 0.02, 0.05);
      t.crush_strain = Uniform(rng, 0.6, 1.0);
      break;
  }
  t.lateral_drain = Uniform(rng, 1.0, 4.0);
  return t;
}

Item DrawItem(HapticCategory category, Engine& rng) {
  Item item;
  item.tissue = DrawTissue(category, rng);
  const Tissue& t = item.tissue;
  const double undrained = t.drained_pa + t.fluid_pa;
  if (category == HapticCategory::kHardSkin) {
    Skin& s = item.skin;
    s.present = true;
    // Griffith in a sheet: strength sqrt(E_s Gamma / (pi c)) for flaws of
    // 50-120 um (a cell or two), skins of 60-150 um at 4-12 MPa with a
    // tearing energy of 150-500 J/m^2; the berry's pressure holds the skin
    // at 15-45% of that tension.
    const double modulus = LogUniform(rng, 4e6, 12e6);
    const double thickness = Uniform(rng, 60e-6, 150e-6);
    const double tearing = LogUniform(rng, 150.0, 500.0);
    const double flaw = Uniform(rng, 50e-6, 120e-6);
    s.fail_tension = thickness * std::sqrt(modulus * tearing / (kPi * flaw));
    s.pre_tension = s.fail_tension * Uniform(rng, 0.15, 0.45);
    s.stiffness = modulus * thickness;
    s.concentration = Uniform(rng, 2.0, 4.0);
    s.dimple_m = Uniform(rng, 2e-3, 3.5e-3);
    s.residual_tension = s.pre_tension * Uniform(rng, 0.2, 0.5);
    s.friction = Uniform(rng, 0.3, 0.6);
    s.softening = Uniform(rng, 0.4, 0.7);
    // The whole berry squashes like a pressurised shell: 5 N presses it by
    // 0.8-2 mm (Hertz-like, F ~ delta^1.5), creeping over 2-6 ms.
    const double squash_at_5n = Uniform(rng, 0.8e-3, 2e-3);
    item.body.hertz = true;
    item.body.stiffness = 5.0 / std::pow(squash_at_5n, 1.5);
    item.body.damping = Uniform(rng, 2e-3, 6e-3) * 1.5 * 5.0 / squash_at_5n;
  } else {
    // A cut piece on the plate: a block of E A / h ~ E L for a piece of
    // 8-30 mm, squashed undrained; creep over 0.5-20 ms.
    const double size = category == HapticCategory::kHard
                            ? Uniform(rng, 8e-3, 20e-3)
                            : Uniform(rng, 15e-3, 30e-3);
    item.body.stiffness = undrained * size;
    const double creep_s =
        category == HapticCategory::kHard     ? Uniform(rng, 0.5e-3, 2e-3)
        : category == HapticCategory::kMedium ? Uniform(rng, 2e-3, 8e-3)
                                              : Uniform(rng, 5e-3, 20e-3);
    item.body.damping = creep_s * item.body.stiffness;
  }
  const int cells = static_cast<int>(std::ceil(kMaxDepthM / t.cell_m)) + 1;
  random::Normal normal;
  const double sd = std::sqrt(std::log1p(t.toughness_cv * t.toughness_cv));
  item.toughness_field.resize(cells);
  for (double& g : item.toughness_field) {
    g = std::exp(sd * normal(rng) - 0.5 * sd * sd);
  }
  return item;
}

struct Fork {
  int tines;
  double radius_m;      // a tine's equivalent radius
  double tip_radius_m;  // radius of its point
  double taper_m;       // depth over which the point widens to radius_m
  double bulb_m;        // depth of the stress bulb under a tine
};

// The item's state under the tines.
struct FoodState {
  double crack_m = 0.0;  // depth the tines' cracks have reached
  bool cracked = false;
  bool ruptured = false;
  std::array<double, kLayers> zeta{};  // fluid content change per layer
  double SumHZeta(double h) const {
    double sum = 0.0;
    for (double z : zeta) sum += z;
    return sum * h;
  }
};

struct Local {
  double force = 0.0;      // N, all tines
  double stiffness = 0.0;  // dF/d(depth), N/m
};

class Penetration {
 public:
  Penetration(const Item& item, const Fork& fork) : item_(item), fork_(fork) {
    const Tissue& t = item.tissue;
    undrained_ = t.drained_pa + t.fluid_pa;
    h_ = fork.bulb_m / kLayers;
    const double mc = t.fluid_pa * t.drained_pa / undrained_;
    // Darcy mobility from the drainage time over the bulb: tau = H^2/(k Mc).
    mobility_ = fork.bulb_m * fork.bulb_m / (t.consolidation_s * mc);
    const double rate =
        mobility_ * mc *
        (6.0 / (h_ * h_) + t.lateral_drain / (fork.radius_m * fork.radius_m));
    substeps_ = std::max(1, static_cast<int>(std::ceil(kStepS * rate / 0.5)));
  }

  FoodState& state() { return state_; }

  double ContactRadius(double depth) const {
    return std::min(
        fork_.radius_m,
        fork_.tip_radius_m +
            depth * (fork_.radius_m - fork_.tip_radius_m) / fork_.taper_m);
  }

  // Column stress under a tine (Pa) for the tip at `depth`, >= 0.
  double ColumnStress(double depth) const {
    const Tissue& t = item_.tissue;
    const double u = depth - state_.crack_m;
    const double sigma =
        (undrained_ * u + t.fluid_pa * state_.SumHZeta(h_)) / fork_.bulb_m;
    return std::max(0.0, sigma);
  }

  Local At(double depth) const {
    Local out;
    if (depth <= 0.0) return out;
    const Tissue& t = item_.tissue;
    const Skin& skin = item_.skin;
    const double n = fork_.tines;
    const double a = ContactRadius(depth);
    const double area = kPi * a * a;
    const double sigma = ColumnStress(depth);
    if (sigma > 0.0) {
      out.force += n * area * sigma;
      out.stiffness += n * area * undrained_ / fork_.bulb_m;
    }
    // Crack faces wedged open by the shafts press on them and rub.
    const double rub = n * t.friction * t.wedge_strain * t.drained_pa * 2.0 *
                       kPi * fork_.radius_m;
    const double embedded = std::min(state_.crack_m, depth);
    out.force += rub * embedded;
    if (state_.crack_m > depth) out.stiffness += rub;
    if (skin.present) {
      if (!state_.ruptured) {
        // A tensioned membrane dimpled by a point: F = 2 pi T w / ln(l/a),
        // its mean tension growing with the stretch of the dimple.
        const double lnr = std::log(skin.dimple_m / fork_.radius_m);
        const double s = depth / skin.dimple_m;
        const double tension = skin.pre_tension + 0.5 * skin.stiffness * s * s;
        out.force += n * 2.0 * kPi * tension * depth / lnr;
        out.stiffness += n * 2.0 * kPi *
                         (skin.pre_tension + 1.5 * skin.stiffness * s * s) /
                         lnr;
      } else {
        out.force += n * skin.friction * 2.0 * kPi * fork_.radius_m *
                     skin.residual_tension;
      }
    }
    return out;
  }

  // Grows cracks (or bursts the skin) at `depth` until the tissue holds.
  // Returns true if anything failed.
  bool Fail(double depth) {
    const Tissue& t = item_.tissue;
    const Skin& skin = item_.skin;
    bool failed = false;
    for (int iter = 0; iter < 32 && depth > 0.0; ++iter) {
      if (skin.present && !state_.ruptured) {
        const double s = depth / skin.dimple_m;
        const double edge = skin.pre_tension +
                            0.5 * skin.concentration * skin.stiffness * s * s;
        if (edge < skin.fail_tension) break;
        state_.ruptured = true;  // the skin splits; the flesh takes the tine
        failed = true;
        continue;
      }
      // Cells squeezed past their collapse strain crush and flow aside: the
      // cut front follows the tip smoothly (drained tissue would otherwise
      // compact without limit).
      const double squeeze =
          depth - state_.crack_m - t.crush_strain * fork_.bulb_m;
      if (squeeze > 0.0 && (!skin.present || state_.ruptured)) {
        Advance(squeeze);
        failed = true;
        continue;
      }
      const double a = ContactRadius(depth);
      const double sigma = ColumnStress(depth);
      // Energy released per crack area by the column under a punch:
      // G = H sigma^2 / (4 S_undrained) over a bulb H ~ a (fast cracks are
      // undrained), so the tissue cracks at sigma_c = sqrt(4 S Gc / H).
      const size_t cell = std::min(
          item_.toughness_field.size() - 1,
          static_cast<size_t>(std::max(0.0, state_.crack_m) / t.cell_m));
      const double gc = (state_.cracked ? t.gc_prop : t.gc_init) *
                        item_.toughness_field[cell];
      const double bulb = fork_.bulb_m * a / fork_.radius_m;
      const double critical = std::sqrt(4.0 * undrained_ * gc / bulb);
      if (sigma < critical) break;
      // The crack runs until the energy left is `arrest` of the critical.
      const double target = std::sqrt(t.arrest) * critical;
      const double u = depth - state_.crack_m;
      const double u_arrest =
          (target * fork_.bulb_m - t.fluid_pa * state_.SumHZeta(h_)) /
          undrained_;
      Advance(std::max(u - u_arrest, 0.02 * t.cell_m));
      failed = true;
    }
    return failed;
  }

  // The cut front moves down by `advance`; fresh, undrained tissue enters
  // the bulb as it does.
  void Advance(double advance) {
    state_.crack_m += advance;
    state_.cracked = true;
    const double keep = std::exp(-advance / fork_.bulb_m);
    for (double& z : state_.zeta) z *= keep;
  }

  // Juice flows (Darcy) between the layers, out into the crack (once there
  // is one) and sideways, for one physics step with the tip at `depth`.
  void Drain(double depth) {
    const Tissue& t = item_.tissue;
    bool idle = depth <= 0.0;
    for (double z : state_.zeta) idle = idle && z == 0.0;
    if (idle) return;
    const bool open = state_.cracked || (item_.skin.present && state_.ruptured);
    const double dt = kStepS / substeps_;
    const double lateral =
        mobility_ * t.lateral_drain / (fork_.radius_m * fork_.radius_m);
    std::array<double, kLayers> p{}, dz{};
    for (int sub = 0; sub < substeps_; ++sub) {
      const double sigma = ColumnStress(depth);
      for (int i = 0; i < kLayers; ++i) {
        p[i] =
            t.fluid_pa * (t.drained_pa * state_.zeta[i] + sigma) / undrained_;
        dz[i] = -lateral * p[i];
      }
      if (open) dz[0] -= mobility_ * p[0] / (0.5 * h_ * h_);
      for (int i = 0; i + 1 < kLayers; ++i) {
        const double q = mobility_ * (p[i] - p[i + 1]) / (h_ * h_);
        dz[i] -= q;
        dz[i + 1] += q;
      }
      for (int i = 0; i < kLayers; ++i) state_.zeta[i] += dt * dz[i];
    }
  }

 private:
  const Item& item_;
  const Fork& fork_;
  FoodState state_;
  double undrained_ = 0.0;
  double h_ = 0.0;
  double mobility_ = 0.0;
  int substeps_ = 1;
};

// A two-pole low-pass (two first-order sections) on the six channels.
class LowPass {
 public:
  LowPass(double corner_hz, double step_s)
      : alpha_(1.0 - std::exp(-2.0 * kPi * corner_hz * step_s)) {}
  std::array<double, 6> Step(const std::array<double, 6>& in) {
    for (int k = 0; k < 6; ++k) {
      first_[k] += alpha_ * (in[k] - first_[k]);
      second_[k] += alpha_ * (first_[k] - second_[k]);
    }
    return second_;
  }

 private:
  double alpha_;
  std::array<double, 6> first_{}, second_{};
};

double Quantise(double value, double count) {
  return count * std::round(value / count);
}

}  // namespace

std::vector<TimedWrench> PoroelasticStoryTrace(HapticCategory category,
                                               std::mt19937_64& rng) {
  const Item item = DrawItem(category, rng);

  // The fork: 4 tines (sometimes 3) of 0.6-0.9 mm equivalent radius with
  // points of 0.1-0.3 mm widening over 1-3 mm; a stress bulb of
  // pi/2 (1 - nu^2) a ~ 1.4 a (Sneddon's flat punch on a column).
  Fork fork;
  fork.tines = random::Canonical(rng) < 0.25 ? 3 : 4;
  fork.radius_m = Uniform(rng, 0.6e-3, 0.9e-3);
  fork.tip_radius_m = Uniform(rng, 0.1e-3, 0.3e-3);
  fork.taper_m = Uniform(rng, 1e-3, 3e-3);
  fork.bulb_m = 1.43 * fork.radius_m;

  // The arm: Cartesian impedance control at 1 kHz, 2-5 kN/m, damping ratio
  // 0.7-1, 2-4 kg apparent mass, a reference descending at 15-40 mm/s to a
  // planned depth of 8-15 mm (at most 60 N of spring). The gripper holds the
  // fork by friction: it slips at 15-50 N and slides at 70-90% of that.
  // The reference eases to a stop there over 0.1-0.2 s (raised cosine).
  const double arm_mass = Uniform(rng, 2.0, 4.0);
  const double stiffness = Uniform(rng, 2000.0, 5000.0);
  const double damping =
      2.0 * Uniform(rng, 0.7, 1.0) * std::sqrt(stiffness * arm_mass);
  const double speed = Uniform(rng, 0.015, 0.04);
  const double plan_m = std::min(Uniform(rng, 8e-3, 15e-3), 60.0 / stiffness);
  const double brake_s = Uniform(rng, 0.1, 0.2);
  const double slip_static = LogUniform(rng, 15.0, 50.0);
  const double slip_kinetic = slip_static * Uniform(rng, 0.7, 0.9);
  const double tool_mass = Uniform(rng, 0.6, 1.1);  // gripper and fork

  // Timing: first touch 0.1-0.3 s in, 0.3-0.45 s recorded after it.
  const double contact_s = Uniform(rng, 0.1, 0.3);
  const double duration_s = contact_s + Uniform(rng, 0.3, 0.45);

  // Geometry in the sensor frame (z up the fork's nominal axis): the fork is
  // held tilted 0-12 deg and 0-12 mm off the sensor's axis; the tines are
  // 16-24 cm below the sensor, the tool's centre of mass 5-9 cm.
  const double tilt = Uniform(rng, 0.0, 12.0) * kPi / 180.0;
  const double tilt_dir = Uniform(rng, 0.0, 2.0 * kPi);
  const Vec3 axis = {std::sin(tilt) * std::cos(tilt_dir),
                     std::sin(tilt) * std::sin(tilt_dir), std::cos(tilt)};
  const Vec3 e1 = Normalized(Cross({0.0, 1.0, 0.0}, axis));
  const Vec3 e2 = Cross(axis, e1);
  const double off_r = Uniform(rng, 0.0, 12e-3);
  const double off_dir = Uniform(rng, 0.0, 2.0 * kPi);
  const Vec3 offset = {off_r * std::cos(off_dir), off_r * std::sin(off_dir),
                       0.0};
  const Vec3 tip_pos = offset + (-Uniform(rng, 0.16, 0.24)) * axis;
  const Vec3 com_pos = (-Uniform(rng, 0.05, 0.09)) * axis;
  // The food pushes sideways too (a sloped top, off-axis cracks): 2-20% of
  // the axial force, in a random direction, kicked at every crack.
  const double lateral_mag = Uniform(rng, 0.02, 0.2);
  const double lateral_dir = Uniform(rng, 0.0, 2.0 * kPi);
  double lambda1 = lateral_mag * std::cos(lateral_dir);
  double lambda2 = lateral_mag * std::sin(lateral_dir);

  // Arm vibration (gear and motor ripple) seen through the tool's mass:
  // two tones at 8-30 Hz and 40-120 Hz, 0.01-0.1 m/s^2, random directions.
  struct Tone {
    double amp, omega, phase;
    Vec3 dir;
  };
  std::array<Tone, 2> tones;
  for (int i = 0; i < 2; ++i) {
    tones[i].amp = LogUniform(rng, 0.01, 0.1);
    tones[i].omega =
        2.0 * kPi *
        (i == 0 ? Uniform(rng, 8.0, 30.0) : Uniform(rng, 40.0, 120.0));
    tones[i].phase = Uniform(rng, 0.0, 2.0 * kPi);
    const double az = Uniform(rng, 0.0, 2.0 * kPi);
    const double el = Uniform(rng, -0.5 * kPi, 0.5 * kPi);
    tones[i].dir = {std::cos(el) * std::cos(az), std::cos(el) * std::sin(az),
                    std::sin(el)};
  }
  // The gripped fork's first bending mode (50-180 Hz, 3-10% damping), rung
  // sideways by 5-20% of every sudden loss of force.
  const double ring_omega = 2.0 * kPi * Uniform(rng, 50.0, 180.0);
  const double ring_zeta = Uniform(rng, 0.03, 0.1);
  const double ring_gain = Uniform(rng, 0.05, 0.2);

  // The sensor: Mini40 over EtherCAT, cycle 500 Hz, 1 kHz or 2 kHz, DC time
  // stamps with +-2% jitter, 0-1% stale frames, a two-pole low-pass at
  // 100-700 Hz, gauge noise, counts of 1/100 N (Fx, Fy), 1/50 N (Fz) and
  // 1/4000 N m, a zero offset, the tool's weight left from a bias taken
  // 0-8 deg away, and thermal drift.
  static constexpr std::array<double, 3> kRates = {500.0, 1000.0, 2000.0};
  const double rate_hz = kRates[random::UniformInt(rng, 0, 2)];
  const double period_s = 1.0 / rate_hz;
  const double stale_p = Uniform(rng, 0.0, 0.01);
  LowPass filter(LogUniform(rng, 100.0, 700.0), kStepS);
  const double force_sd = LogUniform(rng, 0.006, 0.03);
  const double torque_sd = LogUniform(rng, 1.5e-4, 6e-4);
  static constexpr std::array<double, 6> kCounts = {0.01,   0.01,   0.02,
                                                    2.5e-4, 2.5e-4, 2.5e-4};
  std::array<double, 6> offset6{}, drift6{};
  for (int k = 0; k < 6; ++k) {
    offset6[k] = k < 3 ? Uniform(rng, -0.3, 0.3) : Uniform(rng, -0.01, 0.01);
    drift6[k] = k < 3 ? Uniform(rng, -0.05, 0.05) : Uniform(rng, -0.002, 0.002);
  }
  {
    // Gravity on the tool is -axis (down); a bias taken in a pose rotated by
    // a small angle leaves m g (omega x g_hat) behind.
    const double angle = Uniform(rng, 0.0, 8.0) * kPi / 180.0;
    const Vec3 rot_axis = InPlane(e1, e2, Uniform(rng, 0.0, 2.0 * kPi));
    const Vec3 weight = (tool_mass * kGravity * angle) * Cross(rot_axis, axis);
    const Vec3 moment = Cross(com_pos, weight);
    offset6[0] += weight.x;
    offset6[1] += weight.y;
    offset6[2] += weight.z;
    offset6[3] += moment.x;
    offset6[4] += moment.y;
    offset6[5] += moment.z;
  }

  Penetration food(item, fork);
  random::Normal normal;
  double x = -speed * contact_s;  // tine tip depth below the item's top
  double v = speed;
  double squash = 0.0;  // the item's body deflection on the plate
  double slip = 0.0;    // the fork's slide up through the gripper
  bool slipping = false;
  double command = 0.0;
  double next_control = 0.0;
  double ref = x;  // the impedance controller's reference and its speed
  double ref_v = speed;
  double brake_from = -1.0;
  std::array<double, 2> ring{}, ring_v{};

  auto body_force = [&](double d, double* k) {
    const double soft = (item.skin.present && food.state().ruptured)
                            ? item.skin.softening
                            : 1.0;
    if (d <= 0.0) {
      *k = item.body.hertz ? 0.0 : item.body.stiffness;
      return 0.0;
    }
    if (item.body.hertz) {
      const double s = soft * item.body.stiffness * std::sqrt(d);
      *k = 1.5 * s;
      return s * d;
    }
    *k = item.body.stiffness;
    return item.body.stiffness * d;
  };

  std::vector<TimedWrench> trace;
  trace.reserve(static_cast<size_t>(duration_s * rate_hz) + 2);
  const double first_sample = Uniform(rng, 0.0, period_s);
  int64_t sample_index = 0;
  double sample_t = first_sample;
  std::array<double, 6> last{};
  bool have_last = false;

  const int steps = static_cast<int>(std::ceil(duration_s / kStepS)) + 2;
  for (int step = 0; step < steps; ++step) {
    const double t = step * kStepS;
    // Impedance controller, zero-order held between ticks; the reference
    // eases to a stop at the planned depth over `brake_s`.
    if (t >= next_control) {
      if (brake_from < 0.0 && ref >= plan_m - 0.5 * speed * brake_s) {
        brake_from = t;
      }
      if (brake_from >= 0.0) {
        const double into = (t - brake_from) / brake_s;
        ref_v = into < 1.0 ? 0.5 * speed * (1.0 + std::cos(kPi * into)) : 0.0;
      }
      ref += ref_v * kControlS;
      command = stiffness * (ref - x) + damping * (ref_v - v);
      next_control += kControlS;
    }
    const double tip = x - slip;
    Local local = food.At(tip - squash);
    // The item's body squashes on the plate in series (implicit step).
    if (tip > 0.0 || squash > 0.0) {
      double kb = 0.0;
      const double fb = body_force(squash, &kb);
      const double denom = item.body.damping + kStepS * (local.stiffness + kb);
      squash = std::max(0.0, squash + kStepS * (local.force - fb) / denom);
      local = food.At(tip - squash);
    }
    // The gripper slips when the fork's load passes its friction.
    if (local.force > (slipping ? slip_kinetic : slip_static)) {
      double kb = 0.0;
      body_force(squash, &kb);
      const double k_series =
          local.stiffness * kb / std::max(local.stiffness + kb, 1.0);
      slip += (local.force - slip_kinetic) / std::max(k_series, 1e3);
      slipping = true;
      local = food.At(x - slip - squash);
    } else {
      slipping = false;
    }
    // Cracks and bursts.
    const double before = local.force;
    if (food.Fail(x - slip - squash)) {
      local = food.At(x - slip - squash);
      const double drop = before - local.force;
      if (drop > 0.0) {
        const double dir = Uniform(rng, 0.0, 2.0 * kPi);
        ring_v[0] += ring_gain * drop * ring_omega * std::cos(dir);
        ring_v[1] += ring_gain * drop * ring_omega * std::sin(dir);
        lambda1 = std::clamp(lambda1 + 0.02 * normal(rng), -0.3, 0.3);
        lambda2 = std::clamp(lambda2 + 0.02 * normal(rng), -0.3, 0.3);
      }
    }
    const double food_force = local.force;
    // The arm and tool move as one body behind a stiff sensor.
    const double acc = (command - food_force) / arm_mass;
    v += acc * kStepS;
    x += v * kStepS;
    food.Drain(x - slip - squash);
    for (int i = 0; i < 2; ++i) {
      const double a_ring = -ring_omega * ring_omega * ring[i] -
                            2.0 * ring_zeta * ring_omega * ring_v[i];
      ring_v[i] += a_ring * kStepS;
      ring[i] += ring_v[i] * kStepS;
    }

    // The wrench on the sensor: the food at the tines, the tool's inertia
    // at its centre of mass (the sensor carries F + m_t a along the fork).
    const Vec3 at_tips = food_force * axis + (food_force * lambda1) * e1 +
                         (food_force * lambda2) * e2 + ring[0] * e1 +
                         ring[1] * e2;
    Vec3 inertial = (tool_mass * acc) * axis;
    for (const Tone& tone : tones) {
      inertial = inertial + (tool_mass * tone.amp *
                             std::sin(tone.omega * t + tone.phase)) *
                                tone.dir;
    }
    const Vec3 moment = Cross(tip_pos, at_tips) + Cross(com_pos, inertial);
    const Vec3 force = at_tips + inertial;
    const std::array<double, 6> filtered =
        filter.Step({force.x, force.y, force.z, moment.x, moment.y, moment.z});

    // EtherCAT cycles that fall in this step read the filtered gauges.
    const double t_end = t + kStepS;
    while (sample_t <= t_end && sample_t < duration_s) {
      std::array<double, 6> out;
      if (have_last && random::Canonical(rng) < stale_p) {
        out = last;  // the frame was not refreshed this cycle
      } else {
        for (int k = 0; k < 6; ++k) {
          const double sd = k < 3 ? (k == 2 ? 1.5 : 1.0) * force_sd : torque_sd;
          out[k] = Quantise(filtered[k] + offset6[k] + drift6[k] * sample_t +
                                sd * normal(rng),
                            kCounts[k]);
        }
      }
      last = out;
      have_last = true;
      TimedWrench sample;
      sample.t_s = sample_t;
      sample.wrench = domain::WrenchFromChannels(out);
      trace.push_back(sample);
      ++sample_index;
      sample_t = first_sample + sample_index * period_s +
                 Uniform(rng, -0.02, 0.02) * period_s;
    }
  }
  return trace;
}

}  // namespace bitewise::sim
