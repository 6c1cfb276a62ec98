#include "services/bandit/store/event_checksum.h"

#include <cstring>

namespace bitewise::bandit {
namespace {

// FNV-1a 64 over length-prefixed fields, so ("ab", "c") and ("a", "bc")
// differ; integers and doubles as their 8 little-endian bytes.
class Fnv1a {
 public:
  void Bytes(absl::string_view bytes) {
    Integer(static_cast<int64_t>(bytes.size()));
    for (const char c : bytes) Byte(static_cast<uint8_t>(c));
  }
  void Integer(int64_t value) {
    const auto bits = static_cast<uint64_t>(value);
    for (int i = 0; i < 8; ++i) Byte(static_cast<uint8_t>(bits >> (8 * i)));
  }
  void Double(double value) {
    uint64_t bits;
    std::memcpy(&bits, &value, sizeof(bits));
    Integer(static_cast<int64_t>(bits));
  }
  int64_t Value() const { return static_cast<int64_t>(hash_); }

 private:
  void Byte(uint8_t b) {
    hash_ ^= b;
    hash_ *= 0x100000001b3ULL;
  }
  uint64_t hash_ = 0xcbf29ce484222325ULL;
};

}  // namespace

int64_t SelectionChecksum(absl::string_view user_id, absl::string_view meal_id,
                          absl::string_view item_label,
                          absl::string_view context_bytes, int64_t action,
                          double propensity, int64_t selected_at_us) {
  Fnv1a h;
  h.Bytes(user_id);
  h.Bytes(meal_id);
  h.Bytes(item_label);
  h.Bytes(context_bytes);
  h.Integer(action);
  h.Double(propensity);
  h.Integer(selected_at_us);
  return h.Value();
}

int64_t OutcomeChecksum(double loss, absl::string_view posthoc_bytes,
                        double weight, int64_t model_version,
                        int64_t updated_at_us) {
  Fnv1a h;
  h.Double(loss);
  h.Bytes(posthoc_bytes);
  h.Double(weight);
  h.Integer(model_version);
  h.Integer(updated_at_us);
  return h.Value();
}

}  // namespace bitewise::bandit
