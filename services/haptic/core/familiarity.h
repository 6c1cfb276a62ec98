// How familiar a force/torque trace is to the stories HapticNet was trained
// on, computed from the trace itself (no change to the ONNX graph): a few
// physical summaries of HapticNet's input window (peak force, when it peaks,
// the largest drop and how fast it happens, the shape of the rise, ringing,
// lateral and torque ratios) and Gaussian densities over them (one per
// class, or one per class and training story), fitted by the trainer on its
// training windows and shipped beside the model as "<model>.familiarity". The
// familiarity of a window is the share of the trainer's validation windows that
// lie at least as far from every class as it does: about uniform on [0, 1] for
// traces like the training ones, near 0 for traces unlike any of them. Below
// the file's threshold the trace is called unfamiliar (docs/haptic.md,
// "Familiarity").
#ifndef BITEWISE_SERVICES_HAPTIC_CORE_FAMILIARITY_H_
#define BITEWISE_SERVICES_HAPTIC_CORE_FAMILIARITY_H_

#include <array>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "absl/types/span.h"
#include "services/haptic/core/haptic_window.h"
#include "services/haptic/core/wrench_trace.h"

namespace bitewise::haptic {

// The summaries, in this order (docs/haptic.md lists their definitions).
inline constexpr int kFamiliarityFeatures = 10;
const char* FamiliarityFeatureName(int index);

using FamiliarityVector = std::array<double, kFamiliarityFeatures>;

// The summaries of one HapticNet input window (tared, channel-major, as
// ExtractWindow makes it). Always finite.
FamiliarityVector FamiliarityFeatures(
    const std::array<float, kHapticInputs>& window);

// One Gaussian of the density: the class it belongs to, the source its
// windows came from (a training story, "recordings", "pooled", or "" when it
// was fitted on every source), mean and precision (inverse covariance),
// row-major.
struct FamiliarityComponent {
  int label = 0;
  std::string source;
  FamiliarityVector mean{};
  std::array<double, kFamiliarityFeatures * kFamiliarityFeatures> precision{};
};

struct FamiliarityScore {
  // Smallest squared Mahalanobis distance to a Gaussian (of
  // class_distances).
  double distance = 0.0;
  // Share of the calibration windows at least that far out, in [0, 1].
  double familiarity = 0.0;
  // familiarity < the model's threshold.
  bool unfamiliar = false;
  // Smallest squared Mahalanobis distance to each class's Gaussians, in
  // HapticClass order (what the summaries alone say the trace is: a second
  // opinion beside the network's).
  std::array<double, kHapticClasses> class_distances{};
};

// The fitted density, its calibration and threshold. Immutable, so
// thread-safe.
class FamiliarityModel {
 public:
  // Fits one Gaussian per class on `features[i]` labelled `labels[i]`
  // (0..3), each covariance shrunk by `shrinkage` towards its diagonal, and
  // calibrates on `calibration` (windows of the same sources, not fitted
  // on). `threshold` is the familiarity below which a trace is unfamiliar;
  // `trained_on` names the sources (recorded in the file). INVALID_ARGUMENT
  // when a class has fewer than 2 * kFamiliarityFeatures distinct windows, the
  // calibration set is empty, a label is out of range, or a parameter is
  // outside its range.
  static absl::StatusOr<FamiliarityModel> Fit(
      absl::Span<const FamiliarityVector> features,
      absl::Span<const int> labels,
      absl::Span<const FamiliarityVector> calibration, double threshold,
      double shrinkage, const std::string& trained_on);

  // As Fit, with one Gaussian per class and source: `sources[i]` names
  // window i's source (a training story, "recordings"). A source with fewer
  // than 2 * kFamiliarityFeatures distinct windows of a class (a repeated
  // window counts once) adds them to one pooled Gaussian of that class
  // ("pooled"); windows in a pool still smaller than that are left out of
  // the fit (left_out() counts them). INVALID_ARGUMENT
  // as Fit, when a class has no Gaussian at all, when `sources` is not one
  // per window, or when a source name is empty, contains white space or is
  // "pooled". An empty `sources` is Fit. (A window the trainer alters after
  // repeating it, with --augment for example, counts as distinct.)
  static absl::StatusOr<FamiliarityModel> FitPerSource(
      absl::Span<const FamiliarityVector> features,
      absl::Span<const int> labels, absl::Span<const std::string> sources,
      absl::Span<const FamiliarityVector> calibration, double threshold,
      double shrinkage, const std::string& trained_on);

  // Parses the text written by ToText. `source` names the file in errors:
  // INVALID_ARGUMENT naming it and the line for anything malformed.
  static absl::StatusOr<FamiliarityModel> FromText(absl::string_view text,
                                                   const std::string& source);
  // Reads and parses `path`; NOT_FOUND naming it when it does not exist.
  static absl::StatusOr<FamiliarityModel> FromFile(const std::string& path);

  // The file's text: "bitewise-haptic-familiarity 1" and one field a line
  // for one Gaussian per class fitted on every source, version 2 (with a
  // "components N" line, and each Gaussian's class and source) otherwise.
  // FromText reads both.
  std::string ToText() const;

  // Smallest squared Mahalanobis distance to each class's Gaussians;
  // Distance is the smallest of all.
  std::array<double, kHapticClasses> ClassDistances(
      const FamiliarityVector& features) const;
  double Distance(const FamiliarityVector& features) const;
  FamiliarityScore Score(const FamiliarityVector& features) const;

  double threshold() const { return threshold_; }
  const std::string& trained_on() const { return trained_on_; }
  const std::vector<FamiliarityComponent>& components() const {
    return components_;
  }
  // Windows the fit left out (FitPerSource's pools too small to fit).
  int left_out() const { return left_out_; }

 private:
  FamiliarityModel() = default;

  // One Gaussian per class, in class order, fitted on every source (the
  // version 1 file).
  bool OnePerClass() const;
  // Sorts the calibration windows' distances into calibration_.
  void Calibrate(absl::Span<const FamiliarityVector> calibration);

  // At least one per class, in class order; within a class in source
  // name order ("pooled" after the sources it pools).
  std::vector<FamiliarityComponent> components_;
  int left_out_ = 0;
  // Sorted squared distances of the calibration windows.
  std::vector<double> calibration_;
  double threshold_ = 0.05;
  std::string trained_on_;
};

// The file beside a model: "<model_path>.familiarity".
std::string FamiliarityPathFor(const std::string& model_path);

// Area under the ROC curve of `scores` separating `positives` (should score
// higher) from `negatives`; ties count half. 0.5 when either is empty.
double Auroc(absl::Span<const double> positives,
             absl::Span<const double> negatives);

}  // namespace bitewise::haptic

#endif  // BITEWISE_SERVICES_HAPTIC_CORE_FAMILIARITY_H_
