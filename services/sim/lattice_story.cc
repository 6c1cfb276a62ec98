// The lattice story: what the Forque feels when a fork, driven by an
// admittance-controlled arm, breaks its way through a lattice of plant cells.
//
// Tissue. Under each of the four tines the food is a discrete column of cell
// walls (nodes) one cell diameter d apart. Neighbouring walls are joined by
// the cell between them, an axial spring k_a = E A / d (A the tine tip's
// area); each wall is tied to the surrounding tissue by the ring of wall
// junctions round the tine's path, a shear spring k_s = (2 pi / 3) E d (shear
// modulus E / 3 of an incompressible tissue over a shear-lag length of the
// tip radius a). This chain on a foundation has the stiffness of Boussinesq's
// punch (sqrt(k_a k_s) = 2.6 E a against 2.7 E a), and its load fades over
// 1.2 a / d walls, so the window of walls the solver carries (at most 64)
// holds the whole loaded zone; below it a tail spring stands for the rest
// of the tissue, or the last cell sits on the plate. Bonds break
// stochastically and with the rate of loading: each bond has a Weibull
// strength (modulus m: narrow in turgid, crisp tissue, wide where fibres or
// stone cells are mixed in), and breaks by Bell/Zhurkov kinetics, a hazard
// nu0 exp((load / strength - 1) / beta) against an exponential budget drawn
// with the bond, so a fast tine meets stronger walls. Two kinds of bond fail:
// the wall under the tip bursts when the tip's pressure exceeds its rupture
// pressure (the tine then passes into the next cell, its gap closed only by
// the elastic displacement the column already had), and a junction ring
// shears when its wall's displacement over a exceeds its failure strain (the
// wall keeps a residual, frictional grip; the column softens, loading the
// walls below, which is how a crack runs ahead of the tip as an avalanche).
// How large a burst's drop is, is not written per category: the tine
// unloads by about a cell diameter over the column's sag at the burst
// (about 1.2 p_c / E tip radii, p_c the rupture pressure), shared with the
// other tines and partly made up at once by the energy stored in the arm,
// which drives the tine on into the next walls. Behind the tip the tapered
// tine (tip area A, shaft 2-3.5 A reached 3-5 mm up) wedges the hole open
// against a fraction of the rupture pressure (small where the tissue splits
// ahead of the wedge, near one where it must be pushed aside) and rubs on
// its walls (Coulomb, mu 0.15-0.4 on wet tissue, against a residual wall
// pressure). Rupture pressures are those of small-probe puncture tests
// (Magness-Taylor firmness over the probe's area, raised for a 1 mm tip
// whose perimeter counts for more), moduli and cell sizes from tissue
// mechanics, all as I remember them and rounded wide.
//  - Hard (carrot, celery, apple, cucumber): turgid parenchyma, E 1.5-12
//    MPa, rupture 0.6-4 MPa (carrot highest), junction rings failing at
//    15-30% shear strain with 2-8% residual grip, narrow strengths (m 6-12;
//    celery's strands 3-6), quick kinetics (beta 0.03-0.06). Walls burst
//    only under 1-4 N a tine, so the force climbs steeply to the highest
//    peaks; the small cells (40-250 um) against a sag of a few cells make
//    each burst a crack of a few tenths of a newton, repeated as the tines
//    advance: a steep, finely cracked rise.
//  - Medium (strawberry, cantaloupe, unripe banana, honeydew, pear): E
//    0.3-3 MPa, rupture 0.1-1 MPa, rings failing at 25-50% with 10-30%
//    residual grip, m 2-6 (pear's stone cells), and large cells in melons
//    (200-400 um): the rings round the tip give way over many walls (cells
//    collapse) and the walls burst at a lower force, each burst unloading
//    its tine by a larger share: a lower, coarsely serrated rise.
//  - Soft (ripe banana, kiwi, egg, mango): E 0.05-0.6 MPa, rupture 0.06-0.3
//    MPa, walls that stretch 50-120% on slow kinetics (beta 0.1-0.2) and
//    keep 30-60% of their grip: the column sags by many cells before a wall
//    bursts, so bursts vanish in a smooth rise that is mostly the wedge and
//    the rubbing of a paste; a newton or two over the fork, often less.
//  - Hard-skin (cherry tomato, grape, blueberry, olive): wall 0 is a skin, a
//    membrane of stiffness E_s t 500-6000 N/m pre-tensioned by turgor to
//    20-100 N/m, whose ring force 2 pi (T + E_s t eps) u stiffens as it is
//    stretched (eps = (u / l)^2 / 2 over a span l of 2.5 tip radii) and which
//    bursts at 10-30% strain (0.2-2 N a tine, the skin-break forces of small
//    probes); beneath it soft flesh (E 0.05-1 MPa, olive's firmest). The
//    round berry, 10-28 mm across, squashes on the plate at 1.5-7 N/mm
//    (FirmTech-style firmness), in series with the arm; only tines within
//    0.85 R of its centre land, the outer ones later on its curve. When a
//    skin bursts it splits round the berry with probability 0.3-0.7 (every
//    tine's skin goes) and in any case the released pressure slackens the
//    other skins to 10-40% of their tension, and the energy stored in the
//    squashed berry and the arm throws the tines into the flesh: the force
//    loses most of itself within a few ms.
//
// Arm. A JACO2 taking Cartesian velocity commands at 100 Hz from an
// admittance law on the tared Forque reading, v = v0 (1 - Fz / F_lim)
// (v0 15-45 mm/s, F_lim 12-30 N: a damper that lets the food slow the fork),
// capped to stop at a depth of 45-75% of the item's height; the arm tracks
// the command with a 20-50 ms lag and is a 3-8 N/mm spring (harmonic drives,
// carbon links) between its motors and the Forque, with an idle vibration of
// 6-25 Hz. The fork is rolled 0-360 deg about its axis, its tines 5-7 mm
// apart at 10-15 cm from the sensor, tilted up to 8 deg; the item off-centre.
//
// Sensor. Tine forces and their moments about the sensor pass through the
// fork-and-adapter mount, one mode at 250-900 Hz (damping 3-12%), then the
// DAQ's RC anti-alias (0.35-0.5 of the ADC rate); a 16-bit ADC at 1-7 kHz
// over the Nano25's ranges (+-125 N, Fz +-500 N, +-3 N m), with white noise,
// an untared offset (the fork's weight, bias) and thermal drift; block
// averages of 1, 2, 4 or 8 samples (125 Hz-7 kHz out, a +-150 ppm crystal),
// sent over USB in packets of about 1 ms that the host stamps on arrival
// (0.5-3 ms latency on the 1 ms frame grid, 0-0.3 ms of scheduler jitter),
// back-filling each packet's samples at the nominal period.
//
// Recorder. A pre-triggered acquisition cut from that stream: tare on its
// first 50 ms, trigger where the tared force passes 1 N; the touch 0.1-0.2 s
// in (later if needed to bring the trigger by 0.29 s), 0.3-0.45 s after the
// touch and at least 0.3 s after the trigger. An item too soft to trigger by
// then is recorded up to just before its trigger.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "services/domain/random.h"
#include "services/sim/trace_stories.h"

