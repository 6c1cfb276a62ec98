// Server bootstrap shared by every bitewise service binary: binds the
// listening address (plaintext, TLS or mutual TLS), loads the roles file
// into the services' RpcEnvironment, serves its metrics, switches on the
// standard grpc.health.v1 health service and server reflection, and drains
// in-flight calls on shutdown. Services only supply their grpc::Service
// objects and the environment they were made with, and drive readiness
// with SetServing().
#ifndef BITEWISE_SERVICES_COMMON_SERVER_H_
#define BITEWISE_SERVICES_COMMON_SERVER_H_

#include <grpcpp/server.h>

#include <memory>
#include <string>
#include <vector>

#include "absl/base/thread_annotations.h"
#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/synchronization/mutex.h"
#include "absl/time/time.h"
#include "services/common/authz.h"
#include "services/common/metrics.h"
#include "services/common/rpc_environment.h"

namespace bitewise {

// How a ServiceServer listens. Plain data so mains fill it from flags
// (server_flags.h) and tests fill it directly.
struct ServerOptions {
  // host:port to bind. Port 0 picks a free port (see ServiceServer::port()).
  // Defaults to loopback so nothing is exposed unless asked for.
  std::string listen_address = "127.0.0.1:0";
  // PEM certificate chain and private key of the server. Both empty means
  // plaintext; setting only one of them is an error.
  std::string tls_cert_file;
  std::string tls_key_file;
  // PEM CA bundle for client certificates. When set (requires the two files
  // above), clients must present a certificate signed by this CA (mutual
  // TLS); when empty, client certificates are not requested.
  std::string tls_client_ca_file;
  // Largest message accepted or sent, in bytes. Default 4 MiB, gRPC's own.
  int max_message_bytes = 4 << 20;
  // How long Shutdown() lets in-flight calls finish before cancelling them.
  absl::Duration drain_timeout = absl::Seconds(10);
  // Listening on a non-loopback address without TLS exposes health data
  // and the robot to the network in clear text; Start refuses it unless
  // this says the operator means it.
  bool allow_plaintext_remote = false;
  // Roles file (authz.h). Requires mutual TLS. Empty: authorization off,
  // which the start-up line says.
  std::string authz_file;
  // Prometheus metrics (metrics.h) on their own HTTP port, "host:port"
  // (port 0 picks one). Empty: no metrics endpoint.
  std::string metrics_listen;
};

// A running gRPC server hosting one or more bitewise services plus health and
// reflection. The health status of "" and of every name passed to Start()
// begins NOT_SERVING: a service is only reported ready once the caller has
// checked its dependencies (model loaded, database open, ...) and called
// SetServing(true).
//
// Thread-safe. The grpc::Service objects and the RpcEnvironment must
// outlive the ServiceServer.
class ServiceServer {
 public:
  // Binds and starts serving `services`. `health_names` are the full service
  // names reported through grpc.health.v1 (for example
  // "bitewise.v1.BanditService"); gRPC offers no public way to read them
  // from a grpc::Service, so the caller lists them. `env` is the
  // environment the services were made with: before the first call Start
  // installs in it the roles file's authorizer (none with authorization
  // off), and with options.metrics_listen set it serves env's metrics. An
  // environment serves one ServiceServer at a time, so that no server's
  // calls are checked against another's roles; the destructor, once the
  // last call has finished, removes the authorizer and leaves `env` free
  // for another server.
  //
  // Errors: INVALID_ARGUMENT for inconsistent options (TLS key without
  // certificate, client CA without server certificate, non-positive message
  // size); FAILED_PRECONDITION naming the file when a TLS file cannot be
  // read; UNAVAILABLE when the address cannot be bound (bad address or port
  // in use); FAILED_PRECONDITION when `env` already serves another
  // ServiceServer.
  static absl::StatusOr<std::unique_ptr<ServiceServer>> Start(
      const ServerOptions& options, RpcEnvironment* env,
      std::vector<grpc::Service*> services,
      std::vector<std::string> health_names);

  // Shuts down (draining) if the caller has not already.
  ~ServiceServer();

  ServiceServer(const ServiceServer&) = delete;
  ServiceServer& operator=(const ServiceServer&) = delete;

  // The bound port; the actual one when the options asked for port 0.
  int port() const { return port_; }

  // An address a client on this machine can dial ("127.0.0.1:<port>" when
  // bound to a wildcard address, otherwise the configured host).
  std::string address() const { return address_; }
  // For the start-up line: the address actually bound (wildcards as
  // given) and the transport security, e.g. "0.0.0.0:50051 (mutual TLS)".
  std::string description() const { return description_; }
  // The metrics endpoint's port; 0 without options.metrics_listen.
  int metrics_port() const { return metrics_ ? metrics_->port() : 0; }
  // Reloads the roles file (on SIGHUP); OK when authorization is off.
  absl::Status ReloadAuthorization();
  bool authorization_on() const { return authorizer_ != nullptr; }

  absl::Duration drain_timeout() const { return drain_timeout_; }

  // Sets the health status of "" and of every health name. No effect after
  // Shutdown(): a draining server never reports SERVING again.
  void SetServing(bool serving);

  // Reports NOT_SERVING, stops accepting calls and waits up to the drain
  // timeout for in-flight calls, then cancels the rest. Idempotent.
  void Shutdown();

  // Blocks until the server has shut down.
  void Wait();

 private:
  ServiceServer(std::unique_ptr<grpc::Server> server,
                std::vector<std::string> health_names, int port,
                std::string address, std::string description,
                absl::Duration drain_timeout, RpcEnvironment* env,
                std::unique_ptr<Authorizer> authorizer,
                std::unique_ptr<MetricsServer> metrics);

  const std::unique_ptr<grpc::Server> server_;
  const std::vector<std::string> health_names_;
  const int port_;
  const std::string address_;
  const std::string description_;
  RpcEnvironment* const env_;
  const std::unique_ptr<Authorizer> authorizer_;
  const std::unique_ptr<MetricsServer> metrics_;
  const absl::Duration drain_timeout_;

  absl::Mutex mu_;
  bool shut_down_ ABSL_GUARDED_BY(mu_) = false;
};

// Blocks SIGTERM, SIGINT and SIGHUP in the calling thread. Mains call this
// first thing, before any thread exists (gRPC starts threads as soon as it is
// used), so every thread inherits the mask and the signals are only ever
// consumed by RunUntilSignal() instead of killing the process mid-call.
void BlockTerminationSignals();

// Waits for SIGTERM or SIGINT (which BlockTerminationSignals() must already
// have blocked), prints one line to stderr, shuts `server` down with its
// drain timeout and returns once it has stopped. A SIGHUP meanwhile reloads
// the roles file (and keeps serving). Errors: INTERNAL if waiting
// for the signal fails.
absl::Status RunUntilSignal(ServiceServer& server);

// Prints "<program>: <what>: <status>" to stderr and returns 1, the exit
// code of a service main that cannot go on (bad flags, a model or database
// that does not load, an address that cannot be bound). `program` is the
// binary's name, for example "bitewise-bandit"; tests and operators grep for
// these lines. Usage: `if (!s.ok()) return ReportFatal(kProgram, "...", s);`
int ReportFatal(const char* program, const std::string& what,
                const absl::Status& status);

}  // namespace bitewise

#endif  // BITEWISE_SERVICES_COMMON_SERVER_H_
