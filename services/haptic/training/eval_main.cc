// bitewise-haptic-eval: measures a HapticNet model the way the service runs
// it (HapticClassifier: contact detection, window, OpenCV DNN) on fresh
// simulated traces under several sensor conditions, and on traces of a
// deliberately different, independent generator (out of distribution), and
// prints accuracy, log loss, calibration error, the range of the
// log-probabilities and a confusion matrix for each. Flags are parsed here
// and nowhere else.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <functional>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "absl/flags/flag.h"
#include "absl/flags/parse.h"
#include "absl/flags/usage.h"
#include "services/common/flags_usage.h"
#include "services/haptic/core/haptic_classifier.h"
#include "services/haptic/core/haptic_net.h"
#include "services/haptic/default_model.h"
#include "services/haptic/training/haptic_trainer.h"
#include "services/haptic/training/labelled_traces.h"

ABSL_FLAG(std::string, model, "",
          "ONNX model to evaluate. Empty: the model compiled into the "
          "binary (models/hapticnet/hapticnet.onnx).");
ABSL_FLAG(int, traces_per_class, 500,
          "Simulated traces per class and "
          "condition.");
ABSL_FLAG(uint64_t, seed, 20261123,
          "Seed of the test traces; differs from the trainer's so every "
          "trace is new.");
ABSL_FLAG(bool, confusion, true, "Print a confusion matrix per condition.");

