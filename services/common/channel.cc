#include "services/common/channel.h"

#include <arpa/inet.h>
#include <grpc/grpc.h>
#include <grpcpp/create_channel.h>
#include <grpcpp/generic/generic_stub.h>
#include <grpcpp/security/credentials.h>
#include <grpcpp/support/byte_buffer.h>
#include <grpcpp/support/channel_arguments.h>

#include <algorithm>
#include <cerrno>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <sstream>
#include <utility>
#include <vector>

#include "absl/strings/ascii.h"
#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "absl/strings/str_split.h"
#include "absl/strings/string_view.h"
#include "absl/synchronization/notification.h"
#include "absl/time/clock.h"
#include "services/common/grpc_status.h"
#include "services/common/status_macros.h"
#include "services/common/tls_files.h"

namespace bitewise {
namespace {

absl::StatusOr<std::shared_ptr<grpc::ChannelCredentials>> MakeCredentials(
    const ChannelOptions& options) {
  const bool has_ca = !options.tls_ca_file.empty();
  const bool has_cert = !options.tls_cert_file.empty();
  const bool has_key = !options.tls_key_file.empty();
  if (has_cert != has_key) {
    return absl::InvalidArgumentError(
        "mutual TLS needs both a client certificate file and a key file, got "
        "only one");
  }
  if (has_cert && !has_ca) {
    return absl::InvalidArgumentError(
        "a client certificate (mutual TLS) needs the server's CA file too");
  }
  if (!has_ca) return grpc::InsecureChannelCredentials();

  grpc::SslCredentialsOptions ssl;
  ASSIGN_OR_RETURN(ssl.pem_root_certs,
                   ReadPemFile(options.tls_ca_file, "TLS CA"));
  if (has_cert) {
    ASSIGN_OR_RETURN(ssl.pem_cert_chain,
                     ReadPemFile(options.tls_cert_file, "TLS certificate"));
    ASSIGN_OR_RETURN(ssl.pem_private_key,
                     ReadPrivateKeyFile(options.tls_key_file, "TLS key"));
  }
  return grpc::SslCredentials(ssl);
}

// grpc 1.51 installs no generated grpc.health.v1 client, and the two messages
// are tiny, so they are encoded by hand in protobuf wire format:
//   HealthCheckRequest  { string service = 1; }
//   HealthCheckResponse { ServingStatus status = 1; }
constexpr char kHealthCheckMethod[] = "/grpc.health.v1.Health/Check";

void AppendVarint(uint64_t value, std::string& out) {
  while (value >= 0x80) {
    out.push_back(static_cast<char>((value & 0x7f) | 0x80));
    value >>= 7;
  }
  out.push_back(static_cast<char>(value));
}

// Reads a varint at `pos`, advancing it; false on truncated or overlong input.
bool ReadVarint(absl::string_view bytes, size_t& pos, uint64_t& value) {
  value = 0;
  for (int shift = 0; shift < 64 && pos < bytes.size(); shift += 7) {
    const uint8_t byte = static_cast<uint8_t>(bytes[pos++]);
    value |= static_cast<uint64_t>(byte & 0x7f) << shift;
    if ((byte & 0x80) == 0) return true;
  }
  return false;
}

std::string EncodeHealthCheckRequest(const std::string& service_name) {
  std::string out;
  if (service_name.empty()) return out;  // proto3 omits default values.
  out.push_back(0x0a);                   // field 1, length-delimited.
  AppendVarint(service_name.size(), out);
  out += service_name;
  return out;
}

absl::StatusOr<ServingStatus> DecodeHealthCheckResponse(
    absl::string_view bytes) {
  uint64_t status = 0;  // Absent field means UNKNOWN.
  size_t pos = 0;
  while (pos < bytes.size()) {
    uint64_t tag = 0;
    if (!ReadVarint(bytes, pos, tag)) break;
    const uint64_t field = tag >> 3;
    const uint64_t wire_type = tag & 7;
    uint64_t value = 0;
    bool ok = true;
    switch (wire_type) {
      case 0:  // varint
        ok = ReadVarint(bytes, pos, value);
        if (ok && field == 1) status = value;
        break;
      case 1:  // fixed64
        pos += 8;
        break;
      case 2:  // length-delimited
        ok = ReadVarint(bytes, pos, value) && value <= bytes.size() - pos;
        pos += value;
        break;
      case 5:  // fixed32
        pos += 4;
        break;
      default:
        ok = false;
    }
    if (!ok || pos > bytes.size()) {
      return absl::InternalError("malformed grpc.health.v1 response");
    }
  }
  if (status > static_cast<uint64_t>(ServingStatus::kServiceUnknown)) {
    return ServingStatus::kUnknown;
  }
  return static_cast<ServingStatus>(status);
}

// The channel's service config: round robin over the resolved addresses
// when `balanced`, and, with retries, a policy that retries every method on
// UNAVAILABLE (an empty name matches all services and methods) but the
// robot's motions: an Acquire or a CaptureFrame (which may move the arm to
// its viewing pose) that failed UNAVAILABLE has halted the arm, and is never
// sent again without the person (a method's own entry, with no policy,
// takes precedence over the default). Empty when there is nothing to say.
std::string ServiceConfig(const ChannelOptions& options, bool balanced) {
  std::vector<std::string> parts;
  if (balanced)
    parts.push_back(R"("loadBalancingConfig": [{"round_robin": {}}])");
  if (options.max_attempts > 1) {
    parts.push_back(absl::StrCat(
        R"("methodConfig": [{"name": [{}], "retryPolicy": {"maxAttempts": )",
        options.max_attempts, R"(, "initialBackoff": ")",
        absl::StrFormat("%.3f", absl::ToDoubleSeconds(options.initial_backoff)),
        R"(s", "maxBackoff": ")",
        absl::StrFormat("%.3f", absl::ToDoubleSeconds(options.max_backoff)),
        R"(s", "backoffMultiplier": 2, "retryableStatusCodes": ["UNAVAILABLE"]}}, )",
        R"({"name": [{"service": "bitewise.v1.RobotService", "method": )",
        R"("Acquire"}, {"service": "bitewise.v1.RobotService", "method": )",
        R"("CaptureFrame"}]}])"));
  }
  if (parts.empty()) return "";
  return absl::StrCat("{", absl::StrJoin(parts, ", "), "}");
}

