#include "services/common/rpc_handler.h"

#include <chrono>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "absl/time/clock.h"
#include "absl/time/time.h"
#include "services/common/authz.h"
#include "services/common/grpc_status.h"
#include "services/common/metrics.h"

namespace bitewise {
namespace {

// Whether the call running on this thread withholds raw contexts (set by
// RunRpc around its handler). Not state shared between calls: a handler
// runs on one thread from start to end, and each thread has its own.
thread_local bool call_withholds_contexts = false;

// Longest message written to the log for one failure.
constexpr size_t kMaxLoggedMessage = 300;

absl::Status Precheck(const char* method, grpc::ServerContext* context) {
  if (context == nullptr) return absl::OkStatus();
  if (context->IsCancelled()) {
    return absl::CancelledError(
        absl::StrCat(method, ": the caller cancelled before it ran"));
  }
  const auto deadline = context->deadline();
  if (deadline != std::chrono::system_clock::time_point::max() &&
      deadline <= std::chrono::system_clock::now()) {
    return absl::DeadlineExceededError(
        absl::StrCat(method, ": the deadline passed before it ran"));
  }
  return absl::OkStatus();
}

// The client's certificate identities: subject CN and SAN entries.
std::vector<std::string> PeerIdentities(const grpc::ServerContext& context) {
  std::vector<std::string> out;
  const std::shared_ptr<const grpc::AuthContext> auth = context.auth_context();
  if (auth == nullptr) return out;
  for (const char* property :
       {"x509_common_name", "x509_subject_alternative_name"}) {
    for (const grpc::string_ref& value : auth->FindPropertyValues(property)) {
      out.emplace_back(value.data(), value.size());
    }
  }
  return out;
}

}  // namespace

bool CallerMayReadContexts() { return !call_withholds_contexts; }

grpc::Status RunRpc(const RpcEnvironment& env, const char* method,
                    grpc::ServerContext* context,
                    const std::function<absl::Status()>& handler,
                    RpcPolicy policy, absl::string_view target) {
  const absl::Time start = absl::Now();
  absl::Status status = Precheck(method, context);
  // Authorization comes before everything, Stop included: a refused call
  // runs nothing.
  const Authorizer* authorizer = env.authorizer();
  std::vector<std::string> identities;
  std::string role;
  bool withhold = false;
  if (authorizer != nullptr && context != nullptr) {
    identities = PeerIdentities(*context);
    absl::Status allowed = authorizer->Check(method, identities,
                                             context->peer(), &role, &withhold);
    if (!allowed.ok()) {
      status = allowed;
      policy = RpcPolicy::kNormal;  // not even Stop runs for a refused call
    }
  }
  if (status.ok() || policy == RpcPolicy::kAlwaysRun) {
    call_withholds_contexts = withhold;
    status = handler();
    call_withholds_contexts = false;
  }
  if (Audited(method) && context != nullptr) {
    AuditEvent event;
    event.time = absl::Now();
    event.method = method;
    event.target = std::string(target);
    event.identity = absl::StrJoin(identities, ",");
    event.role = role;
    event.peer = context->peer();
    event.result = status.ok() ? "OK" : absl::StatusCodeToString(status.code());
    std::fprintf(
        stderr, "audit: %s %s%s%s by %s (role %s) from %s: %s\n",
        absl::FormatTime(event.time).c_str(), method,
        event.target.empty() ? "" : " ", event.target.c_str(),
        event.identity.empty() ? "(no certificate)" : event.identity.c_str(),
        role.empty() ? "none" : role.c_str(), event.peer.c_str(),
        event.result.c_str());
    if (AuditSink* sink = env.audit_sink(); sink != nullptr) {
      absl::Status kept = sink->Record(event);
      if (!kept.ok()) {
        // The call stands (it has happened); its record is in the log
        // above, and the loss is counted for the engineer on call.
        env.CountLostAuditRecord();
        std::fprintf(stderr, "audit record of %s not kept: %s\n", method,
                     kept.ToString().c_str());
      }
    }
  }
  const double seconds = absl::ToDoubleSeconds(absl::Now() - start);
  env.metrics().RecordRpc(method, status.code(), seconds);
  if (!status.ok()) {
    std::string message(status.message().substr(0, kMaxLoggedMessage));
    if (status.message().size() > kMaxLoggedMessage) {
      absl::StrAppend(&message, "... (", status.message().size(), " bytes)");
    }
    std::fprintf(stderr, "rpc %s failed after %.1f ms: %s: %s\n", method,
                 1e3 * seconds, absl::StatusCodeToString(status.code()).c_str(),
                 message.c_str());
  }
  return ToGrpcStatus(status);
}

}  // namespace bitewise
