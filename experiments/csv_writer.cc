#include "experiments/csv_writer.h"

#include <cstdio>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"

namespace bitewise::experiments {

absl::Status WriteCsvColumns(const std::string& path,
                             const std::vector<std::string>& header,
                             const std::vector<std::vector<double>>& columns) {
  if (header.size() != columns.size()) {
    return absl::InvalidArgumentError("CSV header and columns differ in size");
  }
  std::FILE* f = std::fopen(path.c_str(), "w");
  if (f == nullptr) {
    return absl::InternalError(absl::StrCat("cannot write ", path));
  }
  std::fprintf(f, "%s\n", absl::StrJoin(header, ",").c_str());
  const size_t rows = columns.empty() ? 0 : columns.front().size();
  for (size_t r = 0; r < rows; ++r) {
    for (size_t c = 0; c < columns.size(); ++c) {
      // %.6g keeps the files small and is far below any plotted resolution.
      std::fprintf(f, c == 0 ? "%.6g" : ",%.6g", columns[c][r]);
    }
    std::fprintf(f, "\n");
  }
  if (std::fclose(f) != 0) {
    return absl::InternalError(absl::StrCat("error writing ", path));
  }
  return absl::OkStatus();
}

}  // namespace bitewise::experiments
