// ServerOptionsFromFlags (services/common/server_flags.h): with no flags a
// service listens on loopback at its own port with ServerOptions' defaults,
// and each flag reaches its option.
#include "services/common/server_flags.h"

#include <string>

#include "absl/flags/declare.h"
#include "absl/flags/flag.h"
#include "absl/flags/reflection.h"
#include "absl/time/time.h"
#include "gtest/gtest.h"

ABSL_DECLARE_FLAG(std::string, metrics_listen);

namespace bitewise {
namespace {

TEST(ServerFlagsTest, NoFlagsMeanLoopbackOnTheServicesPortAndTheDefaults) {
  absl::FlagSaver saver;
  const ServerOptions defaults;
  const ServerOptions options = ServerOptionsFromFlags(50053);
  EXPECT_EQ(options.listen_address, "127.0.0.1:50053");
  EXPECT_EQ(ServerOptionsFromFlags(9).listen_address, "127.0.0.1:9");
  EXPECT_EQ(options.tls_cert_file, "");
  EXPECT_EQ(options.tls_key_file, "");
  EXPECT_EQ(options.tls_client_ca_file, "");
  EXPECT_EQ(options.max_message_bytes, defaults.max_message_bytes);
  EXPECT_EQ(options.drain_timeout, defaults.drain_timeout);
  EXPECT_EQ(options.allow_plaintext_remote, defaults.allow_plaintext_remote);
  EXPECT_EQ(options.authz_file, "");
  EXPECT_EQ(options.metrics_listen, "");
}

TEST(ServerFlagsTest, EachFlagReachesItsOption) {
  absl::FlagSaver saver;
  absl::SetFlag(&FLAGS_listen, "0.0.0.0:7000");
  absl::SetFlag(&FLAGS_tls_cert, "/etc/bitewise/server.pem");
  absl::SetFlag(&FLAGS_tls_key, "/etc/bitewise/server.key");
  absl::SetFlag(&FLAGS_tls_client_ca, "/etc/bitewise/clients.pem");
  absl::SetFlag(&FLAGS_max_message_bytes, 1234567);
  absl::SetFlag(&FLAGS_drain_timeout_s, 3);
  absl::SetFlag(&FLAGS_allow_plaintext_remote, true);
  absl::SetFlag(&FLAGS_authz_file, "/etc/bitewise/roles.textproto");
  absl::SetFlag(&FLAGS_metrics_listen, "127.0.0.1:9101");
  const ServerOptions options = ServerOptionsFromFlags(50053);
  EXPECT_EQ(options.listen_address, "0.0.0.0:7000");
  EXPECT_EQ(options.tls_cert_file, "/etc/bitewise/server.pem");
  EXPECT_EQ(options.tls_key_file, "/etc/bitewise/server.key");
  EXPECT_EQ(options.tls_client_ca_file, "/etc/bitewise/clients.pem");
  EXPECT_EQ(options.max_message_bytes, 1234567);
  EXPECT_EQ(options.drain_timeout, absl::Seconds(3));
  EXPECT_TRUE(options.allow_plaintext_remote);
  EXPECT_EQ(options.authz_file, "/etc/bitewise/roles.textproto");
  EXPECT_EQ(options.metrics_listen, "127.0.0.1:9101");
}

}  // namespace
}  // namespace bitewise
