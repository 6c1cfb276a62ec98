#include "services/haptic/training/labelled_traces.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <random>

#include "absl/strings/ascii.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_split.h"
#include "services/domain/random.h"
#include "services/domain/trace_csv.h"
#include "services/haptic/core/contact_detector.h"
#include "services/sim/force_trace.h"
#include "services/sim/trace_stories.h"

namespace bitewise::haptic {
namespace {

double Uniform(std::mt19937_64& rng, double lo, double hi) {
  if (lo == hi) return lo;
  return random::Uniform(rng, lo, hi);
}

double LogUniform(std::mt19937_64& rng, double lo, double hi) {
  return std::exp(Uniform(rng, std::log(lo), std::log(hi)));
}

// One draw of the augmentation ranges of `conditions` for an item of
// class `k`.
sim::TraceVariation DrawVariation(const SimulationConditions& conditions, int k,
                                  std::mt19937_64& rng) {
  sim::TraceVariation v;
  v.amplitude = LogUniform(rng, conditions.min_amplitude_scale[k],
                           conditions.max_amplitude_scale[k]);
  v.time_scale = LogUniform(rng, conditions.min_time_scale[k],
                            conditions.max_time_scale[k]);
  v.drop_time_scale = LogUniform(rng, conditions.min_drop_time_scale,
                                 conditions.max_drop_time_scale);
  v.lateral_scale =
      Uniform(rng, conditions.min_lateral_scale, conditions.max_lateral_scale);
  v.twist_m = Uniform(rng, -conditions.max_twist_m, conditions.max_twist_m);
  v.touch_n = Uniform(rng, 0.0, conditions.max_touch_n);
  v.touch_s = Uniform(rng, 0.0, conditions.max_touch_s);
  return v;
}

bool ParseLabel(absl::string_view text, HapticClass* label) {
  for (int k = 0; k < kHapticClasses; ++k) {
    if (text == HapticClassName(static_cast<HapticClass>(k))) {
      *label = static_cast<HapticClass>(k);
      return true;
    }
  }
  return false;
}

}  // namespace

bool SimulationConditions::Augmented() const {
  for (int k = 0; k < kHapticClasses; ++k) {
    if (min_amplitude_scale[k] != 1.0 || max_amplitude_scale[k] != 1.0 ||
        min_time_scale[k] != 1.0 || max_time_scale[k] != 1.0) {
      return true;
    }
  }
  return min_drop_time_scale != 1.0 || max_drop_time_scale != 1.0 ||
         min_lateral_scale != 1.0 || max_lateral_scale != 1.0 ||
         max_twist_m != 0.0 || max_touch_n != 0.0 || max_touch_s != 0.0;
}

SimulationConditions TrainingConditions() {
  SimulationConditions c;
  c.min_rate_hz = 100.0;
  c.max_rate_hz = 7000.0;
  c.min_noise_scale = 0.5;
  c.max_noise_scale = 3.0;
  c.random_bias_n = 2.5;
  c.jitter_fraction = 0.1;
  c.min_contact_s = 0.1;
  c.max_contact_s = 0.3;
  c.after_contact_s = 0.2;
  // Per class: hard, medium, soft, hard_skin. Hard 7-29 N; medium 2-8 N,
  // its puncture still inside the 50 ms window; soft at most 1.2x (it must
  // stay low and slow); hard-skin 3.5-13.5 N.
  c.min_amplitude_scale = {0.7, 0.8, 0.6, 0.7};
  c.max_amplitude_scale = {1.6, 1.6, 1.2, 1.5};
  c.min_time_scale = {0.7, 0.7, 0.7, 0.7};
  c.max_time_scale = {1.4, 1.2, 1.4, 1.4};
  c.min_drop_time_scale = 0.5;
  c.max_drop_time_scale = 1.5;
  c.min_lateral_scale = 0.5;
  c.max_lateral_scale = 2.0;
  c.max_twist_m = 0.003;
  c.max_touch_n = 0.6;
  c.max_touch_s = 0.008;
  return c;
}

std::vector<LabelledTrace> SimulateLabelledTraces(
    int per_class, const SimulationConditions& conditions, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<LabelledTrace> traces;
  traces.reserve(static_cast<size_t>(per_class) * kHapticClasses);
  for (int i = 0; i < per_class; ++i) {
    for (int k = 0; k < kHapticClasses; ++k) {
      // HapticClass and sim::HapticCategory share HapticNet's class order.
      const auto category = static_cast<sim::HapticCategory>(k);
      const sim::ForceProfile profile =
          sim::ForceProfile::Sample(category, rng);
      sim::TraceOptions options;
      options.rate_hz = std::exp(Uniform(rng, std::log(conditions.min_rate_hz),
                                         std::log(conditions.max_rate_hz)));
      options.contact_s =
          Uniform(rng, conditions.min_contact_s, conditions.max_contact_s);
      options.duration_s = options.contact_s + conditions.after_contact_s;
      options.jitter_fraction = conditions.jitter_fraction;
      options.stop.limit_n = conditions.force_limit_n;
      const double noise_scale =
          Uniform(rng, conditions.min_noise_scale, conditions.max_noise_scale);
      options.noise.force_sd_n *= noise_scale;
      options.noise.torque_sd_nm *= noise_scale;
      options.noise.random_bias_n = conditions.random_bias_n;
      for (int c = 0; c < 3; ++c) {
        options.noise.bias.force_n[c] = conditions.fixed_bias_n;
        options.noise.bias.torque_nm[c] = 0.02 * conditions.fixed_bias_n;
      }
      if (conditions.Augmented()) {
        options.variation = DrawVariation(conditions, k, rng);
      }
      LabelledTrace trace;
      trace.label = static_cast<HapticClass>(k);
      trace.samples = sim::SimulateTrace(profile, options, rng);
      traces.push_back(std::move(trace));
    }
  }
  return traces;
}

const char* TraceStoryName(TraceStory story) {
  switch (story) {
    case TraceStory::kWorld:
      return "world";
    case TraceStory::kPiecewise:
      return "piecewise";
    case TraceStory::kMechanics:
      return "mechanics";
    case TraceStory::kCompliant:
      return "compliant";
    case TraceStory::kPuncture:
      return "puncture";
    case TraceStory::kPoroelastic:
      return "poroelastic";
    case TraceStory::kLattice:
      return "lattice";
  }
  return "unknown";
}

std::string TraceStoryNames() {
  std::string names;
  for (int i = 0; i < kTraceStories; ++i) {
    absl::StrAppend(&names, i > 0 ? ", " : "",
                    TraceStoryName(static_cast<TraceStory>(i)));
  }
  return names;
}

absl::StatusOr<std::vector<TraceStory>> ParseTraceStories(
    absl::string_view names) {
  std::vector<TraceStory> stories;
  for (absl::string_view name : absl::StrSplit(names, ',', absl::SkipEmpty())) {
    name = absl::StripAsciiWhitespace(name);
    bool known = false;
    for (int i = 0; i < kTraceStories; ++i) {
      const auto story = static_cast<TraceStory>(i);
      if (name != TraceStoryName(story)) continue;
      known = true;
      if (std::find(stories.begin(), stories.end(), story) != stories.end()) {
        return absl::InvalidArgumentError(
            absl::StrCat("trace story \"", name, "\" given twice"));
      }
      stories.push_back(story);
    }
    if (!known) {
      return absl::InvalidArgumentError(absl::StrCat(
          "unknown trace story \"", name, "\" (", TraceStoryNames(), ")"));
    }
  }
  if (stories.empty()) {
    return absl::InvalidArgumentError("no trace story given");
  }
  return stories;
}

StoryTraceFunction StoryTraceDraw(TraceStory story) {
  switch (story) {
    case TraceStory::kPiecewise:
      return sim::PiecewiseStoryTrace;
    case TraceStory::kMechanics:
      return sim::MechanicsStoryTrace;
    case TraceStory::kCompliant:
      return sim::CompliantStoryTrace;
    case TraceStory::kPuncture:
      return sim::PunctureStoryTrace;
    case TraceStory::kPoroelastic:
      return sim::PoroelasticStoryTrace;
    case TraceStory::kLattice:
      return sim::LatticeStoryTrace;
    case TraceStory::kWorld:
      break;
  }
  return nullptr;
}

std::vector<LabelledTrace> StoryTraces(TraceStory story, int per_class,
                                       uint64_t seed) {
  if (story == TraceStory::kWorld) {
    std::vector<LabelledTrace> traces =
        SimulateLabelledTraces(per_class, TrainingConditions(), seed);
    for (LabelledTrace& trace : traces) trace.source = static_cast<int>(story);
    return traces;
  }
  // Each story its own stream of the seed.
  const uint64_t stream =
      story == TraceStory::kPiecewise   ? 0x00d00d00d00d00dull
      : story == TraceStory::kMechanics ? 0x3ec4a41c53ec4a41ull
      : story == TraceStory::kCompliant ? 0xc0111a9700c0111aull
                                        : 0x9c7c9c7c9c7c9c7cull;
  const StoryTraceFunction draw = StoryTraceDraw(story);
  std::mt19937_64 rng(seed ^ stream);
  std::vector<LabelledTrace> traces;
  traces.reserve(static_cast<size_t>(per_class) * kHapticClasses);
  for (int i = 0; i < per_class; ++i) {
    for (int k = 0; k < kHapticClasses; ++k) {
      const auto category = static_cast<sim::HapticCategory>(k);
      LabelledTrace trace;
      trace.label = static_cast<HapticClass>(k);
      trace.samples = draw(category, rng);
      trace.source = static_cast<int>(story);
      traces.push_back(std::move(trace));
    }
  }
  return traces;
}

std::vector<TimedWrench> AugmentTrace(const std::vector<TimedWrench>& samples,
                                      const TraceAugmentation& augmentation,
                                      std::mt19937_64& rng) {
  const auto log_uniform_around_one = [&](double max_scale) {
    return std::exp(Uniform(rng, -std::log(max_scale), std::log(max_scale)));
  };
  const double time_scale = log_uniform_around_one(augmentation.max_time_scale);
  const double amplitude =
      log_uniform_around_one(augmentation.max_amplitude_scale);
  // Rotation by `tilt` about the horizontal axis (cos a, sin a, 0)
  // (Rodrigues), the same for forces and torques.
  const double tilt =
      Uniform(rng, 0.0, augmentation.max_tilt_deg) * M_PI / 180.0;
  const double axis_angle = Uniform(rng, 0.0, 2.0 * M_PI);
  const double kx = std::cos(axis_angle), ky = std::sin(axis_angle);
  const double c = std::cos(tilt), s = std::sin(tilt);
  const std::array<std::array<double, 3>, 3> rotation = {{
      {c + kx * kx * (1 - c), kx * ky * (1 - c), ky * s},
      {kx * ky * (1 - c), c + ky * ky * (1 - c), -kx * s},
      {-ky * s, kx * s, c},
  }};
  const std::array<double, 3> offset = {
      Uniform(rng, -augmentation.max_offset_m, augmentation.max_offset_m),
      Uniform(rng, -augmentation.max_offset_m, augmentation.max_offset_m), 0.0};
  const double lag_s = Uniform(rng, 0.0, augmentation.max_lag_s);
  const bool resample =
      random::Canonical(rng) < augmentation.resample_probability;
  const double resample_draw = random::Canonical(rng);
  std::array<double, kWrenchChannels> drift;
  for (int k = 0; k < kWrenchChannels; ++k) {
    drift[k] = Uniform(rng, -augmentation.max_drift_n_per_s,
                       augmentation.max_drift_n_per_s) *
               (k < 3 ? 1.0 : 0.02);
  }
  const double correlation_s =
      std::exp(Uniform(rng, std::log(1e-3), std::log(1e-2)));
  const double noise_sd = Uniform(rng, 0.0, augmentation.max_coloured_noise_n);

  // Clock, amplitude, angle and lever.
  std::vector<TimedWrench> out;
  out.reserve(samples.size());
  for (const TimedWrench& sample : samples) {
    TimedWrench w;
    w.t_s = sample.t_s * time_scale;
    std::array<double, 3> f, t;
    for (int i = 0; i < 3; ++i) {
      f[i] = t[i] = 0.0;
      for (int j = 0; j < 3; ++j) {
        f[i] += rotation[i][j] * sample.wrench.force_n[j] * amplitude;
        t[i] += rotation[i][j] * sample.wrench.torque_nm[j] * amplitude;
      }
    }
    t[0] += offset[1] * f[2] - offset[2] * f[1];
    t[1] += offset[2] * f[0] - offset[0] * f[2];
    t[2] += offset[0] * f[1] - offset[1] * f[0];
    w.wrench.force_n = f;
    w.wrench.torque_nm = t;
    out.push_back(w);
  }
  // The lag (exact for a first-order filter between samples).
  if (lag_s > 0.0) {
    for (size_t i = 1; i < out.size(); ++i) {
      const double keep = std::exp(-(out[i].t_s - out[i - 1].t_s) / lag_s);
      for (int k = 0; k < kWrenchChannels; ++k) {
        Channel(out[i].wrench, k) = keep * Channel(out[i - 1].wrench, k) +
                                    (1.0 - keep) * Channel(out[i].wrench, k);
      }
    }
  }
  // A slower sensor.
  if (resample && out.size() > 2) {
    const double duration = out.back().t_s - out.front().t_s;
    const double rate = (out.size() - 1) / duration;
    if (rate > augmentation.min_rate_hz * 1.2) {
      const double new_rate =
          std::exp(std::log(augmentation.min_rate_hz) +
                   resample_draw *
                       (std::log(rate) - std::log(augmentation.min_rate_hz)));
      std::vector<TimedWrench> resampled;
      size_t j = 0;
      for (double t = out.front().t_s; t <= out.back().t_s;
           t += 1.0 / new_rate) {
        while (j + 2 < out.size() && out[j + 1].t_s < t) ++j;
        const double span = out[j + 1].t_s - out[j].t_s;
        const double w = span > 0.0 ? (t - out[j].t_s) / span : 0.0;
        TimedWrench sample;
        sample.t_s = t;
        for (int k = 0; k < kWrenchChannels; ++k) {
          Channel(sample.wrench, k) = (1.0 - w) * Channel(out[j].wrench, k) +
                                      w * Channel(out[j + 1].wrench, k);
        }
        resampled.push_back(sample);
      }
      out = std::move(resampled);
    }
  }
  // Drift and coloured noise.
  random::Normal normal;
  std::array<double, kWrenchChannels> noise{};
  for (int k = 0; k < kWrenchChannels; ++k) {
    noise[k] = noise_sd * (k < 3 ? 1.0 : 0.02) * normal(rng);
  }
  for (size_t i = 0; i < out.size(); ++i) {
    const double dt = i == 0 ? 0.0 : out[i].t_s - out[i - 1].t_s;
    const double keep = std::exp(-dt / correlation_s);
    for (int k = 0; k < kWrenchChannels; ++k) {
      const double sd = noise_sd * (k < 3 ? 1.0 : 0.02);
      noise[k] =
          keep * noise[k] + std::sqrt(1.0 - keep * keep) * sd * normal(rng);
      Channel(out[i].wrench, k) += drift[k] * out[i].t_s + noise[k];
    }
  }
  return out;
}

std::vector<TimedWrench> SlowApproach(const std::vector<TimedWrench>& samples,
                                      double max_factor, std::mt19937_64& rng) {
  const double factor = std::exp(Uniform(rng, 0.0, std::log(max_factor)));
  std::vector<TimedWrench> out = samples;
  for (TimedWrench& sample : out) sample.t_s *= factor;
  return out;
}

std::vector<TimedWrench> CompliantArm(const std::vector<TimedWrench>& samples,
                                      const ArmCompliance& arm,
                                      std::mt19937_64& rng) {
  const bool compliant = Uniform(rng, 0.0, 1.0) < arm.probability;
  const double stiffness =
      std::exp(Uniform(rng, std::log(arm.min_stiffness_n_per_m),
                       std::log(arm.max_stiffness_n_per_m)));
  if (!compliant || samples.size() < 2) return samples;
  const double rate_n_per_s = stiffness * arm.speed_mps;
  const size_t n = samples.size();
  // The service's tare (ContactDetector's), and the tared force norm.
  const std::array<double, kWrenchChannels> offset =
      SensorOffset(samples, ContactDetectorOptions{}.tare_s);
  std::vector<double> force(n);
  for (size_t i = 0; i < n; ++i) {
    force[i] = TaredForceMagnitude(samples[i], offset);
  }
  // Each sample's time through the spring, from the force smoothed over
  // +-0.5 ms; only the samples that come later than every one before them
  // are felt (the others are passed during a snap-through).
  std::vector<double> felt_t;
  std::vector<size_t> felt;
  size_t lo = 0, hi = 0;
  double window_sum = 0.0;
  for (size_t i = 0; i < n; ++i) {
    const double t = samples[i].t_s;
    while (hi < n && samples[hi].t_s <= t + 0.5e-3) window_sum += force[hi++];
    while (samples[lo].t_s < t - 0.5e-3) window_sum -= force[lo++];
    const double smoothed = window_sum / static_cast<double>(hi - lo);
    const double moved = t + smoothed / rate_n_per_s;
    if (felt_t.empty() || moved > felt_t.back()) {
      felt_t.push_back(moved);
      felt.push_back(i);
    }
  }
  // Resampled on the trace's own clock by linear interpolation between the
  // felt samples; the rigid trace's last F / (k v) seconds fall off its end.
  std::vector<TimedWrench> out = samples;
  size_t j = 0;
  for (TimedWrench& sample : out) {
    while (j + 1 < felt_t.size() && felt_t[j + 1] <= sample.t_s) ++j;
    const TimedWrench& a = samples[felt[j]];
    if (sample.t_s <= felt_t[j] || j + 1 == felt_t.size()) {
      sample.wrench = a.wrench;
      continue;
    }
    const TimedWrench& b = samples[felt[j + 1]];
    const double w = (sample.t_s - felt_t[j]) / (felt_t[j + 1] - felt_t[j]);
    for (int k = 0; k < kWrenchChannels; ++k) {
      Channel(sample.wrench, k) =
          (1.0 - w) * Channel(a.wrench, k) + w * Channel(b.wrench, k);
    }
  }
  return out;
}

absl::Status WriteTraceCsv(const std::string& path,
                           const std::vector<LabelledTrace>& traces) {
  std::FILE* file = std::fopen(path.c_str(), "w");
  if (file == nullptr) {
    return absl::InternalError(absl::StrCat("cannot write ", path));
  }
  std::fprintf(file, "%s\n", domain::kTraceCsvHeader);
  std::string rows;
  for (size_t i = 0; i < traces.size(); ++i) {
    rows.clear();
    const std::string id = absl::StrCat(i);
    for (const TimedWrench& s : traces[i].samples) {
      domain::AppendTraceCsvRow(&rows, id, HapticClassName(traces[i].label),
                                s.t_s, Channels(s.wrench));
    }
    std::fwrite(rows.data(), 1, rows.size(), file);
  }
  const bool failed = std::ferror(file) != 0;
  if (std::fclose(file) != 0 || failed) {
    return absl::InternalError(absl::StrCat("error writing ", path));
  }
  return absl::OkStatus();
}

namespace {

// The CSV reader behind ReadTraceCsv and ReadRecordedTraces: "unknown" is a
// label only where `allow_unlabelled`.
absl::StatusOr<std::vector<RecordedTrace>> ReadCsv(const std::string& path,
                                                   bool allow_unlabelled) {
  std::ifstream in(path);
  if (!in) return absl::NotFoundError(absl::StrCat("cannot open ", path));
  std::string line;
  if (!std::getline(in, line) ||
      absl::StripTrailingAsciiWhitespace(line) !=
          absl::string_view(domain::kTraceCsvHeader)) {
    return absl::InvalidArgumentError(absl::StrCat(
        path, ":1: expected the header \"", domain::kTraceCsvHeader, "\""));
  }
  std::vector<RecordedTrace> traces;
  std::string label_text;
  int line_number = 1;
  while (std::getline(in, line)) {
    ++line_number;
    const absl::string_view row = absl::StripTrailingAsciiWhitespace(line);
    if (row.empty()) continue;
    const std::vector<absl::string_view> fields = absl::StrSplit(row, ',');
    if (fields.size() != domain::kTraceCsvFields) {
      return absl::InvalidArgumentError(absl::StrCat(
          path, ":", line_number, ": expected ", domain::kTraceCsvFields,
          " fields, got ", fields.size()));
    }
    std::optional<HapticClass> label;
    HapticClass parsed;
    if (ParseLabel(fields[1], &parsed)) {
      label = parsed;
    } else if (!allow_unlabelled || fields[1] != domain::kUnlabelled) {
      return absl::InvalidArgumentError(absl::StrCat(
          path, ":", line_number, ": unknown label \"", fields[1],
          allow_unlabelled ? "\" (hard, medium, soft, hard_skin, unknown)"
                           : "\" (hard, medium, soft, hard_skin)"));
    }
    TimedWrench sample;
    bool ok = absl::SimpleAtod(fields[2], &sample.t_s);
    for (int c = 0; c < kWrenchChannels && ok; ++c) {
      ok = absl::SimpleAtod(fields[3 + c], &Channel(sample.wrench, c));
    }
    if (!ok) {
      return absl::InvalidArgumentError(
          absl::StrCat(path, ":", line_number, ": malformed number"));
    }
    // SimpleAtod takes "nan", "inf" and "1e999": no sensor sends them.
    bool finite = std::isfinite(sample.t_s);
    for (int c = 0; c < kWrenchChannels && finite; ++c) {
      finite = std::isfinite(Channel(sample.wrench, c));
    }
    if (!finite) {
      return absl::InvalidArgumentError(
          absl::StrCat(path, ":", line_number,
                       ": a time or a reading is not a finite "
                       "number"));
    }
    if (traces.empty() || fields[0] != traces.back().id) {
      if (fields[0].empty()) {
        return absl::InvalidArgumentError(
            absl::StrCat(path, ":", line_number, ": empty trace id"));
      }
      traces.push_back({std::string(fields[0]), label, {}});
      label_text = std::string(fields[1]);
    } else if (fields[1] != label_text) {
      return absl::InvalidArgumentError(
          absl::StrCat(path, ":", line_number, ": trace ", traces.back().id,
                       " changes its label to ", fields[1]));
    }
    traces.back().samples.push_back(sample);
  }
  return traces;
}

}  // namespace

absl::StatusOr<std::vector<LabelledTrace>> ReadTraceCsv(
    const std::string& path) {
  absl::StatusOr<std::vector<RecordedTrace>> read =
      ReadCsv(path, /*allow_unlabelled=*/false);
  if (!read.ok()) return read.status();
  std::vector<LabelledTrace> traces;
  traces.reserve(read->size());
  for (RecordedTrace& trace : *read) {
    traces.push_back({*trace.label, std::move(trace.samples)});
  }
  return traces;
}

absl::StatusOr<std::vector<RecordedTrace>> ReadRecordedTraces(
    const std::string& path) {
  return ReadCsv(path, /*allow_unlabelled=*/true);
}

absl::StatusOr<std::map<std::string, std::optional<HapticClass>>>
ReadTraceLabels(const std::string& path) {
  std::ifstream in(path);
  if (!in) return absl::NotFoundError(absl::StrCat("cannot open ", path));
  std::string line;
  if (!std::getline(in, line)) {
    return absl::InvalidArgumentError(absl::StrCat(path, ": empty file"));
  }
  const std::vector<std::string> header =
      absl::StrSplit(absl::StripTrailingAsciiWhitespace(line), ',');
  const auto column = [&](absl::string_view name) {
    return static_cast<int>(std::find(header.begin(), header.end(), name) -
                            header.begin());
  };
  const int trace_column = column("trace");
  const int label_column = column("label");
  const int columns = static_cast<int>(header.size());
  if (trace_column == columns || label_column == columns) {
    return absl::InvalidArgumentError(absl::StrCat(
        path, ":1: the header needs the columns \"trace\" and \"label\""));
  }
  std::map<std::string, std::optional<HapticClass>> labels;
  int line_number = 1;
  while (std::getline(in, line)) {
    ++line_number;
    const absl::string_view row = absl::StripTrailingAsciiWhitespace(line);
    if (row.empty()) continue;
    const std::vector<absl::string_view> fields = absl::StrSplit(row, ',');
    if (static_cast<int>(fields.size()) != columns) {
      return absl::InvalidArgumentError(
          absl::StrCat(path, ":", line_number, ": expected ", columns,
                       " fields, got ", fields.size()));
    }
    std::optional<HapticClass> label;
    HapticClass parsed;
    if (ParseLabel(fields[label_column], &parsed)) {
      label = parsed;
    } else if (fields[label_column] != domain::kUnlabelled) {
      return absl::InvalidArgumentError(absl::StrCat(
          path, ":", line_number, ": unknown label \"", fields[label_column],
          "\" (hard, medium, soft, hard_skin, unknown)"));
    }
    if (!labels.emplace(std::string(fields[trace_column]), label).second) {
      return absl::InvalidArgumentError(
          absl::StrCat(path, ":", line_number, ": trace ", fields[trace_column],
                       " is listed twice"));
    }
  }
  return labels;
}

LabelledWindows WindowsFromTraces(const std::vector<LabelledTrace>& traces,
                                  const HapticPipelineOptions& options,
                                  int* skipped) {
  LabelledWindows windows;
  int rejected = 0;
  for (const LabelledTrace& trace : traces) {
    absl::StatusOr<HapticFeatures> features =
        ExtractHapticFeatures(trace.samples, options);
    if (!features.ok()) {
      ++rejected;
      continue;
    }
    windows.inputs.push_back(features->window.inputs);
    windows.labels.push_back(static_cast<int>(trace.label));
    windows.sources.push_back(trace.source);
  }
  if (skipped != nullptr) *skipped = rejected;
  return windows;
}

}  // namespace bitewise::haptic
