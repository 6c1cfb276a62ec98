// The puncture story (trace_stories.h): the fork as four texture-analyser
// punches. Each tine is its own puncture test, in the terms of food-texture
// science (Bourne's puncture equation and the bioyield point), the four
// tines land on the item's surface at different depths and fail one by one,
// and the item's body and the arm take up part of the fork's travel in
// series. Written from its own physical account; it shares no code or
// shapes with the force-trace model or the other stories.
//
// Units inside: millimetres, newtons, seconds (so stiffnesses are N/mm and
// stresses N/mm^2 = MPa); the wrench leaves in N and N m.
//
//  - The arm: a position-controlled arm descends at 25-60 mm/s along its
//    approach direction and is already at speed when the trace starts. Its
//    end point is stiff (100-400 N/mm, counted in series with the food; at
//    20 N it gives 0.05-0.2 mm, so the arm's own dynamics are neglected).
//    The motion planner stops 6-14 mm past the first touch, decelerating at
//    0.5-1.5 m/s^2; a force guard checks the axial force at the controller's
//    125, 250 or 500 Hz and, 2-12 ms after it first sees 12-25 N, brakes at
//    2-5 m/s^2. While braking, the 20-40 g of fork below the sensor pull on
//    it (F = m a, up to 0.2 N against the food's push).
//  - The approach: axial (the vertical and angled skewers: 0-4 degrees
//    between the motion and the tines) or, one time in three, a tilted
//    vertical skewer with the tines 15-35 degrees off the motion, tilted
//    across or along the tine row; the food's reaction opposes the motion.
//  - The fork: four tines in a row 4.5-5.5 mm apart (centre to centre),
//    stamped from 1.0-1.5 mm sheet; each tine is 1.6-2.2 mm wide and tapers
//    over its last 3-6 mm to a blunt 0.5-0.9 mm tip. The tips are not
//    coplanar (+-0.15 mm) and the row is rolled +-3 degrees to the food.
//    The tine tips are 55-90 mm below the sensor's origin and the tine plane
//    sits +-4 mm off the handle's axis (the neck's bend).
//  - Where the tines land: the item sits +-3 mm off the fork's centre along
//    the row; its top is a cylinder or sphere of curvature 1/R (a flat or
//    gently curved cut piece; a whole berry for hard-skin foods), so an
//    outer tine touches only after the surface has dropped by
//    R - sqrt(R^2 - x^2) under it, or misses the item altogether beyond its
//    half-width (or, on a sphere, beyond 0.85 R, where it slides off the
//    flank). A tine on the slope is pushed outwards along the row by
//    0.2-0.8 of the slope's sine times its tip force.
//  - One tine in the tissue, at depth d below the local surface:
//    * indentation (Sneddon's flat punch, F = 2 E* a d, integrated over the
//      taper): F_I(d) = 2 E* integral_0^d a(s) ds, a = sqrt(A(s) / pi), with
//      A and P the tine's cross-section and perimeter at the depth reached;
//    * the bioyield (Bourne's puncture equation): the tissue under the tip
//      fails when F_I reaches F_B(d) = Kc A(d) + Ks P(d) (Kc the
//      compression coefficient, Ks the shear coefficient), times a local
//      strength scatter (+-10-12 % per event); E* is tied to Kc through the
//      tissue's yield strain (E* = Kc / strain), and each tine meets tissue
//      of its own firmness (x0.8-1.2, the scale of cortex and core);
//    * once in, the shaft drags on the tissue with an interfacial shear
//      stress tau_f over its perimeter and embedded length;
//    * a failure does not drop the force at once: the load the failed
//      ligament carried is shed linearly in time over the tear's duration
//      (a crack or tear crossing the ligament at a steady speed).
//  - The food (per category; ranges drawn per item):
//    * hard (raw carrot, celery, apple): Kc 0.7-2.5 N/mm^2, Ks = Kc x
//      0.35-0.8 mm (apple Magness-Taylor pressures of 0.5-0.9 MPa; carrot
//      a few times firmer), yield strain 0.10-0.22 (E* 3-25 MPa), tau_f
//      0.006-0.02 N/mm^2 (the tissue clamps the tine). Brittle: at the
//      bioyield a crack runs 0.2-1 mm ahead of the tip within 0.05-0.3 ms;
//      the tine then wedges the crack open at 0.3-0.6 of F_B until its tip
//      meets the crack front, reloads the intact tissue there with the
//      tip's indentation stiffness, and cracks again (per tine, out of step
//      with the others). If the deepest tine passes the piece's splitting
//      depth (5-50 mm, log-uniform), the cracks join and the piece splits:
//      over 1-4 ms the tips lose their load and the halves pinch the shafts
//      with 0.3-0.6 of the friction. Relaxation 8-20 %.
//    * medium (strawberry, cantaloupe, kiwi): Kc 0.08-0.3 N/mm^2, Ks = Kc
//      x 0.5-1.5 mm (firmness of 2-13 N on a 5 mm probe, 5-26 N on an 8 mm
//      one: a ripe strawberry to firm melon or kiwi), yield strain
//      0.10-0.25 (E* 0.3-3 MPa), tau_f 0.001-0.005 N/mm^2 (juice
//      lubricates). Juicy cellular tissue: at the bioyield the cells under
//      the tip burst and the tine's force falls to 0.5-0.85 of F_B over a
//      tear of 0.5-4 ms, then follows F_B as the taper widens, hardened by
//      0.02-0.1 per mm of travel as crushed cells compact (puncture curves
//      of juicy fruit are nearly flat after the bioyield: at most twice the
//      force after 10 mm). Relaxation 15-35 %.
//    * soft (banana, avocado, ripe peach): Kc 0.03-0.12 N/mm^2, Ks = Kc x
//      0.3-1.0 mm (firmness of 2-9 N on an 8 mm probe), yield strain 0.2-0.45
//      (E* 0.07-0.6 MPa), tau_f 0.0015-0.005 N/mm^2 (sticky pulp). No bioyield:
//      the cells part rather than break, so the tine's force passes smoothly
//      from indentation to flow, F = (F_I^-m + F_B^-m)^(-1/m) with m 1.5-4, and
//      never drops. Relaxation 30-55 %.
//    * hard_skin (grape, cherry tomato): a whole berry of radius 7-14 mm,
//      its skin a membrane pre-tensioned by turgor: under one tine F_S =
//      F_r (s x + (1 - s) x^3), x = d / D_r (the pre-tension gives the
//      linear part, a share s of 0.3-0.7; the skin's own stretching
//      Foppl's cubic); the skin breaks under a tine at F_r 0.4-3.5 N
//      (log-uniform; grape skins 0.4-1.5 N, tomato skins up to 3.5 N on
//      1-2 mm probes) after D_r 0.8-2.5 mm. The first break releases the
//      turgor: the split runs through the skin at 2-10 m/s and each other
//      loaded tine sheds its skin load over 0.2-1 ms as it arrives, and the
//      berry deflates (its body stiffness falls to 0.25-0.5 over 5-30 ms
//      as juice leaves). Below lies soft flesh (Kc 0.01-0.08 N/mm^2, Ks =
//      Kc x 0.3-1 mm, yield strain 0.15-0.35, tau_f 0.0005-0.003 N/mm^2,
//      flowing as the soft foods do). Relaxation 15-35 %.
//  - The item's body and the arm in series: the body compresses against the
//    plate as B(u) = K_b u^n: cut pieces with a flat base n = 1, K_b = E A
//    / H of the piece (hard 30-300 N/mm, medium 4-40 N/mm, soft 1.5-12
//    N/mm); a berry n = 1.5 (Hertzian flattening of a pressurised sphere,
//    K_b 0.8-4 N/mm^1.5). The fork's travel z is shared: z = d_i + offset_i
//    + u + F / k_arm, with F = B(u) = sum of the tines' forces, solved each
//    step (the food's masses are grams, so quasi-statics holds).
//  - Viscoelasticity: the tissue's force relaxes (Fung's quasi-linear
//    viscoelasticity on the whole load: F = (1 - r) F_e + r integral of
//    exp(-(t - s) / tau) dF_e(s), r the relaxation share above, tau 0.05-0.5
//    s log-uniform), so it lags while loading and sags once the arm holds.
//  - The sensor (an ATI Nano25 on a Net F/T box): force on each tine acts
//    at its tip and its shaft's friction at the middle of its embedded
//    length; torque = r x F about the sensor's origin. The fork on the
//    transducer rings as a lightly damped mode at 1.2-3 kHz (damping ratio
//    0.02-0.06; the Nano25 alone resonates near 3.6 kHz). The box samples
//    the gauges at 7 kHz with white noise of 0.015-0.05 N and 0.3-1.2 mN m
//    per sample, an untared offset of +-1.5 N and +-0.04 N m (the fork's
//    weight, mounting preload) drifting by up to 0.05 N/s and 1 mN m/s; it
//    applies its selectable low-pass filter (none, 838, 326, 152 or 73 Hz;
//    modelled as a two-pole Butterworth at 7 kHz) and streams every n-th
//    sample (n = 1, 2, 4, 7, 14, 28 or 70: 7 kHz down to 100 Hz, no further
//    anti-aliasing), stamped by the record's sequence number. Its counts
//    (10^-6 N) are far below the noise, so quantisation is left out.
// The mechanics run at 28 kHz, four steps per sample of the box: fine for
// the fastest crack (0.05 ms spans 1.4 steps) and, with the exact update of
// the sensor's mode, stable at any frequency.
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "services/domain/random.h"
#include "services/domain/wrench.h"
#include "services/sim/trace_stories.h"