namespace bitewise::sim {
namespace {

using random::Engine;

constexpr double kPi = 3.14159265358979323846;
constexpr double kPhysicsDt = 1.0 / 20000.0;  // 20 kHz
constexpr int kMaxWindow = 64;
constexpr double kBellRateHz = 2000.0;    // attempt rate at the threshold
constexpr double kControlPeriodS = 0.01;  // JACO2 API at 100 Hz

struct Range {
  double lo;
  double hi;
};

double Draw(Engine& rng, Range r) { return random::Uniform(rng, r.lo, r.hi); }

// One food's tissue: a row of ranges.
struct FoodRanges {
  Range modulus_mpa;      // tissue Young's modulus
  Range burst_mpa;        // a wall's rupture pressure under the tip
  Range ring_strain;      // junction rings' shear failure strain
  Range weibull;          // Weibull modulus of the strengths
  Range bell_beta;        // width of the Bell kinetics
  Range cell_um;          // cell diameter
  Range height_mm;        // piece height, or berry diameter
  Range halfwidth_mm;     // piece half-width (cut pieces)
  Range skin_et_n_per_m;  // skin membrane stiffness (0: no skin)
  Range skin_strain;      // skin burst strain
  Range body_n_per_mm;    // whole berry on the plate
};

FoodRanges FoodOf(HapticCategory category, int food) {
  constexpr Range kNone{0.0, 0.0};
  switch (category) {
    case HapticCategory::kHard: {
      static constexpr std::array<FoodRanges, 4> kFoods = {{
          // carrot, celery, apple, cucumber
          {{6, 12},
           {2, 4},
           {0.15, 0.25},
           {8, 12},
           {0.03, 0.05},
           {40, 80},
           {8, 14},
           {6, 10},
           kNone,
           kNone,
           kNone},
          {{4, 10},
           {1.5, 3},
           {0.2, 0.3},
           {3, 6},
           {0.03, 0.06},
           {40, 80},
           {6, 10},
           {5, 8},
           kNone,
           kNone,
           kNone},
          {{2, 6},
           {0.8, 1.6},
           {0.15, 0.25},
           {6, 10},
           {0.03, 0.05},
           {150, 250},
           {10, 18},
           {8, 14},
           kNone,
           kNone,
           kNone},
          {{1.5, 4},
           {0.6, 1.2},
           {0.2, 0.3},
           {6, 10},
           {0.03, 0.06},
           {100, 200},
           {8, 15},
           {8, 14},
           kNone,
           kNone,
           kNone},
      }};
      return kFoods[food];
    }
    case HapticCategory::kMedium: {
      static constexpr std::array<FoodRanges, 5> kFoods = {{
          // strawberry, cantaloupe, unripe banana, honeydew, pear
          {{0.3, 0.8},
           {0.1, 0.3},
           {0.3, 0.5},
           {3, 5},
           {0.06, 0.1},
           {100, 200},
           {12, 20},
           {8, 12},
           kNone,
           kNone,
           kNone},
          {{0.5, 1.5},
           {0.15, 0.4},
           {0.3, 0.5},
           {4, 6},
           {0.05, 0.09},
           {200, 400},
           {12, 20},
           {8, 14},
           kNone,
           kNone,
           kNone},
          {{1, 3},
           {0.4, 0.9},
           {0.25, 0.45},
           {4, 6},
           {0.05, 0.09},
           {60, 120},
           {10, 16},
           {7, 10},
           kNone,
           kNone,
           kNone},
          {{0.6, 1.8},
           {0.2, 0.5},
           {0.3, 0.5},
           {4, 6},
           {0.05, 0.09},
           {200, 400},
           {12, 20},
           {8, 14},
           kNone,
           kNone,
           kNone},
          {{1, 3},
           {0.5, 1.0},
           {0.25, 0.4},
           {2, 4},
           {0.05, 0.08},
           {100, 200},
           {10, 18},
           {8, 14},
           kNone,
           kNone,
           kNone},
      }};
      return kFoods[food];
    }
    case HapticCategory::kSoft: {
      static constexpr std::array<FoodRanges, 4> kFoods = {{
          // ripe banana, kiwi, egg, mango
          {{0.1, 0.3},
           {0.08, 0.18},
           {0.5, 1.0},
           {2, 4},
           {0.1, 0.2},
           {60, 120},
           {10, 16},
           {7, 10},
           kNone,
           kNone,
           kNone},
          {{0.2, 0.6},
           {0.12, 0.3},
           {0.5, 0.9},
           {3, 5},
           {0.1, 0.2},
           {100, 300},
           {8, 14},
           {8, 12},
           kNone,
           kNone,
           kNone},
          {{0.05, 0.15},
           {0.06, 0.15},
           {0.6, 1.2},
           {5, 8},
           {0.1, 0.2},
           {80, 150},
           {10, 18},
           {8, 14},
           kNone,
           kNone,
           kNone},
          {{0.1, 0.4},
           {0.1, 0.3},
           {0.5, 1.0},
           {2, 4},
           {0.1, 0.2},
           {80, 150},
           {10, 18},
           {8, 14},
           kNone,
           kNone,
           kNone},
      }};
      return kFoods[food];
    }
    case HapticCategory::kHardSkin:
      break;
  }
  static constexpr std::array<FoodRanges, 4> kBerries = {{
      // cherry tomato, grape, blueberry, olive (flesh, then skin and body)
      {{0.1, 0.4},
       {0.1, 0.25},
       {0.4, 0.8},
       {3, 5},
       {0.08, 0.15},
       {100, 200},
       {20, 28},
       kNone,
       {2500, 6000},
       {0.1, 0.25},
       {3, 6}},
      {{0.05, 0.2},
       {0.05, 0.12},
       {0.5, 0.9},
       {3, 5},
       {0.08, 0.15},
       {100, 200},
       {16, 22},
       kNone,
       {800, 3000},
       {0.1, 0.3},
       {2, 4}},
      {{0.1, 0.3},
       {0.06, 0.15},
       {0.4, 0.8},
       {3, 5},
       {0.08, 0.15},
       {80, 150},
       {10, 14},
       kNone,
       {500, 1500},
       {0.1, 0.3},
       {1.5, 3}},
      {{0.3, 1.0},
       {0.15, 0.4},
       {0.3, 0.6},
       {3, 5},
       {0.06, 0.12},
       {80, 150},
       {16, 24},
       kNone,
       {1000, 3000},
       {0.1, 0.25},
       {3, 7}},
  }};
  return kBerries[food];
}

// The item drawn for one trace, in SI units.
struct Tissue {
  double modulus_pa;
  double burst_pa;
  double ring_strain;
  double weibull;
  double bell_beta;
  double cell_m;
  double height_m;
  double residual_ring;   // broken ring's remaining grip (fraction of k_s)
  double wedge_fraction;  // hole-opening pressure over the rupture pressure
  double friction_mu;
  double wall_pressure_fraction;  // residual pressure on the shaft
  bool skin;
  double skin_et_n_per_m;
  double skin_strain;
  double turgor_tension_n_per_m;
  double split_probability;
  double body_n_per_m;  // 0 for cut pieces (the lattice reaches the plate)
};

// A bond's strength around `mean`: Weibull with modulus `m`, mean `mean`.
double WeibullStrength(Engine& rng, double mean, double m) {
  const double e = -std::log(1.0 - random::Canonical(rng));
  return mean * std::pow(e, 1.0 / m) / std::tgamma(1.0 + 1.0 / m);
}

double ExponentialBudget(Engine& rng) {
  return -std::log(1.0 - random::Canonical(rng));
}

struct Wall {
  double burst;  // rupture pressure (Pa), or the skin's burst strain
  double burst_budget;
  double burst_hazard = 0.0;
  double ring_strain;
  double ring_budget;
  double ring_hazard = 0.0;
  bool ring_intact = true;
};

struct Tine {
  bool lands = false;
  double landing_m = 0.0;  // arm travel at which the tip meets the surface
  double lateral_m = 0.0;  // offset along the fork's plane
  double slope = 0.0;      // surface slope where it lands
  std::vector<Wall> walls;
  int top = 0;  // the wall the tip presses
  bool skin = false;
  double skin_tension = 0.0;
  double skin_solved_u = 0.0;  // skin displacement its stiffness was set at
  std::array<double, kMaxWindow> unit_disp{};  // wall displacement per newton
  int window = 0;
  double gain = 0.0;  // contact force per metre of overlap
  double deepest_m = 0.0;
  double contact_n = 0.0;
  double shaft_n = 0.0;
};

// Hazard of a Bell bond at load ratio `ratio` over one step.
double BellHazard(double ratio, double beta) {
  if (ratio < 0.5) return 0.0;
  return kBellRateHz * std::exp((ratio - 1.0) / beta) * kPhysicsDt;
}

class LatticeFork {
 public:
  LatticeFork(const Tissue& tissue, double tip_radius_m, double shaft_area_m2,
              double taper_m, std::vector<Tine> tines, Engine& rng)
      : tissue_(tissue),
        tip_radius_(tip_radius_m),
        tip_area_(kPi * tip_radius_m * tip_radius_m),
        shaft_area_(shaft_area_m2),
        taper_(taper_m),
        tines_(std::move(tines)),
        rng_(rng) {
    k_axial_ = tissue_.modulus_pa * tip_area_ / tissue_.cell_m;
    k_ring_ = 2.0 * kPi / 3.0 * tissue_.modulus_pa * tissue_.cell_m;
    k_tip_ = 2.0 * k_axial_;
    const double decay = std::sqrt(k_axial_ / k_ring_);
    window_ =
        std::clamp(static_cast<int>(std::ceil(5.0 * decay)) + 2, 8, kMaxWindow);
    plate_walls_ = static_cast<int>(tissue_.height_m / tissue_.cell_m);
    for (Tine& tine : tines_) {
      tine.skin = tissue_.skin;
      tine.skin_tension = tissue_.turgor_tension_n_per_m;
      if (tine.lands) Refresh(tine);
    }
  }

