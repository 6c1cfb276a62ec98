// What RunRpc (rpc_handler.h) needs besides the call itself, passed to every
// handler instead of reached through process-wide state: the metrics each
// call is counted in, the authorizer consulted before each handler and the
// audit sink that keeps administrative calls. A main makes one environment,
// gives it to its services (which hand it to RunRpc) and to
// ServiceServer::Start (which installs the roles file's authorizer in it and
// serves its metrics); a test makes its own, so nothing one test records or
// installs reaches another.
// Thread-safe.
#ifndef BITEWISE_SERVICES_COMMON_RPC_ENVIRONMENT_H_
#define BITEWISE_SERVICES_COMMON_RPC_ENVIRONMENT_H_

#include <atomic>
#include <cstdint>
#include <memory>
#include <vector>

#include "services/common/audit.h"
#include "services/common/metrics.h"

namespace bitewise {

class Authorizer;
class ServiceServer;

class RpcEnvironment {
 public:
  RpcEnvironment() : metrics_(std::make_unique<Metrics>()) {
    metrics_->AddScrapeValues(
        "bitewise_audit_records_lost_total",
        "Audited calls whose record the audit sink (the store) did not keep; "
        "the call itself stood and its line is in the log",
        ScrapeType::kCounter, [this]() -> std::vector<ScrapeValue> {
          return {{{}, static_cast<double>(audit_records_lost())}};
        });
  }
  RpcEnvironment(const RpcEnvironment&) = delete;
  RpcEnvironment& operator=(const RpcEnvironment&) = delete;

  // Where RunRpc counts every call and a main adds its own values. Recording
  // changes the metrics' counts, not which metrics these are, so a const
  // environment hands them out.
  Metrics& metrics() const { return *metrics_; }

  // The authorizer RunRpc consults before every handler; null: authorization
  // off. Installed by the ServiceServer that serves this environment (from
  // ServerOptions::authz_file, before it takes calls) and removed when that
  // server has stopped; SIGHUP's reload changes its roles in place.
  const Authorizer* authorizer() const {
    return authorizer_.load(std::memory_order_acquire);
  }

  // Where audited calls are kept besides stderr (audit.h); null: stderr
  // only. May change at any time; `sink` must outlive every call that may
  // use it (in a main: be declared before the server).
  AuditSink* audit_sink() const {
    return audit_sink_.load(std::memory_order_acquire);
  }
  void set_audit_sink(AuditSink* sink) {
    audit_sink_.store(sink, std::memory_order_release);
  }
  // Audited calls whose record the sink refused (RunRpc counts them; the
  // metric bitewise_audit_records_lost_total).
  int64_t audit_records_lost() const {
    return audit_records_lost_.load(std::memory_order_relaxed);
  }
  void CountLostAuditRecord() const {
    audit_records_lost_.fetch_add(1, std::memory_order_relaxed);
  }

 private:
  // ServiceServer claims the environment (one server at a time, so that no
  // server's calls are checked against another's roles) and installs its
  // authorizer.
  friend class ServiceServer;

  const std::unique_ptr<Metrics> metrics_;
  std::atomic<bool> served_{false};
  std::atomic<const Authorizer*> authorizer_{nullptr};
  std::atomic<AuditSink*> audit_sink_{nullptr};
  mutable std::atomic<int64_t> audit_records_lost_{0};
};

}  // namespace bitewise

#endif  // BITEWISE_SERVICES_COMMON_RPC_ENVIRONMENT_H_