namespace bitewise::sim {
namespace {

using random::LogUniform;
using random::Uniform;

constexpr int kTines = 4;
constexpr double kBoxHz = 7000.0;  // the Net F/T's gauge sample rate
constexpr int kSubsteps = 4;       // mechanics steps per gauge sample
constexpr double kStepS = 1.0 / (kBoxHz * kSubsteps);
constexpr double kAfterContactS = 0.3;
constexpr double kNever = std::numeric_limits<double>::infinity();

// The fork's geometry (mm).
struct Fork {
  double spacing_mm = 5.0;    // tine centre to tine centre
  double tip_width_mm = 0.7;  // blunt tip
  double width_mm = 1.9;      // above the taper
  double thickness_mm = 1.2;  // the sheet, constant
  double taper_mm = 4.0;      // length over which the width grows
  double lever_mm = 70.0;     // tine tips below the sensor's origin
  double neck_mm = 0.0;       // tine plane off the handle's axis

  double Width(double d) const {
    const double s = std::clamp(d, 0.0, taper_mm);
    return tip_width_mm + (width_mm - tip_width_mm) * s / taper_mm;
  }
  // Cross-section (mm^2) and perimeter (mm) at depth d behind the tip.
  double Area(double d) const { return Width(d) * thickness_mm; }
  double Perimeter(double d) const { return 2.0 * (Width(d) + thickness_mm); }
  double ShaftPerimeter() const { return Perimeter(taper_mm); }
  // integral_0^d a(s) ds (mm^2), a = sqrt(A(s) / pi) the tine's equivalent
  // punch radius: Sneddon's flat punch integrated over the taper.
  double RadiusIntegral(double d) const {
    if (d <= 0.0) return 0.0;
    const double c = std::sqrt(thickness_mm / M_PI);
    const double g = (width_mm - tip_width_mm) / taper_mm;
    const double s = std::min(d, taper_mm);
    const double w = tip_width_mm + g * s;
    double r = c * 2.0 / (3.0 * g) *
               (w * std::sqrt(w) - tip_width_mm * std::sqrt(tip_width_mm));
    if (d > taper_mm) r += c * std::sqrt(width_mm) * (d - taper_mm);
    return r;
  }
};

// A tissue's puncture properties.
struct Tissue {
  double kc = 0.0;        // Bourne's compression coefficient (N/mm^2)
  double ks = 0.0;        // Bourne's shear coefficient (N/mm)
  double modulus = 0.0;   // indentation modulus E* (N/mm^2)
  double friction = 0.0;  // interfacial shear stress on the shaft (N/mm^2)
};

Tissue DrawTissue(std::mt19937_64& rng, double kc_lo, double kc_hi,
                  double length_lo, double length_hi, double strain_lo,
                  double strain_hi, double friction_lo, double friction_hi) {
  Tissue t;
  t.kc = LogUniform(rng, kc_lo, kc_hi);
  t.ks = t.kc * Uniform(rng, length_lo, length_hi);
  t.modulus = t.kc / Uniform(rng, strain_lo, strain_hi);
  t.friction = LogUniform(rng, friction_lo, friction_hi);
  return t;
}

enum class Phase {
  kIntact,       // indenting (or, for a berry, stretching the skin)
  kCracked,      // hard: wedging a crack, then reloading at its front
  kPenetrating,  // medium: past the bioyield, crushing cells
  kFlowing,      // soft: the pulp flows round the tip
  kFlesh,        // hard-skin: the skin is gone, the tine is in the flesh
  kSplit,        // hard: the piece has split
};

struct Tine {
  double x_mm = 0.0;       // along the row, from the fork's centre
  bool engaged = false;    // lands on the item
  double offset_mm = 0.0;  // fork travel from the first touch to its touch
  double slope = 0.0;      // sine of the surface's slope, + towards +x
  double firmness = 1.0;   // the local tissue's firmness factor
  Phase phase = Phase::kIntact;
  bool entered = false;   // the shaft is in the tissue (friction)
  double entry_mm = 0.0;  // depth at which it entered
  double strength = 1.0;  // scatter of the next failure's threshold
  double front_mm = 0.0;  // hard: the crack front's depth
  double front_n = 0.0;   // hard: the wedge force at the front
  double shed_n = 0.0;    // load being shed since the last failure
  double shed_at_s = 0.0, shed_s = 1e-3;
  double skin_release_s = kNever;  // hard-skin: when the skin's split arrives
  // The solved state of this step.
  double depth_mm = 0.0, tip_n = 0.0, friction_n = 0.0;
};

// One food item under the fork: its tissues, its body, the four tines'
// states, and the quasi-static balance between them.
class Item {
 public:
  Item(HapticCategory category, const Fork& fork, std::mt19937_64& rng)
      : category_(category), fork_(fork) {
    double half_width_mm = 10.0, curvature = 0.0, lateral = 0.0;
    switch (category) {
      case HapticCategory::kHard:
        tissue_ = DrawTissue(rng, 0.7, 2.5, 0.35, 0.8, 0.10, 0.22, 0.006, 0.02);
        wedge_ = Uniform(rng, 0.3, 0.6);
        split_mm_ = LogUniform(rng, 5.0, 50.0);
        split_s_ = Uniform(rng, 1e-3, 4e-3);
        pinch_ = Uniform(rng, 0.3, 0.6);
        body_k_ = LogUniform(rng, 30.0, 300.0);
        relax_share_ = Uniform(rng, 0.08, 0.2);
        half_width_mm = Uniform(rng, 6.0, 15.0);
        curvature = Uniform(rng, 0.0, 1.0 / 12.0);
        break;
      case HapticCategory::kMedium:
        tissue_ =
            DrawTissue(rng, 0.08, 0.3, 0.5, 1.5, 0.10, 0.25, 0.001, 0.005);
        residual_ = Uniform(rng, 0.5, 0.85);
        tear_s_ = Uniform(rng, 0.5e-3, 4e-3);
        hardening_per_mm_ = Uniform(rng, 0.02, 0.1);
        body_k_ = LogUniform(rng, 4.0, 40.0);
        relax_share_ = Uniform(rng, 0.15, 0.35);
        half_width_mm = Uniform(rng, 7.0, 15.0);
        curvature = Uniform(rng, 0.0, 1.0 / 10.0);
        break;
      case HapticCategory::kSoft:
        tissue_ =
            DrawTissue(rng, 0.03, 0.12, 0.3, 1.0, 0.2, 0.45, 0.0015, 0.005);
        sharpness_ = Uniform(rng, 1.5, 4.0);
        body_k_ = LogUniform(rng, 1.5, 12.0);
        relax_share_ = Uniform(rng, 0.3, 0.55);
        half_width_mm = Uniform(rng, 8.0, 15.0);
        curvature = Uniform(rng, 0.0, 1.0 / 15.0);
        break;
      case HapticCategory::kHardSkin: {
        const double radius_mm = Uniform(rng, 7.0, 14.0);
        rupture_n_ = LogUniform(rng, 0.4, 3.5);
        rupture_mm_ = Uniform(rng, 0.8, 2.5);
        pretension_ = Uniform(rng, 0.3, 0.7);
        split_speed_mm_per_s_ = Uniform(rng, 2000.0, 10000.0);
        skin_tear_s_ = Uniform(rng, 0.2e-3, 1e-3);
        deflated_ = Uniform(rng, 0.25, 0.5);
        deflate_s_ = Uniform(rng, 5e-3, 30e-3);
        tissue_ =
            DrawTissue(rng, 0.01, 0.08, 0.3, 1.0, 0.15, 0.35, 0.0005, 0.003);
        sharpness_ = 3.0;
        body_k_ = LogUniform(rng, 0.8, 4.0);
        body_exponent_ = 1.5;
        relax_share_ = Uniform(rng, 0.15, 0.35);
        half_width_mm = radius_mm;
        curvature = 1.0 / radius_mm;
        break;
      }
    }
    relax_s_ = LogUniform(rng, 0.05, 0.5);
    lateral = Uniform(rng, 0.2, 0.8);

    // Where the tines land.
    const double centre_mm = Uniform(rng, -3.0, 3.0);
    const double roll = std::tan(Uniform(rng, -3.0, 3.0) * M_PI / 180.0);
    double first_mm = kNever;
    for (int i = 0; i < kTines; ++i) {
      Tine& tine = tines_[i];
      tine.x_mm = (i - 1.5) * fork_.spacing_mm;
      const double x = tine.x_mm - centre_mm;  // from the item's centre
      double drop_mm = 0.0;
      tine.engaged = std::abs(x) < half_width_mm;
      if (curvature > 0.0) {
        const double r = 1.0 / curvature;
        tine.engaged = tine.engaged && std::abs(x) < 0.85 * r;
        if (tine.engaged) drop_mm = r - std::sqrt(r * r - x * x);
      }
      tine.slope = lateral * x * curvature;
      tine.offset_mm = drop_mm + tine.x_mm * roll + Uniform(rng, -0.15, 0.15);
      tine.firmness = Uniform(rng, 0.8, 1.2);
      tine.strength = Uniform(rng, 0.9, 1.1);
      if (tine.engaged) first_mm = std::min(first_mm, tine.offset_mm);
    }
    for (Tine& tine : tines_) tine.offset_mm -= first_mm;
  }