  const std::vector<Tine>& tines() const { return tines_; }

  // Total axial force for the arm's motor-side travel `arm_m`, through the
  // series compliance `series_m_per_n` (arm, and the berry's body); advances
  // the lattice by one step (bonds break at the end of it).
  double Step(double arm_m, double series_m_per_n) {
    // Active set of the piecewise-linear balance: tines in contact, taken in
    // order of their overlap at zero force.
    std::array<int, 4> order{};
    std::array<double, 4> reach{};
    int n = 0;
    double shaft = 0.0;
    for (int i = 0; i < 4; ++i) {
      const Tine& tine = tines_[i];
      if (!tine.lands) continue;
      shaft += tine.shaft_n;
      reach[i] = arm_m - tine.landing_m - TopDepth(tine);
      if (reach[i] <= 0.0) continue;
      int j = n++;  // insertion, deepest reach first
      for (; j > 0 && reach[order[j - 1]] < reach[i]; --j) {
        order[j] = order[j - 1];
      }
      order[j] = i;
    }
    double force = shaft;
    double sum_gain_reach = 0.0;
    double sum_gain = 0.0;
    for (int k = 0; k <= n; ++k) {
      const double f =
          (sum_gain_reach + shaft) / (1.0 + series_m_per_n * sum_gain);
      const bool next_out = k == n || reach[order[k]] <= series_m_per_n * f;
      if (next_out) {
        force = f;
        break;
      }
      sum_gain_reach += tines_[order[k]].gain * reach[order[k]];
      sum_gain += tines_[order[k]].gain;
    }
    const double tip_travel = arm_m - series_m_per_n * force;
    for (Tine& tine : tines_) {
      if (!tine.lands) continue;
      const double depth = tip_travel - tine.landing_m;
      tine.contact_n = tine.gain * std::max(0.0, depth - TopDepth(tine));
      if (depth > tine.deepest_m) {
        tine.deepest_m = depth;
        tine.shaft_n = ShaftForce(tine);
      }
      BreakBonds(tine);
    }
    return force;
  }

