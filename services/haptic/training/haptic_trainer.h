// HapticNet's trainer: mini-batch Adam on the cross-entropy of the
// 384-128-ReLU-128-ReLU-4 MLP (optionally behind a convolutional front end),
// with per-channel normalisation fitted on the
// training windows, early stopping on a validation split, and temperature
// scaling fitted on that split so the probabilities are calibrated, not just
// the argmax right. Label smoothing keeps implausible classes away from
// zero probability. Deterministic: the same data, options and seed give
// bit-identical weights on any x86-64 machine, because every sum runs in
// a fixed order (no BLAS-style blocking, no FMA contraction).
#ifndef BITEWISE_SERVICES_HAPTIC_TRAINING_HAPTIC_TRAINER_H_
#define BITEWISE_SERVICES_HAPTIC_TRAINING_HAPTIC_TRAINER_H_

#include <algorithm>
#include <array>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "services/haptic/core/haptic_window.h"
#include "services/haptic/training/haptic_net_weights.h"

namespace bitewise::haptic {

// Network inputs (ExtractHapticFeatures windows) with class labels 0..3.
struct LabelledWindows {
  std::vector<std::array<float, kHapticInputs>> inputs;
  std::vector<int> labels;
  // Per window, its trace's LabelledTrace::source (WindowsFromTraces).
  std::vector<int> sources;
};

struct TrainerOptions {
  uint64_t seed = 1;            // initial weights and batch order
  int batch_size = 64;          // windows per Adam step
  double learning_rate = 1e-3;  // Adam step size
  double weight_decay = 1e-4;   // L2 on the weights (not biases)
  int max_epochs = 60;          // hard cap on passes over the data
  int patience = 8;             // stop after this many epochs without a better
                     // validation loss; the best epoch's weights are kept
  // Label smoothing: the training targets are (1 - label_smoothing) on the
  // true class plus label_smoothing / 4 on every class, so the network never
  // learns to push an implausible class to a near-zero probability (with
  // 0.04 the target for the other classes is 0.01, log -4.6).
  double label_smoothing = 0.04;
  // Fit a softmax temperature on the validation split (grid search on the
  // validation cross-entropy) and fold it into the last layer.
  bool calibrate_temperature = true;
  // Bounds of that temperature. The floor of 1 means the fit may soften the
  // smoothed model but never sharpen it back towards near-zero
  // probabilities: in distribution it would, since the validation split
  // rewards confidence, but traces from other sources do not.
  double min_temperature = 1.0;
  double max_temperature = 5.0;
  // Output channels of a convolutional front end before the MLP
  // (HapticNetWeights::conv), e.g. {16, 32}; empty (the default) trains the
  // plain MLP.
  std::vector<int> conv_channels;
};

struct EpochLog {
  int epoch = 0;
  double train_loss = 0.0;       // mean cross-entropy over the epoch, against
                                 // the smoothed targets
  double validation_loss = 0.0;  // mean cross-entropy (nats)
  double validation_accuracy = 0.0;
};

struct TrainingResult {
  // Rounded to float precision (RoundToFloat), ready to export.
  HapticNetWeights weights;
  std::vector<EpochLog> epochs;
  int best_epoch = 0;
  double temperature = 1.0;  // already folded into w3 and b3
};

// Trains on `train`, early-stops on `validation`. `on_epoch`, if set, sees
// each epoch's log as it finishes. Errors: INVALID_ARGUMENT for empty sets,
// labels outside 0..3, mismatched sizes or bad options.
absl::StatusOr<TrainingResult> TrainHapticNet(
    const LabelledWindows& train, const LabelledWindows& validation,
    const TrainerOptions& options,
    const std::function<void(const EpochLog&)>& on_epoch = nullptr);

// The mean label-smoothed cross-entropy of `weights` over `data` (as one
// batch) and its gradient with respect to every parameter: what each of the
// trainer's Adam steps follows. Exposed so that tests can check the
// back-propagation against finite differences of the reference pass.
struct LossGradient {
  double loss = 0.0;
  // Shaped like the weights; its input_mean and input_stddev are unused.
  HapticNetWeights gradient;
};
absl::StatusOr<LossGradient> SmoothedLossGradient(
    const HapticNetWeights& weights, const LabelledWindows& data,
    double label_smoothing);

// Counts of (true class, predicted class).
struct ConfusionMatrix {
  std::array<std::array<int, kHapticClasses>, kHapticClasses> counts{};
  int Total() const;
  double Accuracy() const;
  // Share of `true_class`'s windows predicted as it (0 if there are none).
  double Recall(int true_class) const;
  // Rows true class, columns predicted, with per-class recall.
  std::string ToString() const;
};

// Predicted class probabilities for evaluation of the reference pass.
struct ProbabilisticScore {
  ConfusionMatrix confusion;
  double mean_log_loss = 0.0;  // nats
  // Expected calibration error of the top class over 10 equal-width bins.
  double expected_calibration_error = 0.0;
  // Per true class: the mean top probability minus the accuracy over that
  // class's traces (> 0: more sure than right).
  std::array<double, kHapticClasses> overconfidence{};
  double MaxOverconfidence() const {
    return *std::max_element(overconfidence.begin(), overconfidence.end());
  }
};

// Scores predictions `probabilities[i]` against `labels[i]`.
ProbabilisticScore ScorePredictions(
    const std::vector<std::array<double, kHapticClasses>>& probabilities,
    const std::vector<int>& labels);

}  // namespace bitewise::haptic

#endif  // BITEWISE_SERVICES_HAPTIC_TRAINING_HAPTIC_TRAINER_H_
