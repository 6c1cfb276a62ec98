// The store's per-event checksums (services/bandit/store/event_checksum.h):
// every stored column counts, fields do not run into each other, doubles
// count by their bits, and the values are pinned, because a checksum
// written by one build is checked by every later one.
#include "services/bandit/store/event_checksum.h"

#include <cstdint>
#include <set>
#include <string>

#include "gtest/gtest.h"

namespace bitewise::bandit {
namespace {

const std::string kContext("\x01\x02\x03\x04\x05\x06\x07\x08", 8);

int64_t Selection() {
  return SelectionChecksum("alice", "lunch", "grape", kContext, 3, 0.5, 1000);
}

TEST(EventChecksumTest, EverySelectionColumnCounts) {
  std::set<int64_t> seen = {Selection()};
  seen.insert(
      SelectionChecksum("alicf", "lunch", "grape", kContext, 3, 0.5, 1000));
  seen.insert(
      SelectionChecksum("alice", "lunci", "grape", kContext, 3, 0.5, 1000));
  seen.insert(
      SelectionChecksum("alice", "lunch", "grapf", kContext, 3, 0.5, 1000));
  std::string context = kContext;
  context[7] ^= 1;
  seen.insert(
      SelectionChecksum("alice", "lunch", "grape", context, 3, 0.5, 1000));
  seen.insert(
      SelectionChecksum("alice", "lunch", "grape", kContext, 4, 0.5, 1000));
  seen.insert(
      SelectionChecksum("alice", "lunch", "grape", kContext, 3, 0.25, 1000));
  seen.insert(
      SelectionChecksum("alice", "lunch", "grape", kContext, 3, 0.5, 1001));
  EXPECT_EQ(seen.size(), 8u);
}

TEST(EventChecksumTest, FieldsDoNotRunIntoEachOther) {
  EXPECT_NE(SelectionChecksum("ab", "c", "", "", 0, 1.0, 0),
            SelectionChecksum("a", "bc", "", "", 0, 1.0, 0));
  EXPECT_NE(SelectionChecksum("", "", "x", "", 0, 1.0, 0),
            SelectionChecksum("", "x", "", "", 0, 1.0, 0));
}

TEST(EventChecksumTest, OutcomeColumnsCountDoublesByTheirBits) {
  const std::string posthoc(16, '\x11');
  const int64_t base = OutcomeChecksum(0.0, posthoc, 1.0, 7, 99);
  std::set<int64_t> seen = {base};
  seen.insert(OutcomeChecksum(-0.0, posthoc, 1.0, 7, 99));  // other bits
  seen.insert(OutcomeChecksum(1.0, posthoc, 1.0, 7, 99));
  seen.insert(OutcomeChecksum(0.0, posthoc.substr(8), 1.0, 7, 99));
  seen.insert(OutcomeChecksum(0.0, posthoc, 2.0, 7, 99));
  seen.insert(OutcomeChecksum(0.0, posthoc, 1.0, 8, 99));
  seen.insert(OutcomeChecksum(0.0, posthoc, 1.0, 7, 100));
  EXPECT_EQ(seen.size(), 7u);
  EXPECT_EQ(OutcomeChecksum(0.0, posthoc, 1.0, 7, 99), base);  // deterministic
}

TEST(EventChecksumTest, BlobChecksumSeesEveryByteAndTheLength) {
  std::string blob(1000, '\0');
  const int64_t zeros = BlobChecksum(blob);
  blob[999] = 1;
  EXPECT_NE(BlobChecksum(blob), zeros);
  EXPECT_NE(BlobChecksum(std::string(1001, '\0')), zeros);
  EXPECT_NE(BlobChecksum(""), BlobChecksum(std::string(1, '\0')));
}

// Stores on disk carry these: a change of the function would make every
// existing event read as damaged.
TEST(EventChecksumTest, ValuesArePinned) {
  EXPECT_EQ(Selection(), int64_t{3274347293739616335});
  EXPECT_EQ(OutcomeChecksum(1.0, std::string(8, '\x22'), 1.0, 5, 12345),
            int64_t{1517548887718945183});
  EXPECT_EQ(BlobChecksum("bitewise"), int64_t{-6854712463009070611});
}

}  // namespace
}  // namespace bitewise::bandit