  const std::array<Tine, kTines>& tines() const { return tines_; }
  double relax_share() const { return relax_share_; }
  double relax_s() const { return relax_s_; }

  // The elastic axial force (N) with the fork `z_mm` past its first touch
  // at time `t_s`, and the arm's stiffness `arm_n_per_mm`: the force F that
  // the body, the arm and the tines agree on. Stores each tine's state.
  double Solve(double z_mm, double t_s, double arm_n_per_mm) {
    auto excess = [&](double f) {
      return Total(z_mm, BodyCompression(f, t_s) + f / arm_n_per_mm, t_s,
                   false) -
             f;
    };
    double lo = 0.0, hi = Total(z_mm, 0.0, t_s, false);
    if (hi <= 0.0) return Total(z_mm, 0.0, t_s, true);
    // Regula falsi, Illinois variant: the tines' sum falls as F grows.
    double g_lo = hi, g_hi = excess(hi);
    double best = g_hi >= 0.0 ? hi : 0.0;
    int side = 0;
    for (int iteration = 0; iteration < 80 && g_hi < 0.0; ++iteration) {
      const double f = (lo * g_hi - hi * g_lo) / (g_hi - g_lo);
      const double g = excess(f);
      best = f;
      if (std::abs(g) < 1e-9 || hi - lo < 1e-12) break;
      if (g > 0.0) {
        lo = f;
        g_lo = g;
        if (side > 0) g_hi *= 0.5;
        side = 1;
      } else {
        hi = f;
        g_hi = g;
        if (side < 0) g_lo *= 0.5;
        side = -1;
      }
    }
    return Total(z_mm, BodyCompression(best, t_s) + best / arm_n_per_mm, t_s,
                 true);
  }