namespace {

using namespace bitewise::haptic;  // NOLINT: a main over one namespace

struct Condition {
  const char* name;
  SimulationConditions conditions;
};

double Uniform(std::mt19937_64& rng, double lo, double hi) {
  return std::uniform_real_distribution<double>(lo, hi)(rng);
}

// Fz (N) of one item of the out-of-distribution generator: piecewise-linear
// segments through (time after contact, force) knots, flat after the last.
// It shares nothing with the force-trace model (services/sim), whose
// rises are exponential: only the physical idea of each category is the
// same, with its own, wider ranges.
struct PiecewiseLinear {
  std::vector<std::array<double, 2>> knots;  // (tau_s, fz_n), tau ascending
  double At(double tau) const {
    if (tau <= 0.0) return 0.0;
    for (size_t i = 1; i < knots.size(); ++i) {
      if (tau <= knots[i][0]) {
        const auto& a = knots[i - 1];
        const auto& b = knots[i];
        return a[1] + (b[1] - a[1]) * (tau - a[0]) / (b[0] - a[0]);
      }
    }
    return knots.back()[1];
  }
};

PiecewiseLinear OutOfDistributionItem(HapticClass label, std::mt19937_64& rng) {
  PiecewiseLinear p;
  switch (label) {
    case HapticClass::kHard: {
      // A straight ramp to a high force, then a slow creep or relaxation.
      const double peak = Uniform(rng, 8.0, 22.0);
      const double rise = Uniform(rng, 0.004, 0.016);
      p.knots = {
          {0.0, 0.0}, {rise, peak}, {0.2, peak * Uniform(rng, 0.9, 1.1)}};
      break;
    }
    case HapticClass::kMedium: {
      // A moderate ramp, a plateau, a puncture losing 12-35 %, a slow rise.
      const double peak = Uniform(rng, 2.0, 6.0);
      const double rise = Uniform(rng, 0.010, 0.025);
      const double puncture = rise + Uniform(rng, 0.008, 0.020);
      const double after = peak * (1.0 - Uniform(rng, 0.12, 0.35));
      const double fall = Uniform(rng, 0.003, 0.008);
      p.knots = {{0.0, 0.0},
                 {rise, peak},
                 {puncture, peak * Uniform(rng, 0.95, 1.05)},
                 {puncture + fall, after},
                 {0.2, after * Uniform(rng, 1.0, 1.3)}};
      break;
    }
    case HapticClass::kSoft: {
      // A slow ramp that levels off at a low force.
      const double slope = Uniform(rng, 12.0, 40.0);
      const double level = Uniform(rng, 1.5, 3.0);
      p.knots = {{0.0, 0.0},
                 {level / slope, level},
                 {0.2, level * Uniform(rng, 1.0, 1.2)}};
      break;
    }
    case HapticClass::kHardSkin: {
      // A steep ramp to a peak, the skin breaks: a fast drop of 50-80 %.
      const double peak = Uniform(rng, 4.0, 10.0);
      const double rise = Uniform(rng, 0.007, 0.018);
      const double skin = rise + Uniform(rng, 0.002, 0.012);
      const double after = peak * (1.0 - Uniform(rng, 0.5, 0.8));
      const double fall = Uniform(rng, 0.001, 0.004);
      p.knots = {{0.0, 0.0},
                 {rise, peak},
                 {skin, peak * Uniform(rng, 1.0, 1.08)},
                 {skin + fall, after},
                 {0.2, after}};
      break;
    }
  }
  return p;
}

// `per_class` traces per class from the generator above: rates 100 Hz to
// 7 kHz (one of six), its own noise (0.03-0.15 N, 0.002-0.008 N m), offset
// (+-1.5 N), lateral force (up to 30 % of Fz in any direction) and lever
// (15-45 mm), contact 0.15-0.35 s into the trace, 0.25 s after it.
std::vector<LabelledTrace> OutOfDistributionTraces(int per_class,
                                                   uint64_t seed) {
  constexpr std::array<double, 6> kRates = {100.0,  250.0,  500.0,
                                            1000.0, 2500.0, 7000.0};
  std::mt19937_64 rng(seed ^ 0x00d00d00d00d00dull);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::vector<LabelledTrace> traces;
  for (int i = 0; i < per_class; ++i) {
    for (int k = 0; k < kHapticClasses; ++k) {
      LabelledTrace trace;
      trace.label = static_cast<HapticClass>(k);
      const PiecewiseLinear fz = OutOfDistributionItem(trace.label, rng);
      const double rate = kRates[rng() % kRates.size()];
      const double contact = Uniform(rng, 0.15, 0.35);
      const double force_sd = Uniform(rng, 0.03, 0.15);
      const double torque_sd = Uniform(rng, 0.002, 0.008);
      const double angle = Uniform(rng, 0.0, 2.0 * M_PI);
      const double lateral = Uniform(rng, 0.0, 0.3);
      const double lever = Uniform(rng, 0.015, 0.045);
      std::array<double, kWrenchChannels> offset;
      for (int c = 0; c < kWrenchChannels; ++c) {
        offset[c] = Uniform(rng, -1.5, 1.5) * (c < 3 ? 1.0 : 0.02);
      }
      const int n = static_cast<int>((contact + 0.25) * rate);
      for (int j = 0; j < n; ++j) {
        const double t = j / rate;
        const double f = fz.At(t - contact);
        const double fx = lateral * std::cos(angle) * f;
        const double fy = lateral * std::sin(angle) * f;
        WrenchSample sample;
        sample.t_s = t;
        sample.values = {fx, fy, f, lever * fy, -lever * fx, 0.0};
        for (int c = 0; c < kWrenchChannels; ++c) {
          sample.values[c] +=
              offset[c] + (c < 3 ? force_sd : torque_sd) * normal(rng);
        }
        trace.samples.push_back(sample);
      }
      traces.push_back(std::move(trace));
    }
  }
  return traces;
}

std::vector<Condition> Conditions() {
  const SimulationConditions nominal;  // 1 kHz, nominal noise, +-0.5 N
  std::vector<Condition> out = {
      {"nominal (1 kHz, noise x1, bias +-0.5 N)", nominal}};
  SimulationConditions c = nominal;
  c.min_noise_scale = c.max_noise_scale = 2.0;
  out.push_back({"doubled noise", c});
  c = nominal;
  c.fixed_bias_n = 2.0;
  c.random_bias_n = 0.0;
  out.push_back({"bias +2 N on every force channel", c});
  c.fixed_bias_n = -2.0;
  out.push_back({"bias -2 N on every force channel", c});
  c = nominal;
  c.min_rate_hz = c.max_rate_hz = 100.0;
  out.push_back({"100 Hz", c});
  c = nominal;
  c.min_rate_hz = c.max_rate_hz = 7000.0;
  out.push_back({"7 kHz", c});
  out.push_back(
      {"training mix (100 Hz-7 kHz, noise x0.5-3, bias +-2.5 N, augmented)",
       TrainingConditions()});
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  absl::SetProgramUsageMessage(
      "Evaluates a HapticNet model on fresh simulated traces.");
  bitewise::ShowOwnFlagsInHelp();
  absl::ParseCommandLine(argc, argv);
  const std::string path = absl::GetFlag(FLAGS_model);
  absl::StatusOr<std::unique_ptr<HapticNet>> net =
      path.empty() ? HapticNet::FromOnnxBytes(DefaultHapticNetOnnx(),
                                              kDefaultHapticNetSource)
                   : HapticNet::FromOnnxFile(path);
  if (!net.ok()) {
    std::fprintf(stderr, "bitewise-haptic-eval: %s\n",
                 net.status().ToString().c_str());
    return 1;
  }
  std::printf("model %s (%s), %d traces per class and condition, seed %lu\n",
              path.empty() ? kDefaultHapticNetSource : path.c_str(),
              (*net)->fingerprint().c_str(),
              absl::GetFlag(FLAGS_traces_per_class),
              static_cast<unsigned long>(absl::GetFlag(FLAGS_seed)));
  const HapticClassifier classifier(std::move(net).value(),
                                    HapticPipelineOptions());
  std::printf(
      "\nlog-probability columns: the smallest log-probability of each trace "
      "(its least likely class), as the median, 1st percentile and minimum "
      "over the traces\n\n| condition | accuracy | log loss | calibration "
      "error | min log p: median | 1 %% | min | rejected |\n"
      "|---|---:|---:|---:|---:|---:|---:|---:|\n");
  std::string matrices;
  const int per_class = absl::GetFlag(FLAGS_traces_per_class);
  const uint64_t seed = absl::GetFlag(FLAGS_seed);
  auto evaluate = [&](const std::string& name,
                      const std::vector<LabelledTrace>& traces) {
    std::vector<std::array<double, kHapticClasses>> probabilities;
    std::vector<int> labels;
    std::vector<double> smallest;
    int rejected = 0;
    for (const LabelledTrace& trace : traces) {
      absl::StatusOr<HapticClassification> result =
          classifier.Classify(trace.samples);
      if (!result.ok()) {
        ++rejected;
        continue;
      }
      probabilities.push_back(result->probabilities);
      labels.push_back(static_cast<int>(trace.label));
      smallest.push_back(*std::min_element(result->log_probabilities.begin(),
                                           result->log_probabilities.end()));
    }
    std::sort(smallest.begin(), smallest.end());
    auto quantile = [&](double q) {
      return smallest.empty()
                 ? 0.0
                 : smallest[static_cast<size_t>(q * (smallest.size() - 1))];
    };
    const ProbabilisticScore score = ScorePredictions(probabilities, labels);
    std::printf("| %s | %.2f%% | %.4f | %.4f | %.2f | %.2f | %.2f | %d |\n",
                name.c_str(), 100.0 * score.confusion.Accuracy(),
                score.mean_log_loss, score.expected_calibration_error,
                quantile(0.5), quantile(0.01), quantile(0.0), rejected);
    std::fflush(stdout);
    matrices += "\n" + name + "\n" + score.confusion.ToString();
  };
  for (const Condition& condition : Conditions()) {
    evaluate(condition.name,
             SimulateLabelledTraces(per_class, condition.conditions, seed));
  }
  evaluate(
      "OUT OF DISTRIBUTION: independent piecewise-linear generator (100 Hz-7 "
      "kHz, own noise, offset, lateral)",
      OutOfDistributionTraces(per_class, seed));
  if (absl::GetFlag(FLAGS_confusion)) std::printf("%s", matrices.c_str());
  return 0;
}