// The gRPC target for `address`, and whether calls are spread over several
// servers: "a:p,b:p" (numeric IPv4 addresses; localhost is 127.0.0.1) and
// "dns:///name:port" (every address the name resolves to) are.
absl::StatusOr<std::string> Target(const std::string& address, bool* balanced) {
  *balanced = false;
  if (absl::StartsWith(address, "dns:///")) {
    *balanced = true;
    return address;
  }
  if (!absl::StrContains(address, ',')) return address;
  std::vector<std::string> endpoints;
  for (absl::string_view entry : absl::StrSplit(address, ',')) {
    std::string endpoint(absl::StripAsciiWhitespace(entry));
    if (absl::StartsWith(endpoint, "localhost:")) {
      endpoint = absl::StrCat("127.0.0.1", endpoint.substr(9));
    }
    const size_t colon = endpoint.rfind(':');
    in_addr ignored{};
    int port = 0;
    if (colon == std::string::npos ||
        inet_pton(AF_INET, endpoint.substr(0, colon).c_str(), &ignored) != 1 ||
        !absl::SimpleAtoi(endpoint.substr(colon + 1), &port) || port <= 0 ||
        port > 65535) {
      return absl::InvalidArgumentError(absl::StrCat(
          "\"", endpoint, "\" in the address list \"", address,
          "\": each entry must be IPv4:PORT (for host names, give one name "
          "with several DNS records as dns:///NAME:PORT)"));
    }
    endpoints.push_back(endpoint);
  }
  *balanced = true;
  return absl::StrCat("ipv4:", absl::StrJoin(endpoints, ","));
}

}  // namespace