  // Failures reached in the state Solve() stored, at time `t_s`.
  void Fail(double t_s, std::mt19937_64& rng) {
    switch (category_) {
      case HapticCategory::kHard:
        FailHard(t_s, rng);
        break;
      case HapticCategory::kMedium:
        for (Tine& tine : tines_) {
          const double d = tine.depth_mm;
          if (tine.phase != Phase::kIntact || d <= 0.0) continue;
          if (Indent(tissue_, tine, d) <
              tine.strength * Bourne(tissue_, tine, d))
            continue;
          const double before = Tip(tine, d) + Shed(tine, t_s);
          tine.phase = Phase::kPenetrating;
          Enter(tine, d);
          StartShedding(tine, before - Tip(tine, d), t_s, tear_s_);
        }
        break;
      case HapticCategory::kSoft:
        for (Tine& tine : tines_) {
          const double d = tine.depth_mm;
          if (tine.phase != Phase::kIntact || d <= 0.0) continue;
          if (Indent(tissue_, tine, d) < Bourne(tissue_, tine, d)) continue;
          tine.phase = Phase::kFlowing;
          Enter(tine, d);
        }
        break;
      case HapticCategory::kHardSkin:
        FailSkin(t_s);
        break;
    }
  }

 private:
  // Sneddon's indentation force and Bourne's puncture force of one tine.
  double Indent(const Tissue& tissue, const Tine& tine, double d) const {
    return 2.0 * tine.firmness * tissue.modulus * fork_.RadiusIntegral(d);
  }
  double Bourne(const Tissue& tissue, const Tine& tine, double d) const {
    return tine.firmness *
           (tissue.kc * fork_.Area(d) + tissue.ks * fork_.Perimeter(d));
  }
  // Indentation passing smoothly into flow (no bioyield).
  double Flow(const Tissue& tissue, const Tine& tine, double d) const {
    const double a = Indent(tissue, tine, d), b = Bourne(tissue, tine, d);
    if (a <= 0.0 || b <= 0.0) return 0.0;
    return a * b /
           std::pow(std::pow(a, sharpness_) + std::pow(b, sharpness_),
                    1.0 / sharpness_);
  }

