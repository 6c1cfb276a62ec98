#include "experiments/idx.h"

#include <fstream>
#include <iterator>

#include "absl/strings/str_cat.h"

namespace bitewise::experiments {
namespace {

constexpr uint32_t kLabelsMagic = 0x00000801;  // ubyte, 1 dimension
constexpr uint32_t kImagesMagic = 0x00000803;  // ubyte, 3 dimensions

absl::StatusOr<std::string> ReadAll(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return absl::NotFoundError(absl::StrCat("cannot open ", path));
  return std::string(std::istreambuf_iterator<char>(in), {});
}

uint32_t BigEndian32(const std::string& bytes, size_t offset) {
  uint32_t v = 0;
  for (int i = 0; i < 4; ++i) {
    v = (v << 8) | static_cast<unsigned char>(bytes[offset + i]);
  }
  return v;
}

void AppendBigEndian32(uint32_t v, std::string& out) {
  for (int shift = 24; shift >= 0; shift -= 8) {
    out += static_cast<char>((v >> shift) & 0xff);
  }
}

absl::Status WriteAll(const std::string& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  out.close();
  if (!out) return absl::InternalError(absl::StrCat("cannot write ", path));
  return absl::OkStatus();
}

}  // namespace

absl::StatusOr<IdxImages> ReadIdxImages(const std::string& path) {
  auto bytes = ReadAll(path);
  if (!bytes.ok()) return bytes.status();
  if (bytes->size() < 16 || BigEndian32(*bytes, 0) != kImagesMagic) {
    return absl::DataLossError(
        absl::StrCat(path, ": not an IDX ubyte image file (magic 0x803)"));
  }
  IdxImages images;
  const uint32_t count = BigEndian32(*bytes, 4);
  const uint32_t rows = BigEndian32(*bytes, 8);
  const uint32_t cols = BigEndian32(*bytes, 12);
  // Bounded so the product below cannot overflow and a corrupt header
  // cannot ask for gigabytes.
  if (rows == 0 || cols == 0 || rows > 4096 || cols > 4096 ||
      count > (1u << 24)) {
    return absl::DataLossError(absl::StrCat(path, ": implausible dimensions ",
                                            count, "x", rows, "x", cols));
  }
  const uint64_t expected = 16 + uint64_t{count} * rows * cols;
  if (bytes->size() != expected) {
    return absl::DataLossError(absl::StrCat(path, ": ", bytes->size(),
                                            " bytes, header says ", expected));
  }
  images.count = static_cast<int>(count);
  images.rows = static_cast<int>(rows);
  images.cols = static_cast<int>(cols);
  images.pixels.assign(bytes->begin() + 16, bytes->end());
  return images;
}

absl::StatusOr<std::vector<uint8_t>> ReadIdxLabels(const std::string& path) {
  auto bytes = ReadAll(path);
  if (!bytes.ok()) return bytes.status();
  if (bytes->size() < 8 || BigEndian32(*bytes, 0) != kLabelsMagic) {
    return absl::DataLossError(
        absl::StrCat(path, ": not an IDX ubyte label file (magic 0x801)"));
  }
  const uint64_t count = BigEndian32(*bytes, 4);
  if (bytes->size() != 8 + count) {
    return absl::DataLossError(absl::StrCat(path, ": ", bytes->size(),
                                            " bytes, header says ", 8 + count));
  }
  return std::vector<uint8_t>(bytes->begin() + 8, bytes->end());
}

absl::Status WriteIdxImages(const std::string& path, const IdxImages& images) {
  if (images.pixels.size() !=
      static_cast<size_t>(images.count) * images.rows * images.cols) {
    return absl::InvalidArgumentError("pixel count does not match dimensions");
  }
  std::string bytes;
  AppendBigEndian32(kImagesMagic, bytes);
  AppendBigEndian32(images.count, bytes);
  AppendBigEndian32(images.rows, bytes);
  AppendBigEndian32(images.cols, bytes);
  bytes.append(images.pixels.begin(), images.pixels.end());
  return WriteAll(path, bytes);
}

absl::Status WriteIdxLabels(const std::string& path,
                            const std::vector<uint8_t>& labels) {
  std::string bytes;
  AppendBigEndian32(kLabelsMagic, bytes);
  AppendBigEndian32(static_cast<uint32_t>(labels.size()), bytes);
  bytes.append(labels.begin(), labels.end());
  return WriteAll(path, bytes);
}

}  // namespace bitewise::experiments
