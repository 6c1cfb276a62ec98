// Reading a saved model state kept as a test fixture
// (tests/bandit/testdata): its bytes and the format number the state
// records, for the tests that check states made by earlier releases load.
#ifndef BITEWISE_TESTS_BANDIT_STATE_FIXTURE_H_
#define BITEWISE_TESTS_BANDIT_STATE_FIXTURE_H_

#include <cstdint>
#include <cstring>
#include <fstream>
#include <iterator>
#include <string>

namespace bitewise::bandit::testing {

// The bytes of the state at `path` ("" if it cannot be read) and, in
// `*format`, the format number it records (bytes 4-7; -1 if too short).
inline std::string ReadStateFixture(const std::string& path, int32_t* format) {
  std::ifstream file(path, std::ios::binary);
  std::string state((std::istreambuf_iterator<char>(file)),
                    std::istreambuf_iterator<char>());
  *format = -1;
  if (state.size() >= 8) std::memcpy(format, state.data() + 4, sizeof(*format));
  return state;
}

}  // namespace bitewise::bandit::testing

#endif  // BITEWISE_TESTS_BANDIT_STATE_FIXTURE_H_
