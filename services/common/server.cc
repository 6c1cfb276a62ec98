#include "services/common/server.h"

#include <arpa/inet.h>
#include <grpc/grpc.h>
#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/health_check_service_interface.h>
#include <grpcpp/security/server_credentials.h>
#include <grpcpp/server_builder.h>
#include <netinet/in.h>
#include <pthread.h>
#include <signal.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>
#include <utility>

#include "absl/algorithm/container.h"
#include "absl/strings/ascii.h"
#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"
#include "absl/time/clock.h"
#include "grpc/health/v1/health.pb.h"
#include "services/common/status_macros.h"
#include "services/common/tls_files.h"

namespace bitewise {
namespace {

absl::StatusOr<std::shared_ptr<grpc::ServerCredentials>> MakeCredentials(
    const ServerOptions& options) {
  const bool has_cert = !options.tls_cert_file.empty();
  const bool has_key = !options.tls_key_file.empty();
  const bool has_client_ca = !options.tls_client_ca_file.empty();
  if (has_cert != has_key) {
    return absl::InvalidArgumentError(
        "TLS needs both a certificate file and a key file, got only one");
  }
  if (has_client_ca && !has_cert) {
    return absl::InvalidArgumentError(
        "a client CA file (mutual TLS) needs a server certificate and key");
  }
  if (!has_cert) return grpc::InsecureServerCredentials();

  grpc::SslServerCredentialsOptions ssl(
      has_client_ca ? GRPC_SSL_REQUEST_AND_REQUIRE_CLIENT_CERTIFICATE_AND_VERIFY
                    : GRPC_SSL_DONT_REQUEST_CLIENT_CERTIFICATE);
  grpc::SslServerCredentialsOptions::PemKeyCertPair pair;
  ASSIGN_OR_RETURN(pair.cert_chain,
                   ReadPemFile(options.tls_cert_file, "TLS certificate"));
  ASSIGN_OR_RETURN(pair.private_key,
                   ReadPrivateKeyFile(options.tls_key_file, "TLS key"));
  ssl.pem_key_cert_pairs.push_back(std::move(pair));
  if (has_client_ca) {
    ASSIGN_OR_RETURN(ssl.pem_root_certs,
                     ReadPemFile(options.tls_client_ca_file, "TLS client CA"));
  }
  return grpc::SslServerCredentials(ssl);
}

// Turns the listen address into one a local client can dial: wildcard hosts
// are not connectable addresses on every platform.
std::string DialableAddress(const std::string& listen_address, int port) {
  const size_t colon = listen_address.rfind(':');
  std::string host = colon == std::string::npos
                         ? std::string()
                         : listen_address.substr(0, colon);
  if (host.empty() || host == "0.0.0.0") host = "127.0.0.1";
  if (host == "[::]") host = "[::1]";
  return absl::StrCat(host, ":", port);
}

}  // namespace

absl::StatusOr<std::unique_ptr<ServiceServer>> ServiceServer::Start(
    const ServerOptions& options, RpcEnvironment* env,
    std::vector<grpc::Service*> services,
    std::vector<std::string> health_names) {
  if (options.max_message_bytes <= 0) {
    return absl::InvalidArgumentError(absl::StrCat(
        "max_message_bytes must be positive, got ", options.max_message_bytes));
  }
  ASSIGN_OR_RETURN(std::shared_ptr<grpc::ServerCredentials> credentials,
                   MakeCredentials(options));
  // "" for a bare port (every interface).
  const auto host_of = [](const std::string& address) {
    const size_t colon = address.rfind(':');
    return colon == std::string::npos ? std::string()
                                      : address.substr(0, colon);
  };
  // An address, not a name that merely starts like one ("127.x.example").
  const auto loopback = [](const std::string& host) {
    if (host == "localhost" || host == "[::1]") return true;
    in_addr v4;
    return inet_pton(AF_INET, host.c_str(), &v4) == 1 &&
           (ntohl(v4.s_addr) >> 24) == 127;
  };
  const std::string host = host_of(options.listen_address);
  const bool tls = !options.tls_cert_file.empty();
  if (!loopback(host) && !tls && !options.allow_plaintext_remote) {
    return absl::FailedPreconditionError(absl::StrCat(
        "refusing to listen on \"", options.listen_address,
        "\" in plaintext: a non-loopback address needs --tls_cert and "
        "--tls_key (and --tls_client_ca for mutual TLS), or "
        "--allow_plaintext_remote on a network you trust"));
  }
  // CivetWeb (under prometheus-cpp's Exposer) reads a list of ports
  // ("127.0.0.1:9101,9102" also listens on every interface) and suffixes
  // ("9101s", "9101r"): one host:port only, so the check below holds.
  if (!options.metrics_listen.empty()) {
    const std::string& m = options.metrics_listen;
    const size_t colon = m.rfind(':');
    const std::string port =
        colon == std::string::npos ? m : m.substr(colon + 1);
    int port_number = 0;
    if (m.find(',') != std::string::npos || port.empty() ||
        !absl::c_all_of(port, [](char c) { return absl::ascii_isdigit(c); }) ||
        !absl::SimpleAtoi(port, &port_number) || port_number > 65535) {
      return absl::InvalidArgumentError(
          absl::StrCat("--metrics_listen=\"", m,
                       "\": give one HOST:PORT (for example 127.0.0.1:9101)"));
    }
  }
  // The metrics endpoint is plain HTTP with no authentication, whatever the
  // gRPC port's TLS: off the machine only where plaintext is allowed.
  if (!options.metrics_listen.empty() &&
      !loopback(host_of(options.metrics_listen)) &&
      !options.allow_plaintext_remote) {
    return absl::FailedPreconditionError(absl::StrCat(
        "refusing to serve metrics on \"", options.metrics_listen,
        "\": the metrics endpoint is plain HTTP without authentication; give "
        "it a loopback address (127.0.0.1:PORT, scraped on the machine or "
        "through a tunnel), or --allow_plaintext_remote on a network you "
        "trust"));
  }

  std::unique_ptr<Authorizer> authorizer;
  if (!options.authz_file.empty()) {
    if (options.tls_client_ca_file.empty()) {
      return absl::InvalidArgumentError(
          "--authz_file needs mutual TLS (--tls_cert, --tls_key and "
          "--tls_client_ca): roles are given to client certificates");
    }
    ASSIGN_OR_RETURN(authorizer, Authorizer::Load(options.authz_file));
  }

  // The health protocol's descriptor, referenced so that the linker keeps
  // it and reflection can describe grpc.health.v1.Health.
  (void)grpc::health::v1::HealthCheckRequest::descriptor();

  // Both are consulted by ServerBuilder, so they must be on before building.
  grpc::EnableDefaultHealthCheckService(true);
  grpc::reflection::InitProtoReflectionServerBuilderPlugin();

  grpc::ServerBuilder builder;
  int port = 0;
  builder.AddListeningPort(options.listen_address, credentials, &port);
  // gRPC sets SO_REUSEPORT by default, which would let a second server bind
  // the same port and silently take half the traffic; fail loudly instead.
  builder.AddChannelArgument(GRPC_ARG_ALLOW_REUSEPORT, 0);
  builder.SetMaxReceiveMessageSize(options.max_message_bytes);
  builder.SetMaxSendMessageSize(options.max_message_bytes);
  for (grpc::Service* service : services) builder.RegisterService(service);
  // More threads polling for new calls than gRPC's default (1 to 2 per
  // completion queue): with 16 clients on 2 cores, fewer hand-offs between
  // the thread that takes a call and the one that runs it. Measured on the
  // BanditService (bandit_service_bench, d = 64, 16 clients, three runs
  // each): 1,750-1,904 pairs/s by default, 1,957-2,048 with 2 to 8.
  builder.SetSyncServerOption(
      grpc::ServerBuilder::SyncServerOption::MIN_POLLERS, 2);
  builder.SetSyncServerOption(
      grpc::ServerBuilder::SyncServerOption::MAX_POLLERS, 8);

  if (env->served_.exchange(true)) {
    return absl::FailedPreconditionError(
        "this RpcEnvironment already serves another ServiceServer; give each "
        "server an environment of its own");
  }
  // Installed before the server takes its first call, so that none runs
  // unchecked; removed (below, or by the destructor) only once no call can
  // be running.
  env->authorizer_.store(authorizer.get(), std::memory_order_release);
  const auto release = [env] {
    env->authorizer_.store(nullptr, std::memory_order_release);
    env->served_.store(false);
  };
  std::unique_ptr<grpc::Server> server = builder.BuildAndStart();
  if (server == nullptr || port == 0) {
    server.reset();
    release();
    // gRPC says no more than that; with TLS, a certificate and key that
    // do not belong together (or a key that is encrypted or not PEM) fail
    // here too.
    return absl::UnavailableError(absl::StrCat(
        "cannot listen on \"", options.listen_address,
        "\" (invalid address, or port already in use",
        tls ? absl::StrCat("; or --tls_cert ", options.tls_cert_file,
                           " and --tls_key ", options.tls_key_file,
                           " do not belong together, or the key is encrypted "
                           "or not PEM: gRPC's log above says which")
            : "",
        ")"));
  }
  const char* mode = !tls                                 ? "plaintext"
                     : options.tls_client_ca_file.empty() ? "TLS"
                                                          : "mutual TLS";
  // Built before the call: the authorizer is moved in the same argument
  // list, and argument evaluation order is unspecified.
  std::unique_ptr<MetricsServer> metrics;
  if (!options.metrics_listen.empty()) {
    absl::StatusOr<std::unique_ptr<MetricsServer>> started =
        MetricsServer::Start(options.metrics_listen, env->metrics());
    if (!started.ok()) {
      server->Shutdown();
      server->Wait();
      server.reset();
      release();
      return started.status();
    }
    metrics = *std::move(started);
  }
  std::string description = absl::StrCat(
      host, ":", port, " (", mode, ", ",
      authorizer ? absl::StrCat("roles from ", options.authz_file)
                 : std::string("authorization off"),
      metrics ? absl::StrCat(", metrics on ",
                             host_of(options.metrics_listen).empty()
                                 ? "every interface, port "
                                 : host_of(options.metrics_listen) + ":",
                             metrics->port())
              : std::string(),
      ")");
  auto result = std::unique_ptr<ServiceServer>(new ServiceServer(
      std::move(server), std::move(health_names), port,
      DialableAddress(options.listen_address, port), std::move(description),
      options.drain_timeout, env, std::move(authorizer), std::move(metrics)));
  result->SetServing(false);
  return result;
}

ServiceServer::ServiceServer(std::unique_ptr<grpc::Server> server,
                             std::vector<std::string> health_names, int port,
                             std::string address, std::string description,
                             absl::Duration drain_timeout, RpcEnvironment* env,
                             std::unique_ptr<Authorizer> authorizer,
                             std::unique_ptr<MetricsServer> metrics)
    : server_(std::move(server)),
      health_names_(std::move(health_names)),
      port_(port),
      address_(std::move(address)),
      description_(std::move(description)),
      env_(env),
      authorizer_(std::move(authorizer)),
      metrics_(std::move(metrics)),
      drain_timeout_(drain_timeout) {}

ServiceServer::~ServiceServer() {
  Shutdown();
  Wait();
  // No call is running any more: the authorizer can leave the environment
  // (and be freed with this server), and another server may take it.
  env_->authorizer_.store(nullptr, std::memory_order_release);
  env_->served_.store(false);
}

absl::Status ServiceServer::ReloadAuthorization() {
  if (!authorizer_) return absl::OkStatus();
  return authorizer_->Reload();
}

void ServiceServer::SetServing(bool serving) {
  absl::MutexLock lock(&mu_);
  if (shut_down_) return;
  grpc::HealthCheckServiceInterface* health = server_->GetHealthCheckService();
  health->SetServingStatus("", serving);
  for (const std::string& name : health_names_) {
    health->SetServingStatus(name, serving);
  }
}

void ServiceServer::Shutdown() {
  {
    absl::MutexLock lock(&mu_);
    if (shut_down_) return;
    shut_down_ = true;
  }
  // grpc::Server::Shutdown also flips health to NOT_SERVING, but only once
  // it starts; saying so first lets load balancers stop routing here early.
  grpc::HealthCheckServiceInterface* health = server_->GetHealthCheckService();
  health->SetServingStatus("", false);
  for (const std::string& name : health_names_) {
    health->SetServingStatus(name, false);
  }
  server_->Shutdown(absl::ToChronoTime(absl::Now() + drain_timeout_));
}

void ServiceServer::Wait() { server_->Wait(); }

namespace {

sigset_t TerminationSignals() {
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGTERM);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGHUP);  // reload the roles file
  return signals;
}

}  // namespace