  // The tip's force at depth d in the tine's phase (without shedding);
  // never falls as d grows within a phase.
  double Tip(const Tine& tine, double d) const {
    if (d <= 0.0) return 0.0;
    switch (tine.phase) {
      case Phase::kIntact:
        if (category_ == HapticCategory::kSoft) return Flow(tissue_, tine, d);
        if (category_ == HapticCategory::kHardSkin) {
          const double x = d / rupture_mm_;
          return tine.firmness * rupture_n_ *
                 (pretension_ * x + (1.0 - pretension_) * x * x * x);
        }
        return Indent(tissue_, tine, d);
      case Phase::kCracked:
        if (d < tine.front_mm) return wedge_ * Bourne(tissue_, tine, d);
        return tine.front_n + 2.0 * tine.firmness * tissue_.modulus *
                                  (fork_.RadiusIntegral(d) -
                                   fork_.RadiusIntegral(tine.front_mm));
      case Phase::kPenetrating:
        return residual_ * Bourne(tissue_, tine, d) *
               (1.0 + hardening_per_mm_ * std::max(0.0, d - tine.entry_mm));
      case Phase::kFlowing:
      case Phase::kFlesh:
        return Flow(tissue_, tine, d);
      case Phase::kSplit:
        return 0.0;
    }
    return 0.0;
  }

  // The shaft's friction (N) at depth d.
  double Friction(const Tine& tine, double d) const {
    if (!tine.entered || d <= tine.entry_mm) return 0.0;
    const double f =
        tissue_.friction * fork_.ShaftPerimeter() * (d - tine.entry_mm);
    return tine.phase == Phase::kSplit ? pinch_ * f : f;
  }

  // What is left of the load a failure is shedding, linear in time.
  double Shed(const Tine& tine, double t_s) const {
    if (tine.shed_n <= 0.0) return 0.0;
    return tine.shed_n *
           std::max(0.0, 1.0 - (t_s - tine.shed_at_s) / tine.shed_s);
  }

  void StartShedding(Tine& tine, double load_n, double t_s, double over_s) {
    tine.shed_n = std::max(0.0, load_n);
    tine.shed_at_s = t_s;
    tine.shed_s = over_s;
  }

  void Enter(Tine& tine, double d) {
    if (tine.entered) return;
    tine.entered = true;
    tine.entry_mm = d;
  }

  // The body's compression (mm) under F at time t: B(u) = K_b u^n, a berry
  // deflating after its skin has split.
  double BodyCompression(double f, double t_s) const {
    if (f <= 0.0) return 0.0;
    double k = body_k_;
    if (skin_split_s_ < kNever) {
      const double w = std::min(1.0, (t_s - skin_split_s_) / deflate_s_);
      k *= 1.0 - (1.0 - deflated_) * w;
    }
    return body_exponent_ == 1.0 ? f / k
                                 : std::pow(f / k, 1.0 / body_exponent_);
  }

  // The tines' summed force with the fork at z and the body and arm taking
  // up `taken_mm`; with `store`, each tine's depth and forces are kept.
  double Total(double z_mm, double taken_mm, double t_s, bool store) {
    double total = 0.0;
    for (Tine& tine : tines_) {
      if (!tine.engaged) continue;
      const double d = z_mm - tine.offset_mm - taken_mm;
      double tip = 0.0, friction = 0.0;
      if (d > 0.0) {
        tip = Tip(tine, d) + Shed(tine, t_s);
        friction = Friction(tine, d);
      }
      total += tip + friction;
      if (store) {
        tine.depth_mm = d;
        tine.tip_n = tip;
        tine.friction_n = friction;
      }
    }
    return total;
  }

