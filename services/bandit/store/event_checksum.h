// Per-event checksums of the bandit store (internal to services/bandit/store):
// an event's selection (what Select stored) and its outcome (what Update
// added) each carry a 64-bit checksum (FNV-1a's step over 8-byte words) of
// their stored bytes, so a row altered or damaged on disk is reported as
// DATA_LOSS naming the event instead of being learned from. They detect
// accidents (flipped bits, a hand edit), not an attacker who can rewrite the
// file and the checksum alike.
#ifndef BITEWISE_SERVICES_BANDIT_STORE_EVENT_CHECKSUM_H_
#define BITEWISE_SERVICES_BANDIT_STORE_EVENT_CHECKSUM_H_

#include <cstdint>

#include "absl/strings/string_view.h"

namespace bitewise::bandit {

// Over the selection's columns as stored (the context as its float64 blob).
int64_t SelectionChecksum(absl::string_view user_id, absl::string_view meal_id,
                          absl::string_view item_label,
                          absl::string_view context_bytes, int64_t action,
                          double propensity, int64_t selected_at_us);

// Over a blob of any size (a model checkpoint's bytes).
int64_t BlobChecksum(absl::string_view bytes);

// Over the outcome's columns as stored (post hoc as its float64 blob).
int64_t OutcomeChecksum(double loss, absl::string_view posthoc_bytes,
                        double weight, int64_t model_version,
                        int64_t updated_at_us);

}  // namespace bitewise::bandit

#endif  // BITEWISE_SERVICES_BANDIT_STORE_EVENT_CHECKSUM_H_