 private:
  double TopDepth(const Tine& tine) const {
    // The skin is wall 0 at the surface; flesh walls follow a cell apart.
    return tine.top * tissue_.cell_m;
  }

  bool OnSkin(const Tine& tine) const { return tine.skin && tine.top == 0; }

  const Wall& WallAt(Tine& tine, int index) {
    while (static_cast<int>(tine.walls.size()) <= index) {
      Wall wall;
      const bool skin = tine.skin && tine.walls.empty();
      wall.burst =
          skin ? WeibullStrength(rng_, tissue_.skin_strain, 6.0)
               : WeibullStrength(rng_, tissue_.burst_pa, tissue_.weibull);
      wall.burst_budget = ExponentialBudget(rng_);
      wall.ring_strain =
          WeibullStrength(rng_, tissue_.ring_strain, tissue_.weibull);
      wall.ring_budget = ExponentialBudget(rng_);
      tine.walls.push_back(wall);
    }
    return tine.walls[index];
  }

  // The skin's ring stiffness at displacement u: tension plus stretch.
  double SkinRing(const Tine& tine, double u) const {
    const double span = 2.5 * tip_radius_;
    const double strain = 0.5 * (u / span) * (u / span);
    return 2.0 * kPi * (tine.skin_tension + tissue_.skin_et_n_per_m * strain);
  }

