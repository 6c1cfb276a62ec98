#include "services/perception/context_scale.h"

#include <fstream>
#include <sstream>
#include <vector>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_split.h"
#include "absl/strings/strip.h"

namespace bitewise::perception {

std::vector<StatsLine> StatsLines(absl::string_view text) {
  std::vector<StatsLine> lines;
  int number = 0;
  for (absl::string_view line : absl::StrSplit(text, '\n')) {
    ++number;
    line = absl::StripAsciiWhitespace(line);
    if (line.empty() || line.front() == '#') continue;
    lines.push_back(
        {number, line, absl::StrSplit(line, ' ', absl::SkipEmpty())});
  }
  return lines;
}

absl::StatusOr<double> ParseContextScale(const std::string& text) {
  int version = 0;
  double norm = 0.0;
  for (const StatsLine& line : StatsLines(text)) {
    const std::vector<absl::string_view>& fields = line.fields;
    const bool ok =
        fields.size() == 2 &&
        ((fields[0] == "version" && absl::SimpleAtoi(fields[1], &version) &&
          version >= 1) ||
         (fields[0] == "mean_squared_norm" &&
          absl::SimpleAtod(fields[1], &norm) && norm > 0.0 && norm < 1e300));
    if (!ok) {
      return absl::InvalidArgumentError(absl::StrCat(
          "context scale line ", line.number,
          ": expected \"version <n >= 1>\" or \"mean_squared_norm <x > 0>\", "
          "got \"",
          line.text, "\""));
    }
  }
  if (version < 1 || norm <= 0.0) {
    return absl::InvalidArgumentError(
        "context scale: needs a version line and a mean_squared_norm line");
  }
  return norm;
}

std::string ContextScalePathFor(const std::string& model_path) {
  return model_path + ".stats";
}

absl::StatusOr<double> ReadContextScaleFile(const std::string& path) {
  std::ifstream in(path);
  if (!in) {
    return absl::NotFoundError(
        absl::StrCat("context scale file \"", path, "\" does not exist"));
  }
  std::stringstream text;
  text << in.rdbuf();
  absl::StatusOr<double> norm = ParseContextScale(text.str());
  if (!norm.ok()) {
    return absl::InvalidArgumentError(
        absl::StrCat("\"", path, "\": ", norm.status().message()));
  }
  return norm;
}

std::string FormatContextScale(double mean_squared_norm,
                               const std::string& comment) {
  std::string out;
  for (absl::string_view line : absl::StrSplit(comment, '\n')) {
    absl::StrAppend(&out, "# ", line, "\n");
  }
  absl::StrAppend(
      &out, "version 1\n",
      absl::StrFormat("mean_squared_norm %.6g\n", mean_squared_norm));
  return out;
}

}  // namespace bitewise::perception
