// Independent stories of what the Forque feels when the fork enters a food,
// each written from its own physical account and sharing no code or shapes
// with the world's force-trace model (force_trace.h) or with each other.
// They exist so that HapticNet can be trained on some stories and judged on
// one it never saw (docs/haptic.md, "Held-out generators"); the simulated
// world itself streams only force_trace.h's model.
//
//  - Piecewise: Fz through piecewise-linear knots per category (ramps,
//    plateaus, drops), with its own sensor: one of six rates, white noise,
//    offset, lateral force and lever.
//  - Mechanics: penetration mechanics driven by the fork's depth: brittle
//    fracture for hard foods (Hertzian loading of the tines, then a sawtooth
//    of cracks, friction growing with depth), a turgid skin that stretches
//    and ruptures onto soft flesh for hard-skin foods, a cellular solid that
//    yields at a surface puncture and crushes for medium foods, and a
//    viscoelastic standard linear solid that flows at a cutting limit for
//    soft foods; with a recorded-style sensor: untared offset and thermal
//    drift, arm vibration, mains hum, the gauges' low-pass, quantisation to
//    the Nano25's counts and UDP records lost on the way.
//  - Compliant (compliant_story.cc): the fork driven through the arm's
//    compliance with a massive tip, so drops are as fast as the tip can
//    move and ring at the arm's frequency; layered continuum food (a flat
//    punch and cohesive cracks, a bursting membrane over viscous flesh,
//    collapsing cells, a viscoplastic paste); another sensor: tilted tines,
//    a second-order anti-alias filter, 250 Hz-4 kHz host-stamped samples,
//    coloured noise and drift.
//  - Puncture (puncture_story.cc): the fork as four texture-analyser punches
//    in the terms of food-texture science. Each tine indents the tissue
//    (Sneddon's punch over its taper) until the bioyield given by Bourne's
//    puncture equation (compression over the tine's area, shear over its
//    perimeter), then fails in its own way: brittle cracks that it wedges
//    and reloads (hard, with the piece sometimes splitting), bursting cells
//    and crushing (medium), a smooth passage into flow with no bioyield
//    (soft), or a turgid skin whose first break splits it round the berry
//    onto soft flesh (hard-skin); shaft friction grows with depth. The
//    tines land at different depths (a curved top, an off-centre item, a
//    rolled fork) and fail out of step; the item's body and a stiff arm
//    share the travel in series; the tissue relaxes (quasi-linear
//    viscoelasticity). A guarded, position-controlled descent at
//    25-60 mm/s, sometimes tilted to the tines. The sensor: forces at the
//    tine tips and along the shafts, 55-90 mm below it; the fork's mode at
//    1.2-3 kHz; the Net F/T's 7 kHz gauges with its selectable low-pass and
//    every n-th sample streamed (100 Hz-7 kHz), offset and slow drift.
//  - Poroelastic (poroelastic_story.cc): tissue as a fluid-saturated solid,
//    a six-layer Biot column under each tapered tine whose undrained,
//    turgid stiffness relaxes as juice flows out; cracks that run when the
//    released energy meets the toughness (Griffith) and arrest below it
//    (sawtooths in crisp tissue, a bioyield, smooth cutting and crushing in
//    pastes), shafts rubbing on crack faces, a skin tensioned by the berry's
//    pressure that bursts at its flaws' Griffith strength, the item squashing
//    on the plate. An impedance-controlled arm at 15-40 mm/s with a fork that
//    slips in the gripper; a wrist Mini40 16-24 cm above the tines over
//    EtherCAT at 500 Hz-2 kHz (low-pass, counts, stale frames).
//  - Lattice (lattice_story.cc): tissue as a discrete network of cell walls,
//    a column of walls under each tine joined by the cells between them and
//    tied to the surrounding tissue by rings of wall junctions, whose bonds
//    break stochastically with the rate of loading (Weibull strengths, Bell
//    kinetics): the wall under the tip bursts and the tine passes into the
//    next cell, rings shear and the column softens, so crisp tissue climbs
//    steeply through repeated small cracks, medium tissue's large cells
//    collapse and burst in coarse serrations and a soft column sags
//    smoothly by many cells; the tapered tine wedges and rubs behind it.
//    Berries carry a pre-tensioned skin that stiffens as it stretches and
//    bursts (splitting round the berry, or slackening the others) and a body
//    squashed on the plate. The arm is a 3-8 N/mm spring under a 100 Hz
//    admittance law that slows the fork as the force grows (v0 15-45 mm/s); the
//    sensor: the mount's mode at 250-900 Hz, an RC anti-alias, a 16-bit ADC at
//    1-7 kHz with noise, offset and thermal drift, block averages of 1-8
//    samples, USB packets stamped by the host on arrival (irregular stamps),
//    and a pre-triggered recorder that cuts the trace round the 1 N trigger.
//
// Thread-compatible; deterministic in the generator's state.
#ifndef BITEWISE_SERVICES_SIM_TRACE_STORIES_H_
#define BITEWISE_SERVICES_SIM_TRACE_STORIES_H_

#include <random>
#include <vector>

#include "services/sim/food_catalog.h"
#include "services/sim/force_trace.h"

namespace bitewise::sim {

// One trace of a new item of `category` from the piecewise-linear story:
// contact 0.15-0.35 s into the trace, 0.25 s after it.
std::vector<TimedWrench> PiecewiseStoryTrace(HapticCategory category,
                                             std::mt19937_64& rng);

// One trace of a new item of `category` from the mechanics story: contact
// 0.1-0.3 s into the trace, 0.25 s after it, at 250 Hz to 7 kHz.
std::vector<TimedWrench> MechanicsStoryTrace(HapticCategory category,
                                             std::mt19937_64& rng);

// One trace of a new item of `category` from the compliant-arm story:
// contact 0.1-0.3 s into the trace, 0.25 s after it, at 250 Hz to 4 kHz.
std::vector<TimedWrench> CompliantStoryTrace(HapticCategory category,
                                             std::mt19937_64& rng);

// One trace of a new item of `category` from the puncture story: contact
// 0.1-0.3 s into the trace, 0.3 s after it, at 7 kHz / n for n = 1, 2, 4,
// 7, 14, 28 or 70 (7 kHz down to 100 Hz).
std::vector<TimedWrench> PunctureStoryTrace(HapticCategory category,
                                            std::mt19937_64& rng);

// One trace of a new item of `category` from the poroelastic story: contact
// 0.1-0.3 s into the trace, 0.3-0.45 s after it, at 500 Hz, 1 kHz or 2 kHz
// (EtherCAT cycles with +-2% jitter).
std::vector<TimedWrench> PoroelasticStoryTrace(HapticCategory category,
                                               std::mt19937_64& rng);

// One trace of a new item of `category` from the lattice story: contact
// 0.1-0.2 s into the trace (the tared force passing 1 N by 0.29 s, or not
// at all), 0.3-0.45 s after it and at least 0.3 s after the force passes
// 1 N (an item too soft to pass it that soon is recorded for 0.19-0.45 s
// after contact, up to just before it would), at 125 Hz to 7 kHz (an ADC at
// 1-7 kHz averaged in blocks of 1, 2, 4 or 8) with host-stamped, irregular
// times.
std::vector<TimedWrench> LatticeStoryTrace(HapticCategory category,
                                           std::mt19937_64& rng);

}  // namespace bitewise::sim

#endif  // BITEWISE_SERVICES_SIM_TRACE_STORIES_H_
