// bitewise-haptic-eval: measures a HapticNet model the way the service runs
// it (HapticClassifier: contact detection, window, OpenCV DNN) on fresh
// simulated traces under several sensor conditions, and prints accuracy,
// log loss, calibration error and a confusion matrix for each. Flags are
// parsed here and nowhere else.
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "absl/flags/flag.h"
#include "absl/flags/parse.h"
#include "absl/flags/usage.h"
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
  out.push_back({"training mix (100 Hz-7 kHz, noise x0.5-2.5, bias +-2.5 N)",
                 TrainingConditions()});
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  absl::SetProgramUsageMessage(
      "Evaluates a HapticNet model on fresh simulated traces.");
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
      "\n| condition | accuracy | log loss | calibration error | "
      "rejected |\n|---|---:|---:|---:|---:|\n");
  std::string matrices;
  for (const Condition& condition : Conditions()) {
    const std::vector<LabelledTrace> traces =
        SimulateLabelledTraces(absl::GetFlag(FLAGS_traces_per_class),
                               condition.conditions, absl::GetFlag(FLAGS_seed));
    std::vector<std::array<double, kHapticClasses>> probabilities;
    std::vector<int> labels;
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
    }
    const ProbabilisticScore score = ScorePredictions(probabilities, labels);
    std::printf("| %s | %.2f%% | %.4f | %.4f | %d |\n", condition.name,
                100.0 * score.confusion.Accuracy(), score.mean_log_loss,
                score.expected_calibration_error, rejected);
    std::fflush(stdout);
    matrices +=
        std::string("\n") + condition.name + "\n" + score.confusion.ToString();
  }
  if (absl::GetFlag(FLAGS_confusion)) std::printf("%s", matrices.c_str());
  return 0;
}
