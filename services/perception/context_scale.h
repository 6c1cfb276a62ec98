// Context scale files: E||c||^2 of a featurizer's contexts on the simulated
// world's seen foods, shipped beside a model file as "<model>.stats", so the
// PerceptionService can report it and new users' context ridge can follow
// the feature scale (lambda_c = rho_c * E||c||^2; docs/algorithms.md).
//
// Format: '#' comment lines, "version 1" and "mean_squared_norm <x > 0>".
// Written by bitewise-featurizer-stats; no gRPC here.
#ifndef BITEWISE_SERVICES_PERCEPTION_CONTEXT_SCALE_H_
#define BITEWISE_SERVICES_PERCEPTION_CONTEXT_SCALE_H_

#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"

namespace bitewise::perception {

// One entry of a statistics file (this format and the default featurizer's
// statistics): its 1-based line number, the stripped line, and its
// space-separated fields. Blank lines and '#' comments are not entries.
struct StatsLine {
  int number = 0;
  absl::string_view text;
  std::vector<absl::string_view> fields;
};
std::vector<StatsLine> StatsLines(absl::string_view text);

// The mean squared norm in `text`. INVALID_ARGUMENT naming the line when an
// entry is unknown or malformed, or when the version or the norm is missing.
absl::StatusOr<double> ParseContextScale(const std::string& text);

// The file beside a model: "<model_path>.stats".
std::string ContextScalePathFor(const std::string& model_path);

// Reads and parses `path`. NOT_FOUND when it does not exist;
// INVALID_ARGUMENT naming the file when it is malformed.
absl::StatusOr<double> ReadContextScaleFile(const std::string& path);

// The file's text for `mean_squared_norm`, after `comment` (each line of it
// written as a '#' comment).
std::string FormatContextScale(double mean_squared_norm,
                               const std::string& comment);

}  // namespace bitewise::perception

#endif  // BITEWISE_SERVICES_PERCEPTION_CONTEXT_SCALE_H_
