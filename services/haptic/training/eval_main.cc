// bitewise-haptic-eval: measures a HapticNet model the way the service runs
// it (HapticClassifier: contact detection, window, OpenCV DNN) on fresh
// traces of the simulated world under several sensor conditions, and on
// fresh traces of each independent trace story (services/sim/
// trace_stories.h), one of which the model was not trained on, and prints
// accuracy per class, log loss, calibration error, the range of the
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
#include "absl/flags/usage.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "services/common/flags_usage.h"
#include "services/haptic/core/haptic_classifier.h"
#include "services/haptic/core/haptic_net.h"
#include "services/haptic/default_model.h"
#include "services/haptic/model_loading.h"
#include "services/haptic/training/haptic_trainer.h"
#include "services/haptic/training/labelled_traces.h"

ABSL_FLAG(std::string, model, "",
          "ONNX model to evaluate. Empty: the model compiled into the "
          "binary (models/hapticnet/hapticnet.onnx).");
ABSL_FLAG(std::string, familiarity, "",
          "Familiarity model, as bitewise-haptic's flag: empty, the one "
          "beside the model (or the compiled-in one with the compiled-in "
          "model); \"none\": no score.");
ABSL_FLAG(int, traces_per_class, 500,
          "Simulated traces per class and "
          "condition.");
ABSL_FLAG(uint64_t, seed, 20261123,
          "Seed of the test traces; differs from the trainer's so every "
          "trace is new.");
ABSL_FLAG(bool, confusion, true, "Print a confusion matrix per condition.");
ABSL_FLAG(std::string, probabilities_csv, "",
          "Also write every classified trace's true label and probabilities "
          "(condition,label,p_hard,p_medium,p_soft,p_hard_skin,familiarity,"
          "distance,d_hard,d_medium,d_soft,d_hard_skin: the familiarity, its "
          "distance and the squared distance to each class's Gaussian, empty "
          "without a familiarity model) to this CSV, for calibration "
          "studies.");
ABSL_FLAG(double, force_limit_n, 0.0,
          "Also evaluate the world's nominal traces with the fork halted at "
          "this force limit, as the robot halts an action whose limit an "
          "item reaches (10: TA0/TA90, 20: TV, 25: VS); 0: not.");
ABSL_FLAG(std::string, stories, "",
          "Evaluate only these trace stories (comma-separated; empty: the "
          "world conditions and every story).");