  // Solves the column under the tip for a unit load (Thomas algorithm on
  // the tridiagonal stiffness of the window of walls).
  void Refresh(Tine& tine) {
    const int first = tine.top;
    const int last =
        std::min(first + window_, std::max(plate_walls_, first + 1));
    const int n = last - first;
    std::array<double, kMaxWindow> pivot{};
    std::array<double, kMaxWindow> rhs{};
    for (int j = 0; j < n; ++j) {
      const Wall& wall = WallAt(tine, first + j);
      double ring =
          wall.ring_intact ? k_ring_ : tissue_.residual_ring * k_ring_;
      if (tine.skin && first + j == 0) {
        ring = SkinRing(tine, tine.unit_disp[0] * tine.contact_n);
      }
      // Below the window: the rest of the tissue, or the last cell on the
      // plate.
      const double below = j < n - 1 || last >= plate_walls_
                               ? k_axial_
                               : std::sqrt(k_axial_ * k_ring_);
      const double above = j > 0 ? k_axial_ : 0.0;
      double diag = ring + above + below;
      double load = j == 0 ? 1.0 : 0.0;
      if (j > 0) {
        diag -= k_axial_ * k_axial_ / pivot[j - 1];
        load += k_axial_ * rhs[j - 1] / pivot[j - 1];
      }
      pivot[j] = diag;
      rhs[j] = load;
    }
    for (int j = n - 1; j >= 0; --j) {
      const double pushed = j < n - 1 ? k_axial_ * tine.unit_disp[j + 1] : 0.0;
      tine.unit_disp[j] = (rhs[j] + pushed) / pivot[j];
    }
    tine.window = n;
    const double k_tip = OnSkin(tine) ? 4.0 * k_axial_ : k_tip_;
    tine.gain = k_tip / (1.0 + k_tip * tine.unit_disp[0]);
  }

  // Wedging the hole open behind the tip, and rubbing on its walls.
  double ShaftForce(const Tine& tine) const {
    if (tine.top == 0 && !(tine.skin && tine.deepest_m > 0.0)) return 0.0;
    const double inside = std::max(0.0, tine.deepest_m);
    const double grown = std::min(1.0, inside / taper_);
    const double wedge = tissue_.wedge_fraction * tissue_.burst_pa *
                         (shaft_area_ - tip_area_) * grown;
    // Perimeter grows with the tine's section; integrate along the taper.
    const double tip_perimeter = 2.0 * kPi * tip_radius_;
    const double shaft_perimeter = 2.0 * std::sqrt(kPi * shaft_area_);
    const double tapered = std::min(inside, taper_);
    const double wetted =
        tip_perimeter * inside +
        (shaft_perimeter - tip_perimeter) *
            (tapered * tapered / (2.0 * taper_) + (inside - tapered));
    const double friction = tissue_.friction_mu *
                            tissue_.wall_pressure_fraction * tissue_.burst_pa *
                            wetted;
    return wedge + friction;
  }

  void BreakBonds(Tine& tine) {
    bool changed = false;
    const double f = tine.contact_n;
    if (f > 0.0) {
      Wall& top = tine.walls[tine.top];
      double ratio;
      if (OnSkin(tine)) {
        const double span = 2.5 * tip_radius_;
        const double u = tine.unit_disp[0] * f;
        ratio = 0.5 * (u / span) * (u / span) / top.burst;
      } else {
        ratio = f / tip_area_ / top.burst;
      }
      top.burst_hazard += BellHazard(ratio, tissue_.bell_beta);
      if (top.burst_hazard >= top.burst_budget) {
        if (OnSkin(tine)) SkinBurst(tine);
        ++tine.top;
        changed = true;
      } else {
        for (int j = OnSkin(tine) ? 1 : 0; j < tine.window; ++j) {
          const double u = tine.unit_disp[j] * f;
          if (u < 0.02 * tine.unit_disp[0] * f) break;
          Wall& wall = tine.walls[tine.top + j];
          if (!wall.ring_intact) continue;
          wall.ring_hazard +=
              BellHazard(u / tip_radius_ / wall.ring_strain, tissue_.bell_beta);
          if (wall.ring_hazard >= wall.ring_budget) {
            wall.ring_intact = false;
            changed = true;
          }
        }
      }
    }
    // The skin's secant stiffness is renewed once its stretch has moved.
    const double skin_u = tine.unit_disp[0] * f;
    if (changed || (OnSkin(tine) && std::abs(skin_u - tine.skin_solved_u) >
                                        0.01 * tine.skin_solved_u + 1e-7)) {
      Refresh(tine);
      tine.skin_solved_u = skin_u;
    }
  }

  // A burst skin: the berry's pressure goes; it may split round the berry.
  void SkinBurst(const Tine& burst) {
    const bool split = random::Canonical(rng_) < tissue_.split_probability;
    const double slack = random::Uniform(rng_, 0.1, 0.4);
    for (Tine& other : tines_) {
      other.skin_tension *= slack;
      if (split && &other != &burst && other.lands && OnSkin(other)) {
        other.top = 1;
        Refresh(other);
      }
    }
  }

