// Early-return helpers for absl::Status and absl::StatusOr. Debian's abseil
// (20220623) ships no status macros, so bitewise keeps this one small header.
#ifndef BITEWISE_SERVICES_COMMON_STATUS_MACROS_H_
#define BITEWISE_SERVICES_COMMON_STATUS_MACROS_H_

#include <utility>

#include "absl/status/status.h"
#include "absl/status/statusor.h"

#define BITEWISE_CONCAT_INNER_(a, b) a##b
#define BITEWISE_CONCAT_(a, b) BITEWISE_CONCAT_INNER_(a, b)

// Returns from the current function if `expr` yields a non-OK status.
#define RETURN_IF_ERROR(expr)                            \
  do {                                                   \
    const absl::Status bitewise_status_ = (expr);        \
    if (!bitewise_status_.ok()) return bitewise_status_; \
  } while (0)

// ASSIGN_OR_RETURN(lhs, expr): evaluates a StatusOr expression, returns its
// status on error, otherwise moves the value into `lhs` (which may declare).
#define ASSIGN_OR_RETURN(lhs, expr) \
  BITEWISE_ASSIGN_OR_RETURN_IMPL_(  \
      BITEWISE_CONCAT_(bitewise_statusor_, __LINE__), lhs, expr)

#define BITEWISE_ASSIGN_OR_RETURN_IMPL_(statusor, lhs, expr) \
  auto statusor = (expr);                                    \
  if (!statusor.ok()) return std::move(statusor).status();   \
  lhs = std::move(statusor).value()

#endif  // BITEWISE_SERVICES_COMMON_STATUS_MACROS_H_
