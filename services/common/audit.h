// The audit trail of administrative calls. RunRpc writes one line per
// audited call (Audited() in authz.h) to stderr, and hands the same record
// to its environment's AuditSink (rpc_environment.h) if one is installed:
// the BanditService's main installs one that keeps the records in its
// store, readable through ListAudit.
// Thread-safe.
#ifndef BITEWISE_SERVICES_COMMON_AUDIT_H_
#define BITEWISE_SERVICES_COMMON_AUDIT_H_

#include <string>

#include "absl/status/status.h"
#include "absl/time/time.h"

namespace bitewise {

struct AuditEvent {
  absl::Time time;
  std::string method;    // "Service/Method"
  std::string target;    // what the call concerned (a user id), if known
  std::string identity;  // client certificate identities, comma-separated
  std::string role;      // "" when authorization is off
  std::string peer;
  std::string result;  // "OK" or the status code's name
};

class AuditSink {
 public:
  virtual ~AuditSink() = default;
  // Keeps `event` durably before returning; an error is logged by RunRpc
  // (the call's own result stands).
  virtual absl::Status Record(const AuditEvent& event) = 0;
};

}  // namespace bitewise

#endif  // BITEWISE_SERVICES_COMMON_AUDIT_H_
