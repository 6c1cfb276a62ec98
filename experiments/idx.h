// Reading and writing IDX files, the format of the MNIST and Fashion-MNIST
// distributions (big-endian int32 magic and dimensions, then unsigned bytes).
// Only the two shapes those datasets use are supported: 3-D ubyte images
// (count x rows x cols) and 1-D ubyte labels. Files must be uncompressed
// (gunzip the .gz distributions first).
#ifndef BITEWISE_EXPERIMENTS_IDX_H_
#define BITEWISE_EXPERIMENTS_IDX_H_

#include <cstdint>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"

namespace bitewise::experiments {

struct IdxImages {
  int count = 0;
  int rows = 0;
  int cols = 0;
  std::vector<uint8_t> pixels;  // count * rows * cols, row-major per image
};

// NOT_FOUND if the file cannot be opened; DATA_LOSS naming the path for a
// wrong magic number, impossible dimensions or a truncated file.
absl::StatusOr<IdxImages> ReadIdxImages(const std::string& path);
absl::StatusOr<std::vector<uint8_t>> ReadIdxLabels(const std::string& path);

absl::Status WriteIdxImages(const std::string& path, const IdxImages& images);
absl::Status WriteIdxLabels(const std::string& path,
                            const std::vector<uint8_t>& labels);

}  // namespace bitewise::experiments

#endif  // BITEWISE_EXPERIMENTS_IDX_H_
