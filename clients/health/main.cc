// bitewise-health: asks a bitewise service for its grpc.health.v1 status and
// waits until it is SERVING. For start-up scripts, systemd and on-call
// engineers: exit 0 when serving, 1 otherwise, with the last status seen.
#include <cstdio>
#include <string>

#include "absl/flags/flag.h"
#include "absl/flags/usage.h"
#include "absl/time/time.h"
#include "services/common/channel.h"
#include "services/common/flags_usage.h"

ABSL_FLAG(std::string, address, "127.0.0.1:50051", "Service address.");
ABSL_FLAG(std::string, service, "",
          "Service name to check, e.g. bitewise.v1.BanditService; empty "
          "checks the server as a whole.");
ABSL_FLAG(double, timeout_s, 10.0, "How long to wait for SERVING.");
ABSL_FLAG(std::string, tls_ca, "", "CA bundle of the server (turns on TLS).");
ABSL_FLAG(std::string, tls_cert, "", "Client certificate (mutual TLS).");
ABSL_FLAG(std::string, tls_key, "", "Client key (mutual TLS).");

int main(int argc, char** argv) {
  absl::SetProgramUsageMessage(
      "Waits until a bitewise service reports SERVING.");
  bitewise::ShowOwnFlagsInHelp();
  bitewise::ParseFlagsOnly(argc, argv);
  // Exit codes: 0 SERVING; 1 not SERVING within --timeout_s (or no
  // answer); 2 a flag or TLS file it cannot use, before asking.
  if (const double timeout = absl::GetFlag(FLAGS_timeout_s);
      !(timeout > 0.0 && timeout <= 86400.0)) {
    std::fprintf(stderr,
                 "bitewise-health: --timeout_s must be above 0 and at most "
                 "86400 s, got %g\n",
                 timeout);
    return 2;
  }
  bitewise::ChannelOptions options;
  options.tls_ca_file = absl::GetFlag(FLAGS_tls_ca);
  options.tls_cert_file = absl::GetFlag(FLAGS_tls_cert);
  options.tls_key_file = absl::GetFlag(FLAGS_tls_key);
  const std::string address = absl::GetFlag(FLAGS_address);
  auto channel = bitewise::MakeChannel(address, options);
  if (!channel.ok()) {
    std::fprintf(stderr, "bitewise-health: %s\n",
                 channel.status().ToString().c_str());
    return 2;
  }
  const std::string service = absl::GetFlag(FLAGS_service);
  absl::Status status = bitewise::WaitForServing(
      *channel, service, absl::Seconds(absl::GetFlag(FLAGS_timeout_s)));
  if (!status.ok()) {
    std::fprintf(stderr, "bitewise-health: %s %s: %s\n", address.c_str(),
                 service.empty() ? "(server)" : service.c_str(),
                 status.ToString().c_str());
    return 1;
  }
  std::printf("%s %s: SERVING\n", address.c_str(),
              service.empty() ? "(server)" : service.c_str());
  return 0;
}