  void FailHard(double t_s, std::mt19937_64& rng) {
    if (split_) return;
    double deepest_mm = 0.0;
    for (Tine& tine : tines_) {
      const double d = tine.depth_mm;
      if (!tine.engaged || d <= 0.0) continue;
      deepest_mm = std::max(deepest_mm, d);
      const bool at_front =
          tine.phase == Phase::kIntact ||
          (tine.phase == Phase::kCracked && d >= tine.front_mm);
      if (!at_front ||
          Tip(tine, d) < tine.strength * Bourne(tissue_, tine, d)) {
        continue;
      }
      // A crack runs ahead of the tip; the tine now only wedges it open.
      const double before = Tip(tine, d) + Shed(tine, t_s);
      tine.phase = Phase::kCracked;
      Enter(tine, d);
      tine.front_mm = d + LogUniform(rng, 0.2, 1.0);
      tine.front_n = wedge_ * Bourne(tissue_, tine, tine.front_mm);
      tine.strength = Uniform(rng, 0.88, 1.12);
      StartShedding(tine, before - Tip(tine, d), t_s,
                    Uniform(rng, 0.05e-3, 0.3e-3));
    }
    if (deepest_mm < split_mm_) return;
    // The cracks join and the piece falls apart round the tines.
    split_ = true;
    for (Tine& tine : tines_) {
      const double d = tine.depth_mm;
      if (!tine.engaged) continue;
      const double before =
          d > 0.0 ? Tip(tine, d) + Shed(tine, t_s) + Friction(tine, d) : 0.0;
      tine.phase = Phase::kSplit;
      const double after = d > 0.0 ? Friction(tine, d) : 0.0;
      StartShedding(tine, before - after, t_s, split_s_);
    }
  }

  void FailSkin(double t_s) {
    for (int i = 0; i < kTines; ++i) {
      Tine& tine = tines_[i];
      if (!tine.engaged || tine.phase != Phase::kIntact) continue;
      const double d = tine.depth_mm;
      const bool broken = d > 0.0 && d >= tine.strength * rupture_mm_;
      if (!broken && t_s < tine.skin_release_s) continue;
      // The skin under this tine gives way; the tine sinks into the flesh.
      const double before = d > 0.0 ? Tip(tine, d) + Shed(tine, t_s) : 0.0;
      tine.phase = Phase::kFlesh;
      Enter(tine, 0.0);
      const double after = d > 0.0 ? Tip(tine, d) + Friction(tine, d) : 0.0;
      StartShedding(tine, before - after, t_s, skin_tear_s_);
      if (skin_split_s_ < kNever) continue;
      // The first break: the turgor goes, the split runs round the berry.
      skin_split_s_ = t_s;
      for (int j = 0; j < kTines; ++j) {
        Tine& other = tines_[j];
        if (j == i || !other.engaged || other.phase != Phase::kIntact) continue;
        if (other.depth_mm > 0.0) {
          other.skin_release_s =
              t_s + std::abs(other.x_mm - tine.x_mm) / split_speed_mm_per_s_;
        } else {
          other.phase = Phase::kFlesh;  // slack skin: nothing to break
          Enter(other, 0.0);
        }
      }
    }
  }

  HapticCategory category_;
  Fork fork_;
  Tissue tissue_;  // the flesh, for hard-skin foods
  std::array<Tine, kTines> tines_;
  // Hard.
  double wedge_ = 0.5, split_mm_ = kNever, split_s_ = 1e-3, pinch_ = 0.5;
  bool split_ = false;
  // Medium.
  double residual_ = 1.0, tear_s_ = 1e-3, hardening_per_mm_ = 0.0;
  // Soft and hard-skin flesh.
  double sharpness_ = 2.0;
  // Hard-skin.
  double rupture_n_ = 1.0, rupture_mm_ = 1.0, pretension_ = 0.5;
  double split_speed_mm_per_s_ = 5000.0, skin_tear_s_ = 0.5e-3;
  double deflated_ = 1.0, deflate_s_ = 0.01;
  double skin_split_s_ = kNever;
  // Body and relaxation.
  double body_k_ = 10.0, body_exponent_ = 1.0;
  double relax_share_ = 0.0, relax_s_ = 0.1;
};

// A lightly damped mode between the fork's load and the gauges, updated
// exactly over one step with the load held: y'' = w^2 (x - y) - 2 z w y'.
class Mode {
 public:
  Mode(double hz, double damping, double step_s) {
    const double w = 2.0 * M_PI * hz;
    decay_ = damping * w;
    ringing_ = w * std::sqrt(1.0 - damping * damping);
    w2_ = w * w;
    c_ = std::exp(-decay_ * step_s) * std::cos(ringing_ * step_s);
    s_ = std::exp(-decay_ * step_s) * std::sin(ringing_ * step_s);
  }
  double Step(double x) {
    const double e = y_ - x;
    const double e_next = c_ * e + s_ * (rate_ + decay_ * e) / ringing_;
    rate_ = c_ * rate_ - s_ * (w2_ * e + decay_ * rate_) / ringing_;
    y_ = x + e_next;
    return y_;
  }