namespace {

using namespace bitewise::haptic;  // NOLINT: a main over one namespace

struct Condition {
  const char* name;
  SimulationConditions conditions;
};

std::vector<Condition> Conditions(double force_limit_n) {
  const SimulationConditions nominal;  // 1 kHz, nominal noise, +-0.5 N
  std::vector<Condition> out = {
      {"world: nominal (1 kHz, noise x1, bias +-0.5 N)", nominal}};
  SimulationConditions c = nominal;
  if (force_limit_n > 0.0) {
    c.force_limit_n = force_limit_n;
    out.push_back({"world: nominal, the fork halted at the force limit", c});
    c = nominal;
  }
  c.min_noise_scale = c.max_noise_scale = 2.0;
  out.push_back({"world: doubled noise", c});
  c = nominal;
  c.fixed_bias_n = 2.0;
  c.random_bias_n = 0.0;
  out.push_back({"world: bias +2 N on every force channel", c});
  c.fixed_bias_n = -2.0;
  out.push_back({"world: bias -2 N on every force channel", c});
  c = nominal;
  c.min_rate_hz = c.max_rate_hz = 100.0;
  out.push_back({"world: 100 Hz", c});
  c = nominal;
  c.min_rate_hz = c.max_rate_hz = 7000.0;
  out.push_back({"world: 7 kHz", c});
  out.push_back(
      {"world: training mix (100 Hz-7 kHz, noise x0.5-3, bias +-2.5 N, "
       "augmented)",
       TrainingConditions()});
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  absl::SetProgramUsageMessage(
      "Evaluates a HapticNet model on fresh simulated traces: the world "
      "model under several sensor conditions, and each trace story.");
  bitewise::ShowOwnFlagsInHelp();
  bitewise::ParseFlagsOnly(argc, argv);
  if (!(absl::GetFlag(FLAGS_force_limit_n) >= 0.0)) {
    std::fprintf(stderr,
                 "bitewise-haptic-eval: --force_limit_n must be 0 (none) or "
                 "a force in N, not %g\n",
                 absl::GetFlag(FLAGS_force_limit_n));
    return 2;
  }
  const std::string path = absl::GetFlag(FLAGS_model);
  absl::StatusOr<std::unique_ptr<HapticNet>> net = LoadHapticNet(path);
  if (!net.ok()) {
    std::fprintf(stderr, "bitewise-haptic-eval: %s\n",
                 net.status().ToString().c_str());
    return 1;
  }
  HapticPipelineOptions pipeline;
  absl::StatusOr<double> window_s =
      ModelWindow(**net, 0.0, path.empty() ? kDefaultHapticNetSource : path);
  if (!window_s.ok()) {
    std::fprintf(stderr, "bitewise-haptic-eval: %s\n",
                 window_s.status().ToString().c_str());
    return 1;
  }
  pipeline.window.window_s = *window_s;
  std::string familiarity_described;
  absl::StatusOr<std::unique_ptr<FamiliarityModel>> familiarity =
      LoadFamiliarity(absl::GetFlag(FLAGS_familiarity), path,
                      &familiarity_described);
  if (!familiarity.ok()) {
    std::fprintf(stderr, "bitewise-haptic-eval: %s\n",
                 familiarity.status().ToString().c_str());
    return 1;
  }
  std::printf(
      "model %s (%s, window %g s), %s, %d traces per class and condition, "
      "seed %lu\n",
      path.empty() ? kDefaultHapticNetSource : path.c_str(),
      (*net)->fingerprint().c_str(), *window_s, familiarity_described.c_str(),
      absl::GetFlag(FLAGS_traces_per_class),
      static_cast<unsigned long>(absl::GetFlag(FLAGS_seed)));
  const HapticClassifier classifier(std::move(net).value(), pipeline,
                                    std::move(familiarity).value());
  std::printf(
      "\nlog-probability columns: the smallest log-probability of each trace "
      "(its least likely class), as the median, 1st percentile and minimum "
      "over the traces; familiarity columns: its median and 10th percentile "
      "over the traces and the share called unfamiliar\n\n| traces | "
      "accuracy | hard | medium | soft | hard-skin | log loss | ECE | "
      "over-confidence: hard | medium | soft | hard-skin | min log p: median "
      "| 1 %% | min | familiarity: median | 10 %% | unfamiliar | rejected |\n"
      "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
      "---:|---:|---:|---:|---:|\n");
  std::string matrices;
  const int per_class = absl::GetFlag(FLAGS_traces_per_class);
  const uint64_t seed = absl::GetFlag(FLAGS_seed);
  std::FILE* dump = nullptr;
  if (!absl::GetFlag(FLAGS_probabilities_csv).empty()) {
    dump = std::fopen(absl::GetFlag(FLAGS_probabilities_csv).c_str(), "w");
    if (dump == nullptr) {
      std::fprintf(stderr, "bitewise-haptic-eval: cannot write %s\n",
                   absl::GetFlag(FLAGS_probabilities_csv).c_str());
      return 1;
    }
    std::fprintf(dump,
                 "condition,label,p_hard,p_medium,p_soft,p_hard_skin,"
                 "familiarity,distance,d_hard,d_medium,d_soft,d_hard_skin\n");
  }
  auto evaluate = [&](const std::string& name,
                      const std::vector<LabelledTrace>& traces) {
    std::vector<std::array<double, kHapticClasses>> probabilities;
    std::vector<int> labels;
    std::vector<double> smallest;
    std::vector<double> familiarities;
    int unfamiliar = 0;
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
      if (result->has_familiarity) {
        familiarities.push_back(result->familiarity.familiarity);
        if (result->familiarity.unfamiliar) ++unfamiliar;
      }
      if (dump != nullptr) {
        const FamiliarityScore& score = result->familiarity;
        const std::string familiarity_fields =
            result->has_familiarity
                ? absl::StrCat(score.familiarity, ",", score.distance, ",",
                               absl::StrJoin(score.class_distances, ","))
                : ",,,,,";
        // Quoted when it holds a comma, so the CSV keeps its columns.
        const std::string condition = absl::StrContains(name, ',')
                                          ? absl::StrCat("\"", name, "\"")
                                          : name;
        std::fprintf(dump, "%s,%s,%.9g,%.9g,%.9g,%.9g,%s\n", condition.c_str(),
                     HapticClassName(trace.label), result->probabilities[0],
                     result->probabilities[1], result->probabilities[2],
                     result->probabilities[3], familiarity_fields.c_str());
      }
      smallest.push_back(*std::min_element(result->log_probabilities.begin(),
                                           result->log_probabilities.end()));
    }
    auto quantile = [](std::vector<double>& values, double q) {
      std::sort(values.begin(), values.end());
      return values.empty()
                 ? 0.0
                 : values[static_cast<size_t>(q * (values.size() - 1))];
    };
    const ProbabilisticScore score = ScorePredictions(probabilities, labels);
    std::printf("| %s | %.2f%%", name.c_str(),
                100.0 * score.confusion.Accuracy());
    for (int k = 0; k < kHapticClasses; ++k) {
      std::printf(" | %.1f%%", 100.0 * score.confusion.Recall(k));
    }
    std::printf(" | %.4f | %.4f", score.mean_log_loss,
                score.expected_calibration_error);
    for (int k = 0; k < kHapticClasses; ++k) {
      std::printf(" | %+.3f", score.overconfidence[k]);
    }
    std::printf(" | %.2f | %.2f | %.2f", quantile(smallest, 0.5),
                quantile(smallest, 0.01), quantile(smallest, 0.0));
    if (familiarities.empty()) {
      std::printf(" | - | - | -");
    } else {
      std::printf(" | %.3f | %.3f | %.1f%%", quantile(familiarities, 0.5),
                  quantile(familiarities, 0.1),
                  100.0 * unfamiliar / familiarities.size());
    }
    std::printf(" | %d |\n", rejected);
    std::fflush(stdout);
    matrices += "\n" + name + "\n" + score.confusion.ToString();
  };
  std::vector<TraceStory> stories = {
      TraceStory::kPiecewise, TraceStory::kMechanics,   TraceStory::kCompliant,
      TraceStory::kPuncture,  TraceStory::kPoroelastic, TraceStory::kLattice};
  if (!absl::GetFlag(FLAGS_stories).empty()) {
    absl::StatusOr<std::vector<TraceStory>> parsed =
        ParseTraceStories(absl::GetFlag(FLAGS_stories));
    if (!parsed.ok()) {
      std::fprintf(stderr, "bitewise-haptic-eval: %s\n",
                   parsed.status().ToString().c_str());
      return 2;
    }
    stories = *parsed;
  } else {
    for (const Condition& condition :
         Conditions(absl::GetFlag(FLAGS_force_limit_n))) {
      evaluate(condition.name,
               SimulateLabelledTraces(per_class, condition.conditions, seed));
    }
  }
  for (TraceStory story : stories) {
    evaluate(absl::StrCat("story: ", TraceStoryName(story)),
             StoryTraces(story, per_class, seed));
  }
  if (dump != nullptr) std::fclose(dump);
  if (absl::GetFlag(FLAGS_confusion)) std::printf("%s", matrices.c_str());
  return 0;
}
