#include "services/haptic/core/familiarity.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>
#include <utility>

#include "absl/status/status.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_split.h"
#include "absl/strings/strip.h"

namespace bitewise::haptic {
namespace {

constexpr int kD = kFamiliarityFeatures;
constexpr char kMagic[] = "bitewise-haptic-familiarity";
constexpr int kVersion = 1;
// Forces below this (N) are taken as this, so ratios stay finite.
constexpr double kMinForceN = 0.05;

const char* const kFeatureNames[kD] = {
    "log_peak_force", "time_to_peak", "largest_drop",  "drop_duration",
    "rise_shape",     "log_ringing",  "log_variation", "log_lateral_ratio",
    "log_lever_arm",  "end_to_peak",
};

double Rms(const std::vector<double>& values) {
  double sum = 0.0;
  for (double v : values) sum += v * v;
  return std::sqrt(sum / static_cast<double>(values.size()));
}

// Inverts the symmetric positive-definite `m` (row-major) by Gauss-Jordan
// with partial pivoting. False if it is singular.
bool Invert(std::array<double, kD * kD> m, std::array<double, kD * kD>* out) {
  std::array<double, kD * kD> inv{};
  for (int i = 0; i < kD; ++i) inv[i * kD + i] = 1.0;
  for (int col = 0; col < kD; ++col) {
    int pivot = col;
    for (int r = col + 1; r < kD; ++r) {
      if (std::abs(m[r * kD + col]) > std::abs(m[pivot * kD + col])) pivot = r;
    }
    if (!(std::abs(m[pivot * kD + col]) > 1e-300)) return false;
    if (pivot != col) {
      for (int c = 0; c < kD; ++c) {
        std::swap(m[col * kD + c], m[pivot * kD + c]);
        std::swap(inv[col * kD + c], inv[pivot * kD + c]);
      }
    }
    const double p = m[col * kD + col];
    for (int c = 0; c < kD; ++c) {
      m[col * kD + c] /= p;
      inv[col * kD + c] /= p;
    }
    for (int r = 0; r < kD; ++r) {
      if (r == col) continue;
      const double f = m[r * kD + col];
      if (f == 0.0) continue;
      for (int c = 0; c < kD; ++c) {
        m[r * kD + c] -= f * m[col * kD + c];
        inv[r * kD + c] -= f * inv[col * kD + c];
      }
    }
  }
  *out = inv;
  return true;
}

double SquaredMahalanobis(const FamiliarityClass& cls,
                          const FamiliarityVector& x) {
  FamiliarityVector d;
  for (int i = 0; i < kD; ++i) d[i] = x[i] - cls.mean[i];
  double sum = 0.0;
  for (int i = 0; i < kD; ++i) {
    double row = 0.0;
    for (int j = 0; j < kD; ++j) row += cls.precision[i * kD + j] * d[j];
    sum += d[i] * row;
  }
  return std::max(0.0, sum);
}

absl::Status ParseError(const std::string& source, int line,
                        const std::string& what) {
  return absl::InvalidArgumentError(
      absl::StrCat("familiarity file ", source, " line ", line, ": ", what));
}

// Parses `count` finite doubles from `tokens` starting at `first`.
absl::Status ParseDoubles(const std::vector<std::string>& tokens, size_t first,
                          size_t count, const std::string& source, int line,
                          double* out) {
  if (tokens.size() != first + count) {
    return ParseError(
        source, line,
        absl::StrCat("expected ", count, " numbers, got ",
                     tokens.size() < first ? 0 : tokens.size() - first));
  }
  for (size_t i = 0; i < count; ++i) {
    double v = 0.0;
    if (!absl::SimpleAtod(tokens[first + i], &v) || !std::isfinite(v)) {
      return ParseError(
          source, line,
          absl::StrCat("not a finite number: \"", tokens[first + i], "\""));
    }
    out[i] = v;
  }
  return absl::OkStatus();
}

}  // namespace

const char* FamiliarityFeatureName(int index) {
  return index >= 0 && index < kD ? kFeatureNames[index] : "unknown";
}

FamiliarityVector FamiliarityFeatures(
    const std::array<float, kHapticInputs>& window) {
  constexpr int n = kWindowPoints;
  auto at = [&](int channel, int k) -> double {
    return window[channel * n + k];
  };
  std::vector<double> force(n), lateral(n), axial(n), torque(n);
  for (int k = 0; k < n; ++k) {
    const double fx = at(0, k), fy = at(1, k), fz = at(2, k);
    lateral[k] = std::sqrt(fx * fx + fy * fy);
    axial[k] = fz;
    force[k] = std::sqrt(fx * fx + fy * fy + fz * fz);
    torque[k] = std::sqrt(at(3, k) * at(3, k) + at(4, k) * at(4, k) +
                          at(5, k) * at(5, k));
  }
  const int peak_index = static_cast<int>(
      std::max_element(force.begin(), force.end()) - force.begin());
  const double peak = std::max(force[peak_index], kMinForceN);

  // Largest drop from the running maximum, and how long it took.
  double running_max = 0.0, largest_drop = 0.0;
  int running_max_index = 0, drop_from = 0, drop_to = 0;
  for (int k = 0; k < n; ++k) {
    if (force[k] > running_max) {
      running_max = force[k];
      running_max_index = k;
    }
    const double drop =
        (running_max - force[k]) / std::max(running_max, kMinForceN);
    if (drop > largest_drop) {
      largest_drop = drop;
      drop_from = running_max_index;
      drop_to = k;
    }
  }

  double rise = 0.0;
  for (int k = 0; k <= peak_index; ++k) rise += force[k];
  rise /= static_cast<double>(peak_index + 1) * peak;

  std::vector<double> second(n - 2);
  for (int k = 1; k + 1 < n; ++k) {
    second[k - 1] = force[k + 1] - 2.0 * force[k] + force[k - 1];
  }
  double variation = 0.0;
  for (int k = 1; k < n; ++k) variation += std::abs(force[k] - force[k - 1]);

  FamiliarityVector f;
  f[0] = std::log(peak);
  f[1] = static_cast<double>(peak_index) / (n - 1);
  f[2] = largest_drop;
  f[3] = static_cast<double>(drop_to - drop_from) / (n - 1);
  f[4] = rise;
  f[5] = std::log(Rms(second) / peak + 1e-4);
  f[6] = std::log(variation / peak + 1e-3);
  f[7] = std::log(Rms(lateral) / (Rms(axial) + 1e-3) + 1e-3);
  f[8] = std::log(Rms(torque) / (Rms(force) + 1e-3) + 1e-5);
  f[9] = std::max(force[n - 1], 0.0) / peak;
  for (double& v : f) {
    if (!std::isfinite(v)) v = 0.0;
  }
  return f;
}

absl::StatusOr<FamiliarityModel> FamiliarityModel::Fit(
    absl::Span<const FamiliarityVector> features, absl::Span<const int> labels,
    absl::Span<const FamiliarityVector> calibration, double threshold,
    double shrinkage, const std::string& trained_on) {
  if (features.size() != labels.size()) {
    return absl::InvalidArgumentError(
        absl::StrCat("familiarity fit: ", features.size(), " windows but ",
                     labels.size(), " labels"));
  }
  if (calibration.empty()) {
    return absl::InvalidArgumentError(
        "familiarity fit: no calibration windows");
  }
  if (!(threshold >= 0.0 && threshold <= 1.0)) {
    return absl::InvalidArgumentError(absl::StrCat(
        "familiarity threshold must be in [0, 1], got ", threshold));
  }
  if (!(shrinkage >= 0.0 && shrinkage <= 1.0)) {
    return absl::InvalidArgumentError(absl::StrCat(
        "familiarity shrinkage must be in [0, 1], got ", shrinkage));
  }
  FamiliarityModel model;
  model.threshold_ = threshold;
  model.trained_on_ = trained_on;
  for (int c = 0; c < kHapticClasses; ++c) {
    std::vector<const FamiliarityVector*> members;
    for (size_t i = 0; i < labels.size(); ++i) {
      if (labels[i] < 0 || labels[i] >= kHapticClasses) {
        return absl::InvalidArgumentError(
            absl::StrCat("familiarity fit: label ", labels[i], " of window ", i,
                         " is not a class 0..3"));
      }
      if (labels[i] == c) members.push_back(&features[i]);
    }
    if (members.size() < 2 * static_cast<size_t>(kD)) {
      return absl::InvalidArgumentError(
          absl::StrCat("familiarity fit: class ", c, " has ", members.size(),
                       " windows, need at least ", 2 * kD));
    }
    FamiliarityClass& cls = model.classes_[c];
    for (const FamiliarityVector* x : members) {
      for (int i = 0; i < kD; ++i) cls.mean[i] += (*x)[i];
    }
    for (double& m : cls.mean) m /= static_cast<double>(members.size());
    std::array<double, kD * kD> cov{};
    for (const FamiliarityVector* x : members) {
      for (int i = 0; i < kD; ++i) {
        for (int j = 0; j < kD; ++j) {
          cov[i * kD + j] += ((*x)[i] - cls.mean[i]) * ((*x)[j] - cls.mean[j]);
        }
      }
    }
    for (int i = 0; i < kD; ++i) {
      for (int j = 0; j < kD; ++j) {
        double& v = cov[i * kD + j];
        v /= static_cast<double>(members.size() - 1);
        if (i != j) v *= 1.0 - shrinkage;
      }
      // A floor, so that a feature constant within a class (say, no drop
      // at all) does not make the covariance singular.
      cov[i * kD + i] += 1e-6;
    }
    if (!Invert(cov, &cls.precision)) {
      return absl::InvalidArgumentError(absl::StrCat(
          "familiarity fit: class ", c, "'s covariance is singular"));
    }
  }
  model.calibration_.reserve(calibration.size());
  for (const FamiliarityVector& x : calibration) {
    model.calibration_.push_back(model.Distance(x));
  }
  std::sort(model.calibration_.begin(), model.calibration_.end());
  return model;
}

std::array<double, kHapticClasses> FamiliarityModel::ClassDistances(
    const FamiliarityVector& features) const {
  std::array<double, kHapticClasses> distances{};
  for (int c = 0; c < kHapticClasses; ++c) {
    distances[c] = SquaredMahalanobis(classes_[c], features);
  }
  return distances;
}

double FamiliarityModel::Distance(const FamiliarityVector& features) const {
  const std::array<double, kHapticClasses> distances = ClassDistances(features);
  return *std::min_element(distances.begin(), distances.end());
}

FamiliarityScore FamiliarityModel::Score(
    const FamiliarityVector& features) const {
  FamiliarityScore score;
  score.class_distances = ClassDistances(features);
  score.distance = *std::min_element(score.class_distances.begin(),
                                     score.class_distances.end());
  const size_t nearer =
      static_cast<size_t>(std::lower_bound(calibration_.begin(),
                                           calibration_.end(), score.distance) -
                          calibration_.begin());
  score.familiarity = static_cast<double>(calibration_.size() - nearer) /
                      static_cast<double>(calibration_.size());
  score.unfamiliar = score.familiarity < threshold_;
  return score;
}

std::string FamiliarityModel::ToText() const {
  std::string text = absl::StrCat(kMagic, " ", kVersion, "\n");
  absl::StrAppend(&text, "trained_on ", trained_on_.empty() ? "-" : trained_on_,
                  "\n");
  absl::StrAppendFormat(&text, "threshold %.17g\n", threshold_);
  absl::StrAppend(&text, "features");
  for (int i = 0; i < kD; ++i) absl::StrAppend(&text, " ", kFeatureNames[i]);
  absl::StrAppend(&text, "\n");
  for (int c = 0; c < kHapticClasses; ++c) {
    absl::StrAppendFormat(&text, "mean %d", c);
    for (double v : classes_[c].mean) absl::StrAppendFormat(&text, " %.17g", v);
    absl::StrAppendFormat(&text, "\nprecision %d", c);
    for (double v : classes_[c].precision) {
      absl::StrAppendFormat(&text, " %.17g", v);
    }
    absl::StrAppend(&text, "\n");
  }
  absl::StrAppendFormat(&text, "calibration %d", calibration_.size());
  for (double v : calibration_) absl::StrAppendFormat(&text, " %.9g", v);
  absl::StrAppend(&text, "\n");
  return text;
}

absl::StatusOr<FamiliarityModel> FamiliarityModel::FromText(
    absl::string_view text, const std::string& source) {
  std::vector<std::string> lines = absl::StrSplit(text, '\n');
  while (!lines.empty() && lines.back().empty()) lines.pop_back();
  auto tokens_of = [&](size_t i) -> std::vector<std::string> {
    return absl::StrSplit(lines[i], ' ', absl::SkipEmpty());
  };
  // Line numbers are 1-based in messages.
  const size_t expected_lines = 4 + 2 * kHapticClasses + 1;
  if (lines.empty()) return ParseError(source, 1, "the file is empty");
  std::vector<std::string> t = tokens_of(0);
  if (t.size() != 2 || t[0] != kMagic || t[1] != absl::StrCat(kVersion)) {
    return ParseError(source, 1,
                      absl::StrCat("expected \"", kMagic, " ", kVersion,
                                   "\", got \"", lines[0], "\""));
  }
  if (lines.size() != expected_lines) {
    return ParseError(source, static_cast<int>(lines.size()),
                      absl::StrCat("expected ", expected_lines,
                                   " lines, the file has ", lines.size()));
  }
  FamiliarityModel model;
  t = tokens_of(1);
  if (t.size() < 2 || t[0] != "trained_on") {
    return ParseError(source, 2, "expected \"trained_on SOURCES\"");
  }
  model.trained_on_ = std::string(absl::StripPrefix(lines[1], "trained_on "));
  t = tokens_of(2);
  if (t.empty() || t[0] != "threshold") {
    return ParseError(source, 3, "expected \"threshold VALUE\"");
  }
  if (absl::Status s = ParseDoubles(t, 1, 1, source, 3, &model.threshold_);
      !s.ok()) {
    return s;
  }
  if (!(model.threshold_ >= 0.0 && model.threshold_ <= 1.0)) {
    return ParseError(
        source, 3,
        absl::StrCat("threshold ", model.threshold_, " is outside [0, 1]"));
  }
  t = tokens_of(3);
  if (t.size() != static_cast<size_t>(kD) + 1 || t[0] != "features") {
    return ParseError(source, 4,
                      absl::StrCat("expected \"features\" and ", kD, " names"));
  }
  for (int i = 0; i < kD; ++i) {
    if (t[i + 1] != kFeatureNames[i]) {
      return ParseError(
          source, 4,
          absl::StrCat("feature ", i, " is \"", t[i + 1],
                       "\", this build computes \"", kFeatureNames[i], "\""));
    }
  }
  for (int c = 0; c < kHapticClasses; ++c) {
    const int mean_line = 5 + 2 * c;
    t = tokens_of(mean_line - 1);
    if (t.size() < 2 || t[0] != "mean" || t[1] != absl::StrCat(c)) {
      return ParseError(source, mean_line,
                        absl::StrCat("expected \"mean ", c, " ...\""));
    }
    if (absl::Status s = ParseDoubles(t, 2, kD, source, mean_line,
                                      model.classes_[c].mean.data());
        !s.ok()) {
      return s;
    }
    t = tokens_of(mean_line);
    if (t.size() < 2 || t[0] != "precision" || t[1] != absl::StrCat(c)) {
      return ParseError(source, mean_line + 1,
                        absl::StrCat("expected \"precision ", c, " ...\""));
    }
    if (absl::Status s = ParseDoubles(t, 2, kD * kD, source, mean_line + 1,
                                      model.classes_[c].precision.data());
        !s.ok()) {
      return s;
    }
  }
  const int calibration_line = static_cast<int>(expected_lines);
  t = tokens_of(expected_lines - 1);
  int count = 0;
  if (t.size() < 2 || t[0] != "calibration" ||
      !absl::SimpleAtoi(t[1], &count) || count <= 0) {
    return ParseError(source, calibration_line,
                      "expected \"calibration N\" with N > 0 and N values");
  }
  model.calibration_.resize(count);
  if (absl::Status s = ParseDoubles(t, 2, count, source, calibration_line,
                                    model.calibration_.data());
      !s.ok()) {
    return s;
  }
  if (!std::is_sorted(model.calibration_.begin(), model.calibration_.end())) {
    return ParseError(source, calibration_line,
                      "the calibration distances are not sorted");
  }
  return model;
}

absl::StatusOr<FamiliarityModel> FamiliarityModel::FromFile(
    const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    return absl::NotFoundError(
        absl::StrCat("cannot open the familiarity file ", path));
  }
  std::ostringstream contents;
  contents << in.rdbuf();
  return FromText(contents.str(), path);
}

std::string FamiliarityPathFor(const std::string& model_path) {
  return model_path + ".familiarity";
}

double Auroc(absl::Span<const double> positives,
             absl::Span<const double> negatives) {
  if (positives.empty() || negatives.empty()) return 0.5;
  std::vector<double> neg(negatives.begin(), negatives.end());
  std::sort(neg.begin(), neg.end());
  double wins = 0.0;
  for (double p : positives) {
    const auto lo = std::lower_bound(neg.begin(), neg.end(), p);
    const auto hi = std::upper_bound(neg.begin(), neg.end(), p);
    wins += static_cast<double>(lo - neg.begin()) +
            0.5 * static_cast<double>(hi - lo);
  }
  return wins / (static_cast<double>(positives.size()) *
                 static_cast<double>(neg.size()));
}

}  // namespace bitewise::haptic
