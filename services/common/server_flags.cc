#include "services/common/server_flags.h"

#include "absl/flags/flag.h"
#include "absl/strings/str_cat.h"
#include "absl/time/time.h"

ABSL_FLAG(std::string, listen, "",
          "host:port to listen on; empty means 127.0.0.1 and the service's "
          "default port. Use 0.0.0.0:<port> to accept remote clients.");
ABSL_FLAG(std::string, tls_cert, "",
          "PEM server certificate chain; with --tls_key turns on TLS.");
ABSL_FLAG(std::string, tls_key, "", "PEM private key for --tls_cert.");
ABSL_FLAG(std::string, tls_client_ca, "",
          "PEM CA bundle; when set, clients must present a certificate it "
          "signed (mutual TLS).");
ABSL_FLAG(int, max_message_bytes, 4 << 20,
          "Largest request or response message, in bytes.");
ABSL_FLAG(bool, allow_plaintext_remote, false,
          "Allow listening on a non-loopback address without TLS (refused by "
          "default: requests carry health data and move the robot).");
ABSL_FLAG(std::string, authz_file, "",
          "Roles file: which client certificate identity may call what "
          "(docs/security.md). Needs mutual TLS; re-read on SIGHUP. Empty: "
          "authorization off.");
ABSL_FLAG(std::string, metrics_listen, "",
          "Serve Prometheus metrics (docs/operations.md) on this host:port, "
          "e.g. 127.0.0.1:9101. Empty: no metrics endpoint.");
ABSL_FLAG(int, drain_timeout_s, 10,
          "Seconds in-flight calls may take to finish after SIGTERM.");

namespace bitewise {

ServerOptions ServerOptionsFromFlags(int default_port) {
  ServerOptions options;
  options.allow_plaintext_remote = absl::GetFlag(FLAGS_allow_plaintext_remote);
  options.authz_file = absl::GetFlag(FLAGS_authz_file);
  options.listen_address = absl::GetFlag(FLAGS_listen);
  if (options.listen_address.empty()) {
    options.listen_address = absl::StrCat("127.0.0.1:", default_port);
  }
  options.tls_cert_file = absl::GetFlag(FLAGS_tls_cert);
  options.tls_key_file = absl::GetFlag(FLAGS_tls_key);
  options.tls_client_ca_file = absl::GetFlag(FLAGS_tls_client_ca);
  options.max_message_bytes = absl::GetFlag(FLAGS_max_message_bytes);
  options.drain_timeout = absl::Seconds(absl::GetFlag(FLAGS_drain_timeout_s));
  options.metrics_listen = absl::GetFlag(FLAGS_metrics_listen);
  return options;
}

}  // namespace bitewise
