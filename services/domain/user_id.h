// Person ids, one rule for every process that takes one: the BanditService
// (which stores them), bitewise-console (which takes them from browsers)
// and the tools. An id names a person's model in logs, files and URLs, so
// it is kept to characters that need no escaping anywhere.
#ifndef BITEWISE_SERVICES_DOMAIN_USER_ID_H_
#define BITEWISE_SERVICES_DOMAIN_USER_ID_H_

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"

namespace bitewise::domain {

// INVALID_ARGUMENT unless `user_id` is 1-128 characters of [A-Za-z0-9._-]
// starting with a letter or digit; the message names `field`.
inline absl::Status ValidateId(absl::string_view field,
                               absl::string_view user_id) {
  if (user_id.empty() || user_id.size() > 128) {
    return absl::InvalidArgumentError(absl::StrCat(
        field, ": must be 1-128 characters, got ", user_id.size()));
  }
  const auto alnum = [](char ch) {
    return (ch >= 'a' && ch <= 'z') || (ch >= 'A' && ch <= 'Z') ||
           (ch >= '0' && ch <= '9');
  };
  if (!alnum(user_id[0])) {
    return absl::InvalidArgumentError(absl::StrCat(
        field, ": must start with a letter or digit, got \"", user_id, "\""));
  }
  for (const char ch : user_id) {
    const bool ok = alnum(ch) || ch == '.' || ch == '_' || ch == '-';
    if (!ok) {
      return absl::InvalidArgumentError(
          absl::StrCat(field,
                       ": only letters, digits, '.', '_' and '-' are "
                       "allowed, got \"",
                       user_id, "\""));
    }
  }
  return absl::OkStatus();
}

inline absl::Status ValidateUserId(absl::string_view user_id) {
  return ValidateId("user_id", user_id);
}

}  // namespace bitewise::domain

#endif  // BITEWISE_SERVICES_DOMAIN_USER_ID_H_
