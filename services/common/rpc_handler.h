// The one handler adapter: every RPC of every bitewise service is written as
// a function returning absl::Status over its request and response, and runs
// through RunRpc, which
//  - refuses work whose caller has already gone (CANCELLED) or whose
//    deadline has already passed (DEADLINE_EXCEEDED), before doing any;
//  - converts the handler's absl::Status to grpc::Status exactly once;
//  - logs every failure with the method, code, latency and message (cut to
//    a few hundred characters, so an oversized value cannot flood the log);
//  - records each call's outcome and latency in RpcStats, the hook that
//    metrics exporters read;
//  - writes administrative calls to the audit trail (audit.h).
// Thread-safe.
#ifndef BITEWISE_SERVICES_COMMON_RPC_HANDLER_H_
#define BITEWISE_SERVICES_COMMON_RPC_HANDLER_H_

#include <grpcpp/server_context.h>
#include <grpcpp/support/status.h>

#include <cstdint>
#include <functional>
#include <map>
#include <string>

#include "absl/base/thread_annotations.h"
#include "absl/status/status.h"
#include "absl/strings/string_view.h"
#include "absl/synchronization/mutex.h"
#include "services/common/audit.h"

namespace bitewise {

// Per-method counts since the process started.
struct RpcMethodStats {
  int64_t calls = 0;
  int64_t failures = 0;
  // Calls per absl::StatusCode (as int), OK included.
  std::map<int, int64_t> by_code;
  double total_seconds = 0.0;
  double max_seconds = 0.0;
};

class RpcStats {
 public:
  // The process-wide registry RunRpc records into.
  static RpcStats& Global();

  void Record(const std::string& method, absl::StatusCode code, double seconds);
  // A copy of every method's counts, keyed "Service/Method".
  std::map<std::string, RpcMethodStats> Snapshot() const;

 private:
  mutable absl::Mutex mu_;
  std::map<std::string, RpcMethodStats> methods_ ABSL_GUARDED_BY(mu_);
};

enum class RpcPolicy {
  kNormal,
  // Runs even when the caller has gone or its deadline has passed: for
  // safety actions (the robot's Stop) whose effect matters more than the
  // reply.
  kAlwaysRun,
};

// Runs `handler` for `method` ("Service/Method") as described above.
// `context` may be null (tests that call a handler directly). An audited
// method (authz.h) is written to the audit trail (audit.h) with `target`,
// what the call concerned (a user id), once the handler has run.
grpc::Status RunRpc(const char* method, grpc::ServerContext* context,
                    const std::function<absl::Status()>& handler,
                    RpcPolicy policy = RpcPolicy::kNormal,
                    absl::string_view target = "");

// Inside a handler run by RunRpc: false when the caller's grant is
// "researcher without_contexts" (authz.h), so the handler must leave raw
// context and post hoc vectors out of its reply; true otherwise (and with
// authorization off).
bool CallerMayReadContexts();

}  // namespace bitewise

#endif  // BITEWISE_SERVICES_COMMON_RPC_HANDLER_H_
