// The one handler adapter: every RPC of every bitewise service is written as
// a function returning absl::Status over its request and response, and runs
// through RunRpc, which
//  - refuses work whose caller has already gone (CANCELLED) or whose
//    deadline has already passed (DEADLINE_EXCEEDED), before doing any;
//  - checks the caller's role with the environment's authorizer, if any
//    (authz.h), before doing any;
//  - converts the handler's absl::Status to grpc::Status exactly once;
//  - logs every failure with the method, code, latency and message (cut to
//    a few hundred characters, so an oversized value cannot flood the log);
//  - counts each call's outcome and latency in the environment's Metrics
//    (metrics.h);
//  - writes administrative calls to the audit trail (audit.h).
// Everything it uses besides the call comes from the RpcEnvironment it is
// given (rpc_environment.h): no process-wide state.
// Thread-safe.
#ifndef BITEWISE_SERVICES_COMMON_RPC_HANDLER_H_
#define BITEWISE_SERVICES_COMMON_RPC_HANDLER_H_

#include <grpcpp/server_context.h>
#include <grpcpp/support/status.h>

#include <functional>

#include "absl/status/status.h"
#include "absl/strings/string_view.h"
#include "services/common/rpc_environment.h"

namespace bitewise {

enum class RpcPolicy {
  kNormal,
  // Runs even when the caller has gone or its deadline has passed: for
  // safety actions (the robot's Stop) whose effect matters more than the
  // reply.
  kAlwaysRun,
};

// Runs `handler` for `method` ("Service/Method") as described above, with
// the authorizer, audit sink and metrics of `env`. `context` may be null
// (tests that call a handler directly; no authorization then). An audited
// method (authz.h) is written to the audit trail (audit.h) with `target`,
// what the call concerned (a user id), once the handler has run.
grpc::Status RunRpc(const RpcEnvironment& env, const char* method,
                    grpc::ServerContext* context,
                    const std::function<absl::Status()>& handler,
                    RpcPolicy policy = RpcPolicy::kNormal,
                    absl::string_view target = "");

// Inside a handler run by RunRpc: false when the caller's grant is
// "researcher without_contexts" (authz.h), so the handler must leave raw
// context and post hoc vectors out of its reply; true otherwise (and with
// authorization off). Read from a thread_local that RunRpc sets around the
// handler it runs on this thread: it describes the one call in progress on
// the calling thread, not state shared between calls, and saves threading
// the caller's grant through every handler's converters.
bool CallerMayReadContexts();

}  // namespace bitewise

#endif  // BITEWISE_SERVICES_COMMON_RPC_HANDLER_H_
