// AuditLog: the store's role that keeps the administrative calls (who,
// what, when, from where, the result), oldest first.
#ifndef BITEWISE_SERVICES_BANDIT_STORE_AUDIT_LOG_H_
#define BITEWISE_SERVICES_BANDIT_STORE_AUDIT_LOG_H_

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/time/time.h"
#include "services/bandit/store/store_records.h"

namespace bitewise::bandit {

class AuditLog {
 public:
  virtual ~AuditLog() = default;

  // Durably appends an audit entry (audit_id ignored) and returns its id.
  virtual absl::StatusOr<int64_t> AppendAudit(const AuditEntry& entry) = 0;
  // The audit log in audit_id order (oldest first).
  virtual absl::StatusOr<PageResult<AuditEntry>> ListAudit(
      const Page& page) = 0;
};

}  // namespace bitewise::bandit

#endif  // BITEWISE_SERVICES_BANDIT_STORE_AUDIT_LOG_H_
