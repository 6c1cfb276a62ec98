// Minimal CSV output for the experiment programs: a header and rows of
// numbers, which gnuplot and spreadsheets read directly.
#ifndef BITEWISE_EXPERIMENTS_CSV_WRITER_H_
#define BITEWISE_EXPERIMENTS_CSV_WRITER_H_

#include <string>
#include <vector>

#include "absl/status/status.h"

namespace bitewise::experiments {

// Writes `columns` (all the same length) under `header` to `path`,
// replacing the file. INTERNAL naming the path if it cannot be written.
absl::Status WriteCsvColumns(const std::string& path,
                             const std::vector<std::string>& header,
                             const std::vector<std::vector<double>>& columns);

}  // namespace bitewise::experiments

#endif  // BITEWISE_EXPERIMENTS_CSV_WRITER_H_
