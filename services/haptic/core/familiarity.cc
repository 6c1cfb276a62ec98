#include "services/haptic/core/familiarity.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <fstream>
#include <limits>
#include <map>
#include <set>
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
// Version 1: one Gaussian per class, fitted on every source; version 2: any
// number, each with its class and source.
constexpr int kVersion = 1;
constexpr int kComponentsVersion = 2;
// More Gaussians than any file the trainer writes (4 classes x a few
// sources), so a corrupt count cannot make the parser allocate without end.
constexpr int kMaxComponents = 4096;
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

double SquaredMahalanobis(const FamiliarityComponent& cls,
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

// Whether the row-major `m` is symmetric (to a relative 1e-6: it was
// written as the inverse of a covariance) and positive definite (its
// Cholesky factor exists). A precision matrix that is not gives distances
// that are 0 or negative, and every trace would read as familiar.
bool IsSymmetricPositiveDefinite(const std::array<double, kD * kD>& m) {
  for (int i = 0; i < kD; ++i) {
    for (int j = 0; j < i; ++j) {
      const double a = m[i * kD + j], b = m[j * kD + i];
      if (std::abs(a - b) >
          1e-6 * std::max({std::abs(a), std::abs(b), std::abs(m[i * kD + i]),
                           std::abs(m[j * kD + j])})) {
        return false;
      }
    }
  }
  std::array<double, kD * kD> l{};
  for (int j = 0; j < kD; ++j) {
    double diagonal = m[j * kD + j];
    for (int k = 0; k < j; ++k) diagonal -= l[j * kD + k] * l[j * kD + k];
    if (!(diagonal > 0.0)) return false;
    l[j * kD + j] = std::sqrt(diagonal);
    for (int i = j + 1; i < kD; ++i) {
      double sum = m[i * kD + j];
      for (int k = 0; k < j; ++k) sum -= l[i * kD + k] * l[j * kD + k];
      l[i * kD + j] = sum / l[j * kD + j];
    }
  }
  return true;
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

namespace {

// Checks what Fit and FitPerSource share.
absl::Status CheckFitInput(absl::Span<const FamiliarityVector> features,
                           absl::Span<const int> labels,
                           absl::Span<const FamiliarityVector> calibration,
                           double threshold, double shrinkage) {
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
  for (size_t i = 0; i < labels.size(); ++i) {
    if (labels[i] < 0 || labels[i] >= kHapticClasses) {
      return absl::InvalidArgumentError(
          absl::StrCat("familiarity fit: label ", labels[i], " of window ", i,
                       " is not a class 0..3"));
    }
  }
  return absl::OkStatus();
}

// One Gaussian on `members` (at least 2 * kD), its covariance shrunk by
// `shrinkage` towards its diagonal.
absl::StatusOr<FamiliarityComponent> FitGaussian(
    const std::vector<const FamiliarityVector*>& members, double shrinkage,
    int label, const std::string& source) {
  FamiliarityComponent g;
  g.label = label;
  g.source = source;
  for (const FamiliarityVector* x : members) {
    for (int i = 0; i < kD; ++i) g.mean[i] += (*x)[i];
  }
  for (double& m : g.mean) m /= static_cast<double>(members.size());
  std::array<double, kD * kD> cov{};
  for (const FamiliarityVector* x : members) {
    for (int i = 0; i < kD; ++i) {
      for (int j = 0; j < kD; ++j) {
        cov[i * kD + j] += ((*x)[i] - g.mean[i]) * ((*x)[j] - g.mean[j]);
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
  if (!Invert(cov, &g.precision)) {
    return absl::InvalidArgumentError(absl::StrCat(
        "familiarity fit: class ", label,
        source.empty() ? std::string() : absl::StrCat(" of ", source),
        "'s covariance is singular"));
  }
  return g;
}

absl::Status TooFew(int label, size_t count, size_t distinct) {
  return absl::InvalidArgumentError(absl::StrCat(
      "familiarity fit: class ", label, " has ", count, " windows, ", distinct,
      " of them distinct, need at least ", 2 * kD, " distinct"));
}

}  // namespace

absl::StatusOr<FamiliarityModel> FamiliarityModel::Fit(
    absl::Span<const FamiliarityVector> features, absl::Span<const int> labels,
    absl::Span<const FamiliarityVector> calibration, double threshold,
    double shrinkage, const std::string& trained_on) {
  // One source, "", for every window: one Gaussian per class.
  return FitPerSource(features, labels, {}, calibration, threshold, shrinkage,
                      trained_on);
}

absl::StatusOr<FamiliarityModel> FamiliarityModel::FitPerSource(
    absl::Span<const FamiliarityVector> features, absl::Span<const int> labels,
    absl::Span<const std::string> sources,
    absl::Span<const FamiliarityVector> calibration, double threshold,
    double shrinkage, const std::string& trained_on) {
  if (absl::Status s =
          CheckFitInput(features, labels, calibration, threshold, shrinkage);
      !s.ok()) {
    return s;
  }
  // Empty: every window's source is "" (Fit).
  if (!sources.empty() && sources.size() != features.size()) {
    return absl::InvalidArgumentError(
        absl::StrCat("familiarity fit: ", features.size(), " windows but ",
                     sources.size(), " sources"));
  }
  for (size_t i = 0; i < sources.size(); ++i) {
    const bool blank = std::any_of(
        sources[i].begin(), sources[i].end(),
        [](char ch) { return std::isspace(static_cast<unsigned char>(ch)); });
    if (sources[i].empty() || blank || sources[i] == "pooled") {
      return absl::InvalidArgumentError(absl::StrCat(
          "familiarity fit: source \"", sources[i], "\" of window ", i,
          " is empty, has white space or is the pool's name \"pooled\""));
    }
  }
  FamiliarityModel model;
  model.threshold_ = threshold;
  model.trained_on_ = trained_on;
  for (int c = 0; c < kHapticClasses; ++c) {
    // Sources in name order, so the file reads the same for any order of
    // the windows.
    std::map<std::string, std::vector<const FamiliarityVector*>> by_source;
    size_t count = 0;
    for (size_t i = 0; i < labels.size(); ++i) {
      if (labels[i] != c) continue;
      ++count;
      by_source[sources.empty() ? std::string() : sources[i]].push_back(
          &features[i]);
    }
    // Distinct windows: a trace the trainer repeats (--traces_repeat) adds
    // weight, not information, so it does not make a group big enough.
    auto distinct = [](const std::vector<const FamiliarityVector*>& group) {
      std::set<FamiliarityVector> seen;
      for (const FamiliarityVector* x : group) seen.insert(*x);
      return seen.size();
    };
    std::vector<const FamiliarityVector*> pooled;
    const size_t before = model.components_.size();
    for (const auto& [source, members] : by_source) {
      if (distinct(members) < 2 * static_cast<size_t>(kD)) {
        pooled.insert(pooled.end(), members.begin(), members.end());
        continue;
      }
      absl::StatusOr<FamiliarityComponent> g =
          FitGaussian(members, shrinkage, c, source);
      if (!g.ok()) return g.status();
      model.components_.push_back(*std::move(g));
    }
    if (distinct(pooled) >= 2 * static_cast<size_t>(kD)) {
      absl::StatusOr<FamiliarityComponent> g =
          FitGaussian(pooled, shrinkage, c, "pooled");
      if (!g.ok()) return g.status();
      model.components_.push_back(*std::move(g));
    } else {
      model.left_out_ += static_cast<int>(pooled.size());
    }
    if (model.components_.size() == before) {
      std::vector<const FamiliarityVector*> all;
      for (const auto& [source, members] : by_source) {
        all.insert(all.end(), members.begin(), members.end());
      }
      return TooFew(c, count, distinct(all));
    }
  }
  model.Calibrate(calibration);
  return model;
}

void FamiliarityModel::Calibrate(
    absl::Span<const FamiliarityVector> calibration) {
  calibration_.clear();
  calibration_.reserve(calibration.size());
  for (const FamiliarityVector& x : calibration) {
    calibration_.push_back(Distance(x));
  }
  std::sort(calibration_.begin(), calibration_.end());
}

std::array<double, kHapticClasses> FamiliarityModel::ClassDistances(
    const FamiliarityVector& features) const {
  std::array<double, kHapticClasses> distances;
  distances.fill(std::numeric_limits<double>::infinity());
  for (const FamiliarityComponent& g : components_) {
    distances[g.label] =
        std::min(distances[g.label], SquaredMahalanobis(g, features));
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

bool FamiliarityModel::OnePerClass() const {
  if (components_.size() != kHapticClasses) return false;
  for (int c = 0; c < kHapticClasses; ++c) {
    if (components_[c].label != c || !components_[c].source.empty()) {
      return false;
    }
  }
  return true;
}

std::string FamiliarityModel::ToText() const {
  const bool v1 = OnePerClass();
  std::string text =
      absl::StrCat(kMagic, " ", v1 ? kVersion : kComponentsVersion, "\n");
  absl::StrAppend(&text, "trained_on ", trained_on_.empty() ? "-" : trained_on_,
                  "\n");
  absl::StrAppendFormat(&text, "threshold %.17g\n", threshold_);
  absl::StrAppend(&text, "features");
  for (int i = 0; i < kD; ++i) absl::StrAppend(&text, " ", kFeatureNames[i]);
  absl::StrAppend(&text, "\n");
  if (!v1) absl::StrAppend(&text, "components ", components_.size(), "\n");
  for (const FamiliarityComponent& g : components_) {
    const std::string head =
        v1 ? absl::StrCat(g.label) : absl::StrCat(g.label, " ", g.source);
    absl::StrAppend(&text, "mean ", head);
    for (double v : g.mean) absl::StrAppendFormat(&text, " %.17g", v);
    absl::StrAppend(&text, "\nprecision ", head);
    for (double v : g.precision) absl::StrAppendFormat(&text, " %.17g", v);
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
  if (lines.empty()) return ParseError(source, 1, "the file is empty");
  std::vector<std::string> t = tokens_of(0);
  int version = 0;
  if (t.size() != 2 || t[0] != kMagic || !absl::SimpleAtoi(t[1], &version) ||
      (version != kVersion && version != kComponentsVersion)) {
    return ParseError(
        source, 1,
        absl::StrCat("expected \"", kMagic, " ", kVersion, "\" or \"", kMagic,
                     " ", kComponentsVersion, "\", got \"", lines[0], "\""));
  }
  // Version 1 has one Gaussian per class and no "components" line.
  int components = kHapticClasses;
  int first_component_line = 5;  // 1-based
  if (version == kComponentsVersion) {
    t = lines.size() > 4 ? tokens_of(4) : std::vector<std::string>();
    if (t.size() != 2 || t[0] != "components" ||
        !absl::SimpleAtoi(t[1], &components) || components < kHapticClasses ||
        components > kMaxComponents) {
      return ParseError(source, 5,
                        absl::StrCat("expected \"components N\" with N from ",
                                     kHapticClasses, " to ", kMaxComponents));
    }
    first_component_line = 6;
  }
  const size_t expected_lines =
      static_cast<size_t>(first_component_line - 1 + 2 * components + 1);
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
  std::array<bool, kHapticClasses> seen{};
  for (int k = 0; k < components; ++k) {
    const int mean_line = first_component_line + 2 * k;
    FamiliarityComponent g;
    // Version 1: "mean C", in class order; version 2: "mean C SOURCE".
    const size_t head = version == kVersion ? 2 : 3;
    const std::string want = version == kVersion
                                 ? absl::StrCat("\"mean ", k, " ...\"")
                                 : std::string("\"mean CLASS SOURCE ...\"");
    t = tokens_of(mean_line - 1);
    if (t.size() < head || t[0] != "mean" ||
        !absl::SimpleAtoi(t[1], &g.label) || g.label < 0 ||
        g.label >= kHapticClasses || (version == kVersion && g.label != k)) {
      return ParseError(
          source, mean_line,
          absl::StrCat("expected ", want, " with a class from 0 to 3"));
    }
    if (version == kComponentsVersion) g.source = t[2];
    if (absl::Status s =
            ParseDoubles(t, head, kD, source, mean_line, g.mean.data());
        !s.ok()) {
      return s;
    }
    t = tokens_of(mean_line);
    if (t.size() < head || t[0] != "precision" ||
        t[1] != absl::StrCat(g.label) ||
        (version == kComponentsVersion && t[2] != g.source)) {
      return ParseError(
          source, mean_line + 1,
          absl::StrCat("expected \"precision ", g.label,
                       version == kVersion ? "" : absl::StrCat(" ", g.source),
                       " ...\", the class and source of the line before"));
    }
    if (absl::Status s = ParseDoubles(t, head, kD * kD, source, mean_line + 1,
                                      g.precision.data());
        !s.ok()) {
      return s;
    }
    if (!IsSymmetricPositiveDefinite(g.precision)) {
      return ParseError(
          source, mean_line + 1,
          absl::StrCat(
              "the precision matrix of class ", g.label,
              g.source.empty() ? "" : absl::StrCat(" (", g.source, ")"),
              " is not symmetric positive definite, so distances "
              "from it would mean nothing"));
    }
    seen[g.label] = true;
    model.components_.push_back(std::move(g));
  }
  for (int c = 0; c < kHapticClasses; ++c) {
    if (!seen[c]) {
      return ParseError(source, first_component_line,
                        absl::StrCat("no Gaussian of class ", c));
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
  if (t.size() != 2 + static_cast<size_t>(count)) {
    return ParseError(
        source, calibration_line,
        absl::StrCat("expected ", count, " numbers, got ", t.size() - 2));
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
