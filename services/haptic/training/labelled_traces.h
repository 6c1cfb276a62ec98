// Labelled force/torque traces for HapticNet's trainer and its evaluation:
// drawn from the simulated world's force-trace model under chosen sensor
// conditions or from the independent trace stories, or read from and written
// to the trace CSV format of services/domain/trace_csv.h (docs/haptic.md),
// including the recordings of real bites that the meal writes.
#ifndef BITEWISE_SERVICES_HAPTIC_TRAINING_LABELLED_TRACES_H_
#define BITEWISE_SERVICES_HAPTIC_TRAINING_LABELLED_TRACES_H_

#include <array>
#include <cstdint>
#include <map>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "services/haptic/core/haptic_classifier.h"
#include "services/haptic/core/wrench_trace.h"
#include "services/haptic/training/haptic_trainer.h"
#include "services/sim/food_catalog.h"
#include "services/sim/force_trace.h"

namespace bitewise::haptic {

struct LabelledTrace {
  HapticClass label = HapticClass::kHard;
  std::vector<TimedWrench> samples;
  // Where it came from, for the familiarity fit per source: a TraceStory's
  // index, kRecordedSource for a recording, -1 when not said.
  int source = -1;
};

// LabelledTrace::source of a recorded trace (not a story).
inline constexpr int kRecordedSource = 1000;

// Sensor and timing conditions of simulated traces. Ranges are sampled
// per trace; set min = max for a fixed condition.
struct SimulationConditions {
  // Sample rate, log-uniform in [min, max] (Hz).
  double min_rate_hz = 1000.0;
  double max_rate_hz = 1000.0;
  // Multiplier of the Nano25's white noise (sim::SensorNoise defaults),
  // uniform in [min, max].
  double min_noise_scale = 1.0;
  double max_noise_scale = 1.0;
  // Untared sensor offset: every force channel gets fixed_bias_n plus a
  // uniform draw in +-random_bias_n (torques 0.02 m times as much).
  double fixed_bias_n = 0.0;
  double random_bias_n = 0.5;
  // Timestamp jitter as a fraction of the sample period.
  double jitter_fraction = 0.0;
  // First contact, uniform in [min, max] seconds after the trace starts;
  // the trace goes on for after_contact_s more.
  double min_contact_s = 0.3;
  double max_contact_s = 0.3;
  double after_contact_s = 0.3;
  // The robot's force limit halting the fork (sim::ForceLimitStop), in N;
  // 0: none. Not an augmentation: the traces of an action whose limit an
  // item reaches (docs/haptic.md, "A trace the robot cut short").
  double force_limit_n = 0.0;

  // Augmentation beyond the force-trace model (training only; all off by
  // default): the ranges of a sim::TraceVariation (force_trace.h), drawn per
  // trace so every item is a new variant. Amplitude and time scale are
  // log-uniform in [min, max]_amplitude_scale[class] and
  // [min, max]_time_scale[class], the after-peak stretch log-uniform in
  // [min, max]_drop_time_scale, the lateral scale uniform in
  // [min, max]_lateral_scale, the twist uniform in +-max_twist_m, the touch
  // uniform in [0, max_touch_n] over [0, max_touch_s].
  // The ranges are per class (index HapticClass) so that the class
  // signatures survive every draw: hard stays the steepest and highest,
  // soft slow and low, hard-skin peaks then drops by more than half, medium
  // is moderate with a small puncture drop.
  std::array<double, kHapticClasses> min_amplitude_scale{1.0, 1.0, 1.0, 1.0};
  std::array<double, kHapticClasses> max_amplitude_scale{1.0, 1.0, 1.0, 1.0};
  std::array<double, kHapticClasses> min_time_scale{1.0, 1.0, 1.0, 1.0};
  std::array<double, kHapticClasses> max_time_scale{1.0, 1.0, 1.0, 1.0};
  double min_drop_time_scale = 1.0;
  double max_drop_time_scale = 1.0;
  double min_lateral_scale = 1.0;
  double max_lateral_scale = 1.0;
  double max_twist_m = 0.0;
  double max_touch_n = 0.0;
  double max_touch_s = 0.0;