 private:
  double decay_, ringing_, w2_, c_, s_;
  double y_ = 0.0, rate_ = 0.0;
};

// The Net F/T's low-pass at the gauge rate: a two-pole Butterworth by the
// bilinear transform; off when `cutoff_hz` is 0. Starts settled.
class LowPass {
 public:
  LowPass(double cutoff_hz, double rate_hz) : on_(cutoff_hz > 0.0) {
    if (!on_) return;
    const double k = std::tan(M_PI * cutoff_hz / rate_hz);
    const double norm = 1.0 / (1.0 + std::sqrt(2.0) * k + k * k);
    b0_ = k * k * norm;
    a1_ = 2.0 * (k * k - 1.0) * norm;
    a2_ = (1.0 - std::sqrt(2.0) * k + k * k) * norm;
  }
  double Step(double x) {
    if (!on_) return x;
    if (!started_) {
      x1_ = x2_ = y1_ = y2_ = x;
      started_ = true;
    }
    const double y = b0_ * (x + 2.0 * x1_ + x2_) - a1_ * y1_ - a2_ * y2_;
    x2_ = x1_;
    x1_ = x;
    y2_ = y1_;
    y1_ = y;
    return y;
  }

 private:
  bool on_;
  bool started_ = false;
  double b0_ = 1.0, a1_ = 0.0, a2_ = 0.0;
  double x1_ = 0.0, x2_ = 0.0, y1_ = 0.0, y2_ = 0.0;
};

using Vec = std::array<double, 3>;

Vec Cross(const Vec& a, const Vec& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
          a[0] * b[1] - a[1] * b[0]};
}

}  // namespace

