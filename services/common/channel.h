// Client side of the bitewise transport: opens channels to bitewise services
// (plaintext, TLS or mutual TLS, matching ServerOptions on the server) and
// waits for a service to report SERVING through grpc.health.v1, so clients
// and tests start calling only once the service is really ready.
#ifndef BITEWISE_SERVICES_COMMON_CHANNEL_H_
#define BITEWISE_SERVICES_COMMON_CHANNEL_H_

#include <grpcpp/channel.h>

#include <memory>
#include <string>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/time/time.h"

namespace bitewise {

// How a client connects. All empty means plaintext.
struct ChannelOptions {
  // PEM CA bundle that signed the server certificate. Setting it turns TLS
  // on; the system roots are never used, since bitewise links are private.
  std::string tls_ca_file;
  // PEM client certificate chain and key for mutual TLS. Both or neither;
  // they need tls_ca_file.
  std::string tls_cert_file;
  std::string tls_key_file;
  // Host name to check the server certificate against instead of the host in
  // the address; for dialing by IP a server whose certificate names a host.
  std::string tls_server_name_override;
  // Largest message accepted or sent, in bytes. Default 4 MiB, gRPC's own.
  int max_message_bytes = 4 << 20;
  // gRPC retry policy (the channel's service config), for every method:
  // a call that ends UNAVAILABLE (the server restarting, the link down, or
  // a service refusing for now, as the robot does while its F/T stream is
  // not sane) is tried again, up to `max_attempts` in all (gRPC caps it at
  // 5), after a random backoff below initial_backoff * 2^(n-1), at most
  // max_backoff. The call's deadline covers all attempts. 1: no retries
  // (the default; the services' own links fail fast).
  int max_attempts = 1;
  absl::Duration initial_backoff = absl::Milliseconds(500);
  absl::Duration max_backoff = absl::Seconds(4);
};

// Creates a channel to `address`: host:port, or several servers of one
// service (replicas) as "IPv4:PORT,IPv4:PORT" or "dns:///NAME:PORT" (every
// address of the name), whose calls are spread round robin over the servers
// that are up. With TLS, every replica's certificate must carry the name the
// client checks (tls_server_name_override for a list). Connection happens
// lazily, on the first call. Errors: INVALID_ARGUMENT for inconsistent
// options (also a max_attempts outside 1-5, backoffs that are not positive,
// or a list entry that is not IPv4:PORT); FAILED_PRECONDITION naming the file
// when a TLS file cannot be read.
absl::StatusOr<std::shared_ptr<grpc::Channel>> MakeChannel(
    const std::string& address, const ChannelOptions& options);

// grpc.health.v1 HealthCheckResponse.ServingStatus, with the same values.
enum class ServingStatus {
  kUnknown = 0,
  kServing = 1,
  kNotServing = 2,
  kServiceUnknown = 3,
};

// "SERVING", "NOT_SERVING", ...: the names grpc.health.v1 uses.
const char* ServingStatusName(ServingStatus status);

// One grpc.health.v1.Health/Check call for `service_name` ("" is the whole
// server). Errors are the call's own: UNAVAILABLE when the server cannot be
// reached, NOT_FOUND when the server does not know the name,
// DEADLINE_EXCEEDED after `timeout`, INTERNAL for an unparsable reply.
absl::StatusOr<ServingStatus> CheckHealth(
    const std::shared_ptr<grpc::Channel>& channel,
    const std::string& service_name, absl::Duration timeout);

// Polls CheckHealth until `service_name` reports SERVING. Returns
// DEADLINE_EXCEEDED, with the last observed status or error in the message,
// if that does not happen within `timeout`.
absl::Status WaitForServing(const std::shared_ptr<grpc::Channel>& channel,
                            const std::string& service_name,
                            absl::Duration timeout);

}  // namespace bitewise

#endif  // BITEWISE_SERVICES_COMMON_CHANNEL_H_
