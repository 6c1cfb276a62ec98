// gMock matchers for absl::Status and absl::StatusOr, so tests say what they
// mean, as the Spanner emulator's tests do:
//   EXPECT_THAT(store->GetUser("x"), StatusIs(absl::StatusCode::kNotFound,
//                                             HasSubstr("\"x\"")));
//   EXPECT_THAT(engine->Select(input), IsOk());
#ifndef BITEWISE_TESTS_COMMON_STATUS_MATCHERS_H_
#define BITEWISE_TESTS_COMMON_STATUS_MATCHERS_H_

#include <string>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "gmock/gmock.h"

namespace bitewise::testing {

inline const absl::Status& GetStatus(const absl::Status& status) {
  return status;
}
template <typename T>
const absl::Status& GetStatus(const absl::StatusOr<T>& status_or) {
  return status_or.status();
}

MATCHER(IsOk, "is OK") {
  const absl::Status& status = GetStatus(arg);
  if (!status.ok()) *result_listener << "which is " << status.ToString();
  return status.ok();
}

MATCHER_P2(StatusIs, code, message_matcher,
           "has code " + absl::StatusCodeToString(code) +
               " and a message that " +
               ::testing::DescribeMatcher<std::string>(message_matcher)) {
  const absl::Status& status = GetStatus(arg);
  *result_listener << "which is " << status.ToString();
  return status.code() == code &&
         ::testing::Matches(message_matcher)(std::string(status.message()));
}

}  // namespace bitewise::testing

#endif  // BITEWISE_TESTS_COMMON_STATUS_MATCHERS_H_