  // True if any augmentation above is on. Without augmentation the traces
  // are exactly sim::SimulateTrace's, as the simulated Net F/T box streams.
  bool Augmented() const;
};

// The conditions the default model is trained on: 100 Hz to 7 kHz, half to
// three times the nominal noise, up to +-2.5 N of offset, 10 % timestamp
// jitter, contact anywhere from 0.1 s to 0.3 s, and the augmentation above
// (amplitude and time scales per class in labelled_traces.cc; drops x0.5-1.5
// as fast, lateral x0.5-2 with +-3 mm twist, a touch of up to 0.6 N over up
// to 8 ms).
SimulationConditions TrainingConditions();

// `per_class` traces of each class, interleaved hard, medium, soft,
// hard_skin, each from a new simulated food item. Deterministic in `seed`.
std::vector<LabelledTrace> SimulateLabelledTraces(
    int per_class, const SimulationConditions& conditions, uint64_t seed);

// Where simulated traces come from: the simulated world's force-trace model
// under TrainingConditions() (augmented), or one of the independent stories
// of services/sim/trace_stories.h. HapticNet is trained on some and judged on
// one it never saw.
enum class TraceStory {
  kWorld = 0,
  kPiecewise = 1,
  kMechanics = 2,
  kCompliant = 3,
  kPuncture = 4,
  kPoroelastic = 5,
  kLattice = 6
};
inline constexpr int kTraceStories = 7;

// "world", "piecewise", "mechanics", "compliant", "puncture", "poroelastic",
// "lattice".
const char* TraceStoryName(TraceStory story);

// Every story's name in order, comma-separated ("world, piecewise, ...").
std::string TraceStoryNames();

// A comma-separated list of story names, each at most once. INVALID_ARGUMENT
// naming an unknown or repeated name, or an empty list.
absl::StatusOr<std::vector<TraceStory>> ParseTraceStories(
    absl::string_view names);

// One trace of a new item of a category, as the independent stories of
// services/sim/trace_stories.h draw it.
using StoryTraceFunction = std::vector<TimedWrench> (*)(sim::HapticCategory,
                                                        std::mt19937_64&);

// The draw of an independent story; nullptr for kWorld, whose traces come
// from per-food profiles (SimulateLabelledTraces, sim::SimulateTrace).
StoryTraceFunction StoryTraceDraw(TraceStory story);

// `per_class` traces of each class from `story`, interleaved hard, medium,
// soft, hard_skin, each a new item. Deterministic in `seed`; different
// stories draw from different streams of the same seed.
std::vector<LabelledTrace> StoryTraces(TraceStory story, int per_class,
                                       uint64_t seed);

// Writes `traces` in the CSV format above. INTERNAL if the file cannot be
// written.
absl::Status WriteTraceCsv(const std::string& path,
                           const std::vector<LabelledTrace>& traces);

// Reads the CSV format above. NOT_FOUND if the file cannot be opened;
// INVALID_ARGUMENT naming the line for a bad header, a malformed row, an
// unknown label or a label that changes within a trace.
absl::StatusOr<std::vector<LabelledTrace>> ReadTraceCsv(
    const std::string& path);

// Augmentation of any trace, drawn from what differs between one fork,
// sensor and arm and another, not from any story's shapes (the trainer's
// --augment; applied to the training and validation traces of every story
// and recording). Per trace, in this order:
//  - time: the whole trace's clock stretched, log-uniform in
//    [1/max_time_scale, max_time_scale] (a faster or slower descent; the
//    sample rate changes with it);
//  - amplitude: every channel scaled, log-uniform in [1/max_amplitude_scale,
//    max_amplitude_scale] (a firmer or weaker item);
//  - fork angle: the wrench rotated by up to max_tilt_deg about a random
//    horizontal axis (the tines not along the sensor's z: Fz mixes into Fx,
//    Fy and the torques), plus a lever offset of up to max_offset_m
//    (torque += offset x force);
//  - lag: a first-order low-pass with a time constant uniform in
//    [0, max_lag_s] (another sensor's gauges and filter);
//  - sample rate: with probability resample_probability, resampled by
//    linear interpolation to a log-uniform rate in [min_rate_hz, its own
//    rate] (a slower sensor);
//  - drift: each channel drifts linearly by up to +-max_drift_n_per_s
//    (torques 0.02 m times as much; thermal drift during the trace);
//  - coloured noise: a first-order autoregression per channel with a
//    correlation time log-uniform in [1 ms, 10 ms] and a standard deviation
//    uniform in [0, max_coloured_noise_n] (arm vibration, mains hum, cable
//    motion).
struct TraceAugmentation {
  double max_time_scale = 1.3;
  double max_amplitude_scale = 1.3;
  double max_tilt_deg = 15.0;
  double max_offset_m = 0.003;
  double max_lag_s = 1e-3;
  double resample_probability = 0.3;
  double min_rate_hz = 250.0;
  double max_drift_n_per_s = 0.5;
  double max_coloured_noise_n = 0.08;
};

// One augmented copy of `samples` (see TraceAugmentation).
std::vector<TimedWrench> AugmentTrace(const std::vector<TimedWrench>& samples,
                                      const TraceAugmentation& augmentation,
                                      std::mt19937_64& rng);

// A trace as recorded by a meal (clients/meal/trace_recording.h): its id in
// the file, and its label unless the food was unknown ("unknown").
struct RecordedTrace {
  std::string id;
  std::optional<HapticClass> label;
  std::vector<TimedWrench> samples;
};

// `samples` with its clock stretched by a factor drawn log-uniform in
// [1, max_factor] (max_factor >= 1): the same trace felt by a fork that
// meets the food more slowly, so every force change takes longer.
std::vector<TimedWrench> SlowApproach(const std::vector<TimedWrench>& samples,
                                      double max_factor, std::mt19937_64& rng);

// The arm's compliance in series with the food, quasi-statically. A trace of
// the stories is felt through a rigid arm descending at `speed_mps`: the tip
// is at depth v t when the food pushes back with F(t). Through a wrist that is
// a spring of stiffness k, the controller's commanded position must run
// ahead of the tip by F / k before the spring carries F, so the tip reaches
// that depth, and the sensor (between the spring and the fork) reads that
// force, at t + F / (k v). Stiff items are slowed most (the series stiffness
// is below k whatever the food's), soft ones little. Where the food yields,
// the spring throws the tip ahead (snap-through): the samples it passes
// during the jump are never felt, so a drop stays as fast as it was.
//  - probability: the share of traces felt through a compliant arm (the
//    others stay as they are, a rigid arm);
//  - stiffness: log-uniform in [min, max] N/m, from a lightweight
//    flexible-joint arm (1 N/mm) to a stiff holder (20 N/mm);
//  - speed_mps: the robot's descend speed (RobotOptions, 5 cm/s).
// Mass, damping and ringing are not modelled (quasi-static).
struct ArmCompliance {
  double probability = 0.5;
  double min_stiffness_n_per_m = 1000.0;
  double max_stiffness_n_per_m = 20000.0;
  double speed_mps = 0.05;
};

// `samples` felt through a compliant arm (see ArmCompliance), on its own
// clock: the same sample times, the force of each moved later by F / (k v),
// where F is the norm of the force tared as the service tares it
// (SensorOffset over ContactDetectorOptions' tare_s), smoothed over 1 ms so
// that noise does not reorder the clock. Returned unchanged with probability 1
// - `probability`.
std::vector<TimedWrench> CompliantArm(const std::vector<TimedWrench>& samples,
                                      const ArmCompliance& arm,
                                      std::mt19937_64& rng);

// Reads the CSV format above, accepting the label "unknown". Errors as
// ReadTraceCsv.
absl::StatusOr<std::vector<RecordedTrace>> ReadRecordedTraces(
    const std::string& path);

// Reads the labels of a recording's bites file (any CSV whose header has the
// columns "trace" and "label"; one row per trace), by trace id, so a lab can
// label or relabel its recordings one bite per row. NOT_FOUND if the file
// cannot be opened; INVALID_ARGUMENT naming the line for a missing column, a
// short row, an unknown label or a trace listed twice.
absl::StatusOr<std::map<std::string, std::optional<HapticClass>>>
ReadTraceLabels(const std::string& path);

// Network inputs of `traces` through the service's own feature pipeline.
// Traces the pipeline rejects (no contact, too short) are skipped and
// counted in `*skipped` if given.
LabelledWindows WindowsFromTraces(const std::vector<LabelledTrace>& traces,
                                  const HapticPipelineOptions& options,
                                  int* skipped);

}  // namespace bitewise::haptic

#endif  // BITEWISE_SERVICES_HAPTIC_TRAINING_LABELLED_TRACES_H_
