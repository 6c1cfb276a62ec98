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

}  // namespace bitewise::sim

#endif  // BITEWISE_SERVICES_SIM_TRACE_STORIES_H_