absl::StatusOr<std::shared_ptr<grpc::Channel>> MakeChannel(
    const std::string& address, const ChannelOptions& options) {
  if (options.max_message_bytes <= 0) {
    return absl::InvalidArgumentError(absl::StrCat(
        "max_message_bytes must be positive, got ", options.max_message_bytes));
  }
  ASSIGN_OR_RETURN(std::shared_ptr<grpc::ChannelCredentials> credentials,
                   MakeCredentials(options));
  if (options.max_attempts < 1 || options.max_attempts > 5) {
    return absl::InvalidArgumentError(absl::StrCat(
        "max_attempts must be 1-5 (gRPC's cap), got ", options.max_attempts));
  }
  if (options.initial_backoff <= absl::ZeroDuration() ||
      options.max_backoff < options.initial_backoff) {
    return absl::InvalidArgumentError(
        "retry backoffs must be positive, the maximum at least the initial");
  }
  bool balanced = false;
  ASSIGN_OR_RETURN(const std::string target, Target(address, &balanced));
  grpc::ChannelArguments args;
  if (options.max_attempts > 1) args.SetInt(GRPC_ARG_ENABLE_RETRIES, 1);
  if (const std::string config = ServiceConfig(options, balanced);
      !config.empty()) {
    args.SetServiceConfigJSON(config);
  }
  args.SetMaxReceiveMessageSize(options.max_message_bytes);
  args.SetMaxSendMessageSize(options.max_message_bytes);
  if (!options.tls_server_name_override.empty()) {
    args.SetSslTargetNameOverride(options.tls_server_name_override);
  }
  return grpc::CreateCustomChannel(target, credentials, args);
}

const char* ServingStatusName(ServingStatus status) {
  switch (status) {
    case ServingStatus::kServing:
      return "SERVING";
    case ServingStatus::kNotServing:
      return "NOT_SERVING";
    case ServingStatus::kServiceUnknown:
      return "SERVICE_UNKNOWN";
    case ServingStatus::kUnknown:
      break;
  }
  return "UNKNOWN";
}

absl::StatusOr<ServingStatus> CheckHealth(
    const std::shared_ptr<grpc::Channel>& channel,
    const std::string& service_name, absl::Duration timeout) {
  const std::string request_bytes = EncodeHealthCheckRequest(service_name);
  grpc::Slice request_slice(request_bytes);
  grpc::ByteBuffer request(&request_slice, 1);
  grpc::ByteBuffer response;
  grpc::ClientContext context;
  context.set_deadline(absl::ToChronoTime(absl::Now() + timeout));

  grpc::GenericStub stub(channel);
  grpc::Status call_status;
  absl::Notification done;
  stub.UnaryCall(&context, kHealthCheckMethod, grpc::StubOptions(), &request,
                 &response, [&](grpc::Status status) {
                   call_status = std::move(status);
                   done.Notify();
                 });
  done.WaitForNotification();
  RETURN_IF_ERROR(FromGrpcStatus(call_status));

  grpc::Slice response_slice;
  RETURN_IF_ERROR(FromGrpcStatus(response.DumpToSingleSlice(&response_slice)));
  return DecodeHealthCheckResponse(
      absl::string_view(reinterpret_cast<const char*>(response_slice.begin()),
                        response_slice.size()));
}

absl::Status WaitForServing(const std::shared_ptr<grpc::Channel>& channel,
                            const std::string& service_name,
                            absl::Duration timeout) {
  const absl::Time deadline = absl::Now() + timeout;
  std::string last = "no answer";
  while (true) {
    const absl::Duration remaining = deadline - absl::Now();
    if (remaining <= absl::ZeroDuration()) break;
    // Short per-call deadlines so one hung attempt cannot eat the budget.
    absl::StatusOr<ServingStatus> status = CheckHealth(
        channel, service_name, std::min(remaining, absl::Seconds(1)));
    if (status.ok() && *status == ServingStatus::kServing) {
      return absl::OkStatus();
    }
    last =
        status.ok() ? ServingStatusName(*status) : status.status().ToString();
    absl::SleepFor(std::min(deadline - absl::Now(), absl::Milliseconds(50)));
  }
  return absl::DeadlineExceededError(
      absl::StrCat("service \"", service_name, "\" not SERVING after ",
                   absl::FormatDuration(timeout), "; last: ", last));
}

}  // namespace bitewise