void BlockTerminationSignals() {
  const sigset_t signals = TerminationSignals();
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);
}

absl::Status RunUntilSignal(ServiceServer& server) {
  const sigset_t signals = TerminationSignals();
  // sigwait is only defined for blocked signals; blocking again here is a
  // no-op when the main already did it.
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);
  int signal_number = 0;
  while (true) {
    if (const int error = sigwait(&signals, &signal_number); error != 0) {
      return absl::InternalError(
          absl::StrCat("sigwait failed: ", std::strerror(error)));
    }
    if (signal_number != SIGHUP) break;
    // Certificates and keys are read once, at start; only roles reload.
    std::string what = "no --authz_file: nothing to reload";
    if (server.authorization_on()) {
      const absl::Status reloaded = server.ReloadAuthorization();
      what = reloaded.ok() ? "roles reloaded"
                           : absl::StrCat("roles kept, reload failed: ",
                                          reloaded.ToString());
    }
    std::fprintf(stderr,
                 "bitewise: SIGHUP: %s (TLS certificates are read only at "
                 "start: restart to use renewed ones)\n",
                 what.c_str());
  }
  std::fprintf(stderr, "bitewise: received %s, draining (up to %s)\n",
               signal_number == SIGTERM ? "SIGTERM" : "SIGINT",
               absl::FormatDuration(server.drain_timeout()).c_str());
  const absl::Time start = absl::Now();
  server.Shutdown();
  server.Wait();
  std::fprintf(stderr, "bitewise: drained in %s; exiting\n",
               absl::FormatDuration(
                   absl::Trunc(absl::Now() - start, absl::Milliseconds(1)))
                   .c_str());
  return absl::OkStatus();
}

int ReportFatal(const char* program, const std::string& what,
                const absl::Status& status) {
  std::fprintf(
      stderr, "%s: %s: %s\n", program, what.c_str(),
      status.ToString(absl::StatusToStringMode::kWithNoExtraData).c_str());
  return 1;
}

}  // namespace bitewise