  Tissue tissue_;
  double tip_radius_;
  double tip_area_;
  double shaft_area_;
  double taper_;
  std::vector<Tine> tines_;
  Engine& rng_;
  double k_axial_ = 0.0;
  double k_ring_ = 0.0;
  double k_tip_ = 0.0;
  int window_ = 0;
  int plate_walls_ = 0;
};

// The recorder: a pre-triggered acquisition cut from the host's stream.
// It tares on the window's first 50 ms and triggers where the tared force
// passes 1 N, the rule its consumers use. The window opens `lead_s` before
// the touch at host time `touch_s`, pulled later (to no less than 0.1 s)
// so that a trigger falls within 0.29 s of its start, and records 0.3 s past
// the trigger and at least `after_s` past the touch. A slow item that would
// trigger later than that (a paste the fork slides into) is recorded up to
// just before its trigger: for the consumer it never reaches 1 N.
std::vector<TimedWrench> CutRecording(const std::vector<TimedWrench>& stream,
                                      double touch_s, double lead_s,
                                      double after_s) {
  const auto at = [&](double t) {
    return static_cast<size_t>(
        std::lower_bound(
            stream.begin(), stream.end(), t,
            [](const TimedWrench& w, double x) { return w.t_s < x; }) -
        stream.begin());
  };
  const auto trigger = [&](size_t first) {
    std::array<double, 3> tare{};
    int n = 0;
    for (size_t i = first;
         i < stream.size() && stream[i].t_s < stream[first].t_s + 0.05; ++i) {
      for (int k = 0; k < 3; ++k) tare[k] += stream[i].wrench.force_n[k];
      ++n;
    }
    for (double& v : tare) v /= std::max(n, 1);
    for (size_t i = first; i < stream.size(); ++i) {
      const auto& f = stream[i].wrench.force_n;
      if (std::hypot(f[0] - tare[0], f[1] - tare[1], f[2] - tare[2]) > 1.0) {
        return i;
      }
    }
    return stream.size();
  };
  size_t first = at(touch_s - lead_s);
  size_t fired = trigger(first);
  for (int pull = 0; pull < 3 && fired < stream.size() &&
                     stream[fired].t_s - stream[first].t_s > 0.29;
       ++pull) {
    lead_s = std::max(0.1, 0.29 - (stream[fired].t_s - touch_s));
    first = at(touch_s - lead_s);
    fired = trigger(first);
  }
  size_t last = at(touch_s + after_s);
  if (fired < stream.size()) {
    if (stream[fired].t_s - stream[first].t_s <= 0.3) {
      last = std::max(last, at(stream[fired].t_s + 0.3));
    } else {
      last = std::min(last, fired);
    }
  }
  last = std::min(last, stream.size());
  std::vector<TimedWrench> trace(stream.begin() + first, stream.begin() + last);
  const double start = trace.front().t_s;
  for (TimedWrench& sample : trace) sample.t_s -= start;
  return trace;
}

}  // namespace

std::vector<TimedWrench> LatticeStoryTrace(HapticCategory category,
                                           std::mt19937_64& rng) {
  // The item.
  const int foods = category == HapticCategory::kMedium ? 5 : 4;
  const FoodRanges ranges =
      FoodOf(category, static_cast<int>(random::UniformInt(rng, 0, foods - 1)));
  Tissue tissue;
  tissue.modulus_pa = 1e6 * random::LogUniform(rng, ranges.modulus_mpa.lo,
                                               ranges.modulus_mpa.hi);
  tissue.burst_pa =
      1e6 * random::LogUniform(rng, ranges.burst_mpa.lo, ranges.burst_mpa.hi);
  tissue.ring_strain = Draw(rng, ranges.ring_strain);
  tissue.weibull = Draw(rng, ranges.weibull);
  tissue.bell_beta = Draw(rng, ranges.bell_beta);
  tissue.cell_m = 1e-6 * Draw(rng, ranges.cell_um);
  tissue.height_m = 1e-3 * Draw(rng, ranges.height_mm);
  // Crisp tissue breaks clean and splits ahead of the wedge; pastes keep
  // their grip and must be pushed aside.
  struct Toughness {
    Range residual_ring, wedge_fraction, friction_mu, wall_pressure;
  };
  static constexpr std::array<Toughness, 4> kToughness = {{
      {{0.02, 0.08}, {0.15, 0.35}, {0.15, 0.3}, {0.05, 0.15}},  // hard
      {{0.1, 0.3}, {0.3, 0.6}, {0.2, 0.35}, {0.1, 0.25}},       // medium
      {{0.3, 0.6}, {0.5, 0.9}, {0.2, 0.4}, {0.2, 0.4}},         // soft
      {{0.2, 0.5}, {0.4, 0.8}, {0.2, 0.4}, {0.15, 0.35}},       // berry flesh
  }};
  const Toughness& toughness = kToughness[static_cast<int>(category)];
  tissue.residual_ring = Draw(rng, toughness.residual_ring);
  tissue.wedge_fraction = Draw(rng, toughness.wedge_fraction);
  tissue.friction_mu = Draw(rng, toughness.friction_mu);
  tissue.wall_pressure_fraction = Draw(rng, toughness.wall_pressure);
  tissue.skin = ranges.skin_et_n_per_m.hi > 0.0;
  tissue.skin_et_n_per_m = 0.0;
  tissue.skin_strain = 0.0;
  tissue.turgor_tension_n_per_m = 0.0;
  tissue.split_probability = 0.0;
  tissue.body_n_per_m = 0.0;
  if (tissue.skin) {
    tissue.skin_et_n_per_m = random::LogUniform(rng, ranges.skin_et_n_per_m.lo,
                                                ranges.skin_et_n_per_m.hi);
    tissue.skin_strain = Draw(rng, ranges.skin_strain);
    tissue.turgor_tension_n_per_m = random::Uniform(rng, 20.0, 100.0);
    tissue.split_probability = random::Uniform(rng, 0.3, 0.7);
    tissue.body_n_per_m = 1e3 * Draw(rng, ranges.body_n_per_mm);
  }

  // The fork over the item.
  const double tip_radius = 1e-3 * random::Uniform(rng, 0.35, 0.6);
  const double shaft_area =
      kPi * tip_radius * tip_radius * random::Uniform(rng, 2.0, 3.5);
  const double taper = 1e-3 * random::Uniform(rng, 3.0, 5.0);
  const double pitch = 1e-3 * random::Uniform(rng, 5.0, 7.0);
  const double fork_length = random::Uniform(rng, 0.10, 0.15);
  const double roll = random::Uniform(rng, 0.0, 2.0 * kPi);
  const double tilt = random::Uniform(rng, 0.0, 8.0) * kPi / 180.0;
  const double tilt_heading = random::Uniform(rng, 0.0, 2.0 * kPi);
  const double lateral_share = random::Uniform(rng, 0.1, 0.3);
  const double half_width = tissue.skin ? 0.5 * tissue.height_m
                                        : 1e-3 * Draw(rng, ranges.halfwidth_mm);
  double centre = random::Uniform(rng, -0.3, 0.3) * half_width;
  const double face_slope = random::Uniform(rng, -0.15, 0.15);
  std::vector<Tine> tines(4);
  for (int pass = 0; pass < 2; ++pass) {
    int landed = 0;
    for (int i = 0; i < 4; ++i) {
      Tine& tine = tines[i];
      tine.lateral_m = (i - 1.5) * pitch;
      const double dx = tine.lateral_m - centre;
      if (tissue.skin) {
        tine.lands = std::abs(dx) < 0.85 * half_width;
        const double rise = std::sqrt(half_width * half_width - dx * dx);
        tine.landing_m = half_width - rise;
        tine.slope = std::min(1.5, dx / rise);
      } else {
        tine.lands = std::abs(dx) < half_width;
        tine.landing_m = dx * face_slope;
        tine.slope = face_slope;
      }
      landed += tine.lands ? 1 : 0;
    }
    if (landed > 0) break;
    centre = 0.0;  // a fork that would miss is aimed again, at the centre
  }
  double highest = 1.0;
  for (const Tine& tine : tines) {
    if (tine.lands) highest = std::min(highest, tine.landing_m);
  }
  // The arm and the timing.
  // The stream starts 0.2 s before the touch; the recorder cuts its window
  // from it (below).
  const double touch_s = 0.2;
  const double lead_draw = random::Uniform(rng, 0.1, 0.2);
  const double speed = random::LogUniform(rng, 0.015, 0.045);
  const double force_limit = random::Uniform(rng, 12.0, 30.0);
  const double lag_s = random::Uniform(rng, 0.02, 0.05);
  const double arm_n_per_m = 1e3 * random::Uniform(rng, 3.0, 8.0);
  const double braking = random::Uniform(rng, 0.3, 1.0);
  const double target_m = random::Uniform(rng, 0.45, 0.75) * tissue.height_m;
  const double fork_kg = random::Uniform(rng, 0.03, 0.07);
  const double shake = random::Uniform(rng, 0.05, 0.6);
  const double shake_hz = random::Uniform(rng, 6.0, 25.0);
  const double shake_phase = random::Uniform(rng, 0.0, 2.0 * kPi);
  const std::array<double, 3> shake_dir = {
      random::Uniform(rng, -0.5, 0.5), random::Uniform(rng, -0.5, 0.5), 1.0};
  double next_tick = random::Uniform(rng, 0.0, kControlPeriodS);
  const double after_s = random::Uniform(rng, 0.3, 0.45);
  const double end_s = touch_s + 0.52;
  const double touch_m = speed * touch_s;
  for (Tine& tine : tines) tine.landing_m += touch_m - highest;
  const double series =
      1.0 / arm_n_per_m + (tissue.skin ? 1.0 / tissue.body_n_per_m : 0.0);
  LatticeFork fork(tissue, tip_radius, shaft_area, taper, std::move(tines),
                   rng);

  // The mount's mode and the DAQ's anti-alias filter.
  const double mode = 2.0 * kPi * random::LogUniform(rng, 250.0, 900.0);
  const double damping = random::Uniform(rng, 0.03, 0.12);
  const double adc_hz = random::LogUniform(rng, 1000.0, 7000.0);
  const double alias_hz = random::Uniform(rng, 0.35, 0.5) * adc_hz;
  const double alias_gain = 1.0 - std::exp(-2.0 * kPi * alias_hz * kPhysicsDt);

  // Physics at 20 kHz; what reaches the ADC is kept per step.
  std::vector<std::array<double, 6>> gauge;
  gauge.reserve(static_cast<size_t>((end_s + 0.5) / kPhysicsDt));
  std::array<double, 6> mount{};
  std::array<double, 6> mount_rate{};
  std::array<double, 6> filtered{};
  double arm = 0.0;
  double velocity = speed;
  double command = speed;
  for (int step = 0; step * kPhysicsDt < end_s; ++step) {
    const double t = step * kPhysicsDt;
    if (t >= next_tick) {
      command = speed * std::max(0.0, 1.0 - filtered[2] / force_limit);
      const double remaining = target_m - (arm - touch_m);
      command = std::min(command,
                         std::sqrt(2.0 * braking * std::max(0.0, remaining)));
      next_tick += kControlPeriodS;
    }
    const double accel = (command - velocity) / lag_s;
    velocity += accel * kPhysicsDt;
    arm += velocity * kPhysicsDt;
    fork.Step(arm, series);

    // The wrench the tines put on the fork, and its moments at the sensor.
    std::array<double, 6> load{};
    const double c = std::cos(roll);
    const double s = std::sin(roll);
    for (const Tine& tine : fork.tines()) {
      if (!tine.lands) continue;
      const double fz = tine.contact_n + tine.shaft_n;
      const double lateral = fz * lateral_share * tine.slope;
      const std::array<double, 3> f = {lateral * c, lateral * s, fz};
      const std::array<double, 3> r = {tine.lateral_m * c, tine.lateral_m * s,
                                       fork_length};
      load[0] += f[0];
      load[1] += f[1];
      load[2] += f[2];
      load[3] += r[1] * f[2] - r[2] * f[1];
      load[4] += r[2] * f[0] - r[0] * f[2];
      load[5] += r[0] * f[1] - r[1] * f[0];
    }
    const double pressing = load[2];
    load[0] += pressing * std::sin(tilt) * std::cos(tilt_heading);
    load[1] += pressing * std::sin(tilt) * std::sin(tilt_heading);
    // The fork's inertia: braking, and the arm's idle shake.
    const double jiggle =
        shake * std::sin(2.0 * kPi * shake_hz * t + shake_phase);
    for (int k = 0; k < 3; ++k) {
      load[k] += fork_kg * (jiggle * shake_dir[k] - (k == 2 ? accel : 0.0));
    }
    for (int sub = 0; sub < 2; ++sub) {
      const double h = 0.5 * kPhysicsDt;
      for (int k = 0; k < 6; ++k) {
        mount_rate[k] += h * (mode * mode * (load[k] - mount[k]) -
                              2.0 * damping * mode * mount_rate[k]);
        mount[k] += h * mount_rate[k];
      }
    }
    for (int k = 0; k < 6; ++k) {
      filtered[k] += alias_gain * (mount[k] - filtered[k]);
    }
    gauge.push_back(filtered);
  }

  // The ADC, the DSP's block averages and the USB packets.
  static constexpr std::array<double, 6> kCount = {
      250.0 / 65536, 250.0 / 65536, 1000.0 / 65536,
      6.0 / 65536,   6.0 / 65536,   6.0 / 65536};
  static constexpr std::array<int, 4> kAverages = {1, 2, 4, 8};
  const int averaged = kAverages[random::UniformInt(rng, 0, 3)];
  const double out_hz = adc_hz / averaged;
  const double adc_period =
      1.0 / (adc_hz * (1.0 + 1e-6 * random::Uniform(rng, -150.0, 150.0)));
  const int packet = std::max(1, static_cast<int>(std::ceil(out_hz * 1e-3)));
  const double latency = random::Uniform(rng, 0.5e-3, 3e-3);
  std::array<double, 6> offset{};
  std::array<double, 6> drift{};
  std::array<double, 6> noise{};
  random::Normal normal;
  for (int k = 0; k < 6; ++k) {
    const bool force = k < 3;
    offset[k] = normal(rng) * (force ? 1.5 : 0.05);
    drift[k] = random::Uniform(rng, -1.0, 1.0) * (force ? 0.08 : 0.002);
    noise[k] = force ? random::Uniform(rng, 0.008, 0.03) * (k == 2 ? 1.5 : 1.0)
                     : random::Uniform(rng, 1e-4, 4e-4);
  }
  const double last_s = (static_cast<double>(gauge.size()) - 1.0) * kPhysicsDt;
  std::vector<TimedWrench> trace;
  std::array<double, 6> sum{};
  int in_block = 0;
  int in_packet = 0;
  for (int64_t n = 0; n * adc_period <= last_s; ++n) {
    const double t = n * adc_period;
    const double at = t / kPhysicsDt;
    const size_t i = std::min(static_cast<size_t>(at), gauge.size() - 2);
    const double w = at - static_cast<double>(i);
    for (int k = 0; k < 6; ++k) {
      const double v = (1.0 - w) * gauge[i][k] + w * gauge[i + 1][k] +
                       offset[k] + drift[k] * t + noise[k] * normal(rng);
      sum[k] += kCount[k] * std::round(v / kCount[k]);
    }
    if (++in_block < averaged) continue;
    TimedWrench sample;
    sample.t_s = t;  // sensor time for now; host stamps below
    for (int k = 0; k < 6; ++k) {
      domain::Channel(sample.wrench, k) = sum[k] / averaged;
      sum[k] = 0.0;
    }
    in_block = 0;
    trace.push_back(sample);
    if (++in_packet < packet) continue;
    in_packet = 0;
    // The host stamps the packet on the next USB frame after it is ready,
    // and back-fills its samples at the nominal period.
    const double arrival = std::ceil((t + latency) / 1e-3) * 1e-3 +
                           random::Uniform(rng, 0.0, 0.3e-3);
    for (int j = 0; j < packet; ++j) {
      trace[trace.size() - 1 - j].t_s = arrival - j / out_hz;
    }
  }
  trace.resize(trace.size() - in_packet);  // an unsent packet is lost
  double previous = trace.front().t_s;
  for (size_t i = 1; i < trace.size(); ++i) {
    previous = std::max(trace[i].t_s, previous + 0.25 / out_hz);
    trace[i].t_s = previous;
  }
  return CutRecording(trace, touch_s + latency, lead_draw, after_s);
}

}  // namespace bitewise::sim
