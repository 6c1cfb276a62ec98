// Certificates for tests that run real servers over TLS: a CA, a server
// certificate for 127.0.0.1/localhost (CN bitewise-server) and a client
// certificate (CN bitewise-client), all signed by the CA, made once per
// test binary by the openssl CLI into a temporary directory, plus the server
// and channel options that use them and a roles file beside them.
#ifndef BITEWISE_TESTS_COMMON_TEST_CERTS_H_
#define BITEWISE_TESTS_COMMON_TEST_CERTS_H_

#include <string>

#include "services/common/channel.h"
#include "services/common/server.h"

namespace bitewise::testing {

struct TestCerts {
  std::string dir;
  std::string error;  // Empty when generation succeeded.

  std::string Path(const std::string& name) const;
  ~TestCerts();
};

// The binary's certificates, made on first use. Failure is recorded in
// `error`, not skipped: CI installs openssl, so its absence is a broken
// environment.
const TestCerts& Certs();

// The server's certificate; `mutual`: clients must present one of the CA's.
ServerOptions TlsServerOptions(bool mutual);
// Trusts the CA; `with_client_cert`: presents the client certificate.
ChannelOptions TlsChannelOptions(bool with_client_cert);
// Writes `text` as the roles file beside the certificates; returns its path.
std::string WriteRoles(const std::string& text);

}  // namespace bitewise::testing

#endif  // BITEWISE_TESTS_COMMON_TEST_CERTS_H_
