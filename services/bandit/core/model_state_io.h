// Helpers the learners share: the raw float64 layout of a saved model
// state (StateWriter, StateReader) and the check of an input vector
// (ValidateVector). Internal to services/bandit/core.
#ifndef BITEWISE_SERVICES_BANDIT_CORE_MODEL_STATE_IO_H_
#define BITEWISE_SERVICES_BANDIT_CORE_MODEL_STATE_IO_H_

#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>
#include <utility>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"
#include "absl/types/span.h"

namespace bitewise::bandit {

// Appends raw float64 and integer values (the host's layout; a marker in
// the header tells another layout apart).
class StateWriter {
 public:
  // Writes into `buffer`'s storage (cleared, its capacity kept).
  StateWriter(std::string buffer, size_t reserve) : out_(std::move(buffer)) {
    out_.clear();
    out_.reserve(reserve);
  }
  template <typename T>
  void Value(T v) {
    out_.append(reinterpret_cast<const char*>(&v), sizeof(v));
  }
  void Doubles(const double* data, size_t n) {
    if (n == 0) return;  // data may be null
    out_.append(reinterpret_cast<const char*>(data), n * sizeof(double));
  }
  std::string Take() { return std::move(out_); }

 private:
  std::string out_;
};

class StateReader {
 public:
  explicit StateReader(absl::string_view in) : in_(in) {}
  template <typename T>
  absl::Status Value(T* v, const char* what) {
    return Read(v, sizeof(T), what);
  }
  absl::Status Doubles(double* data, size_t n, const char* what) {
    return Read(data, n * sizeof(double), what);
  }
  size_t left() const { return in_.size() - pos_; }

 private:
  absl::Status Read(void* out, size_t bytes, const char* what) {
    if (left() < bytes) {
      return absl::DataLossError(absl::StrCat("model state: truncated in ",
                                              what, " at byte ", pos_, " of ",
                                              in_.size()));
    }
    if (bytes == 0) return absl::OkStatus();  // out may be null
    std::memcpy(out, in_.data() + pos_, bytes);
    pos_ += bytes;
    return absl::OkStatus();
  }
  absl::string_view in_;
  size_t pos_ = 0;
};

// INVALID_ARGUMENT naming `field` unless `v` has `expected` finite values
// of magnitude at most `max_magnitude`.
inline absl::Status ValidateVector(const char* field,
                                   absl::Span<const double> v, size_t expected,
                                   double max_magnitude) {
  if (v.size() != expected) {
    return absl::InvalidArgumentError(absl::StrCat(
        field, ": expected ", expected, " values, got ", v.size()));
  }
  for (size_t i = 0; i < v.size(); ++i) {
    if (!std::isfinite(v[i])) {
      return absl::InvalidArgumentError(
          absl::StrCat(field, "[", i, "]: must be finite, got ", v[i]));
    }
    if (std::abs(v[i]) > max_magnitude) {
      return absl::InvalidArgumentError(
          absl::StrCat(field, "[", i, "]: magnitude must be at most ",
                       max_magnitude, ", got ", v[i]));
    }
  }
  return absl::OkStatus();
}

// A saved state starts with 4 magic bytes, its format number and a float64
// marker that tells this host's layout from another.
struct StateHeader {
  const char* magic;  // 4 bytes
  int32_t format;
  double marker;
  const char* name;  // for messages: "model", "poLinUCB"
};

inline void WriteStateHeader(StateWriter& out, const StateHeader& header) {
  for (int i = 0; i < 4; ++i) out.Value(header.magic[i]);
  out.Value(header.format);
  out.Value(header.marker);
}

// DATA_LOSS unless `in` starts with `header`.
// As ReadStateHeader below, accepting any format from `oldest` to
// header.format; `*format` is the one found.
inline absl::Status ReadStateHeader(StateReader& in, const StateHeader& header,
                                    int32_t oldest, int32_t* found) {
  char magic[4];
  int32_t format = 0;
  double marker = 0;
  for (char& c : magic) {
    if (absl::Status s = in.Value(&c, "the header"); !s.ok()) return s;
  }
  if (absl::Status s = in.Value(&format, "the header"); !s.ok()) return s;
  if (absl::Status s = in.Value(&marker, "the header"); !s.ok()) return s;
  if (std::memcmp(magic, header.magic, 4) != 0 || format < oldest ||
      format > header.format || marker != header.marker) {
    return absl::DataLossError(absl::StrCat(
        "model state: not a bitewise ", header.name, " state of format ",
        oldest == header.format ? "" : absl::StrCat(oldest, " to "),
        header.format, " in this host's layout"));
  }
  *found = format;
  return absl::OkStatus();
}

inline absl::Status ReadStateHeader(StateReader& in,
                                    const StateHeader& header) {
  int32_t found = 0;
  return ReadStateHeader(in, header, header.format, &found);
}

}  // namespace bitewise::bandit

#endif  // BITEWISE_SERVICES_BANDIT_CORE_MODEL_STATE_IO_H_