std::vector<TimedWrench> PunctureStoryTrace(HapticCategory category,
                                            std::mt19937_64& rng) {
  // The fork.
  Fork fork;
  fork.spacing_mm = Uniform(rng, 4.5, 5.5);
  fork.tip_width_mm = Uniform(rng, 0.5, 0.9);
  fork.width_mm = Uniform(rng, 1.6, 2.2);
  fork.thickness_mm = Uniform(rng, 1.0, 1.5);
  fork.taper_mm = Uniform(rng, 3.0, 6.0);
  fork.lever_mm = Uniform(rng, 55.0, 90.0);
  fork.neck_mm = Uniform(rng, -4.0, 4.0);
  const double fork_mass_kg = Uniform(rng, 0.02, 0.04);
  // The sensor's frame: z up the handle, the tine row along x (+-5 degrees
  // of mounting).
  const double yaw = Uniform(rng, -5.0, 5.0) * M_PI / 180.0;
  const Vec row = {std::cos(yaw), std::sin(yaw), 0.0};
  const Vec across = {-std::sin(yaw), std::cos(yaw), 0.0};

  Item item(category, fork, rng);

  // The arm and its controller (mm, s).
  const double speed = Uniform(rng, 25.0, 60.0);
  const double arm_n_per_mm = LogUniform(rng, 100.0, 400.0);
  const double target_mm = Uniform(rng, 6.0, 14.0);
  const double plan_decel = Uniform(rng, 500.0, 1500.0);
  const double guard_n = Uniform(rng, 12.0, 25.0);
  constexpr std::array<double, 3> kControlHz = {125.0, 250.0, 500.0};
  const double control_s = 1.0 / kControlHz[random::UniformInt(rng, 0, 2)];
  const double latency_s = Uniform(rng, 2e-3, 12e-3);
  const double guard_decel = Uniform(rng, 2000.0, 5000.0);
  // The approach: the reaction's direction in the sensor's frame.
  const bool tilted = random::Canonical(rng) < 1.0 / 3.0;
  const double tilt =
      (tilted ? Uniform(rng, 15.0, 35.0) : Uniform(rng, 0.0, 4.0)) * M_PI /
      180.0;
  const Vec& tilt_axis = random::Canonical(rng) < 0.5 ? row : across;
  const double tilt_sign = random::Canonical(rng) < 0.5 ? -1.0 : 1.0;
  Vec reaction;
  for (int c = 0; c < 3; ++c) {
    reaction[c] = tilt_sign * std::sin(tilt) * tilt_axis[c];
  }
  reaction[2] = std::cos(tilt);

  // The Nano25 and the Net F/T box.
  Mode mode(Uniform(rng, 1200.0, 3000.0), Uniform(rng, 0.02, 0.06), kStepS);
  constexpr std::array<double, 5> kCutoffHz = {0.0, 838.0, 326.0, 152.0, 73.0};
  const double cutoff_hz = kCutoffHz[random::UniformInt(rng, 0, 4)];
  constexpr std::array<int, 7> kDecimation = {1, 2, 4, 7, 14, 28, 70};
  const int decimation = kDecimation[random::UniformInt(rng, 0, 6)];
  const double force_sd = Uniform(rng, 0.015, 0.05);
  const double torque_sd = Uniform(rng, 0.3e-3, 1.2e-3);
  std::array<double, 6> offset, drift;
  for (int c = 0; c < 6; ++c) {
    offset[c] = c < 3 ? Uniform(rng, -1.5, 1.5) : Uniform(rng, -0.04, 0.04);
    drift[c] = c < 3 ? Uniform(rng, -0.05, 0.05) : Uniform(rng, -1e-3, 1e-3);
  }
  const double contact_s = Uniform(rng, 0.1, 0.3);

  std::array<Mode, 6> modes = {mode, mode, mode, mode, mode, mode};
  std::array<LowPass, 6> filters = {
      LowPass(cutoff_hz, kBoxHz), LowPass(cutoff_hz, kBoxHz),
      LowPass(cutoff_hz, kBoxHz), LowPass(cutoff_hz, kBoxHz),
      LowPass(cutoff_hz, kBoxHz), LowPass(cutoff_hz, kBoxHz)};
  random::Normal normal;

  const int samples =
      static_cast<int>((contact_s + kAfterContactS) * kBoxHz) + 1;
  std::vector<TimedWrench> trace;
  trace.reserve(samples / decimation + 1);

  // The motion: the first tine touches at contact_s.
  double z_mm = -speed * contact_s, velocity = speed, decel = 0.0;
  double next_check_s = 0.0, brake_at_s = kNever;
  // Quasi-linear viscoelasticity: the elastic force and its relaxing part.
  double elastic_n = 0.0, relaxing_n = 0.0;
  const double keep = std::exp(-kStepS / item.relax_s());
  const double lever = fork.lever_mm;

  for (int step = 0; step < samples * kSubsteps; ++step) {
    const double t = step * kStepS;
    // The controller: the planned stop, the guard's brake.
    if (decel < plan_decel &&
        z_mm >= target_mm - speed * speed / (2.0 * plan_decel)) {
      decel = std::max(decel, plan_decel);
    }
    if (t >= brake_at_s) decel = std::max(decel, guard_decel);
    const double braking = velocity > 0.0 ? decel : 0.0;  // mm/s^2
    velocity = std::max(0.0, velocity - braking * kStepS);
    z_mm += velocity * kStepS;

    // The food, its failures, its relaxation.
    const double now_n = z_mm > 0.0 ? item.Solve(z_mm, t, arm_n_per_mm) : 0.0;
    if (z_mm > 0.0) item.Fail(t, rng);
    relaxing_n = keep * relaxing_n + (now_n - elastic_n);
    elastic_n = now_n;
    const double felt_n = std::max(0.0, (1.0 - item.relax_share()) * elastic_n +
                                            item.relax_share() * relaxing_n);
    const double scale = elastic_n > 0.0 ? felt_n / elastic_n : 0.0;
    if (t >= next_check_s) {
      next_check_s += control_s;
      if (brake_at_s == kNever && felt_n * reaction[2] >= guard_n) {
        brake_at_s = t + latency_s;
      }
    }

    // The wrench on the fork at the sensor (N, N mm), tine by tine.
    Vec force = {0.0, 0.0, 0.0}, torque = {0.0, 0.0, 0.0};
    for (const Tine& tine : item.tines()) {
      if (!tine.engaged || tine.depth_mm <= 0.0) continue;
      Vec at;
      for (int c = 0; c < 3; ++c) {
        at[c] = tine.x_mm * row[c] + fork.neck_mm * across[c];
      }
      at[2] = -lever;
      Vec tip, drag;
      for (int c = 0; c < 3; ++c) {
        tip[c] = scale * tine.tip_n * (reaction[c] + tine.slope * row[c]);
        drag[c] = scale * tine.friction_n * reaction[c];
      }
      const Vec mid = {at[0], at[1], -lever + 0.5 * tine.depth_mm};
      const Vec t1 = Cross(at, tip), t2 = Cross(mid, drag);
      for (int c = 0; c < 3; ++c) {
        force[c] += tip[c] + drag[c];
        torque[c] += t1[c] + t2[c];
      }
    }
    // Braking: the fork below the sensor is decelerated through it.
    const double inertial_n = -fork_mass_kg * braking * 1e-3;
    const Vec centre = {0.0, 0.5 * fork.neck_mm, -0.5 * lever};
    Vec pull;
    for (int c = 0; c < 3; ++c) pull[c] = inertial_n * reaction[c];
    const Vec t3 = Cross(centre, pull);
    std::array<double, 6> load;
    for (int c = 0; c < 3; ++c) {
      load[c] = force[c] + pull[c];
      load[3 + c] = (torque[c] + t3[c]) * 1e-3;  // N mm -> N m
    }
    for (int c = 0; c < 6; ++c) load[c] = modes[c].Step(load[c]);

    // The box: a gauge sample every kSubsteps steps, every decimation-th
    // one streamed.
    if (step % kSubsteps != 0) continue;
    const int k = step / kSubsteps;
    TimedWrench sample;
    sample.t_s = k / kBoxHz;
    for (int c = 0; c < 6; ++c) {
      const double sd = c < 3 ? force_sd : torque_sd;
      const double raw =
          load[c] + offset[c] + drift[c] * sample.t_s + sd * normal(rng);
      domain::Channel(sample.wrench, c) = filters[c].Step(raw);
    }
    if (k % decimation == 0) trace.push_back(sample);
  }
  return trace;
}

}  // namespace bitewise::sim
