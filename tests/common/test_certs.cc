#include "tests/common/test_certs.h"

#include <stdlib.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "absl/strings/str_cat.h"

namespace bitewise::testing {
namespace {

// Runs the openssl CLI into a fresh temporary directory.
void GenerateCerts(TestCerts& certs) {
  std::string dir_template =
      (std::filesystem::temp_directory_path() / "bitewise_common_test_XXXXXX")
          .string();
  if (mkdtemp(dir_template.data()) == nullptr) {
    certs.error = "mkdtemp failed";
    return;
  }
  certs.dir = dir_template;
  const std::string script = absl::StrCat(
      "cd '", certs.dir, "' && {",
      " openssl req -x509 -newkey rsa:2048 -nodes -days 2",
      "   -subj /CN=bitewise-test-ca -keyout ca.key -out ca.pem &&",
      " printf 'subjectAltName=DNS:localhost,IP:127.0.0.1\\n",
      "extendedKeyUsage=serverAuth\\n' > server.ext &&",
      " printf 'extendedKeyUsage=clientAuth\\n' > client.ext &&",
      " for who in server client; do",
      "   openssl req -newkey rsa:2048 -nodes -subj /CN=bitewise-$who",
      "     -keyout $who.key -out $who.csr &&",
      "   openssl x509 -req -in $who.csr -CA ca.pem -CAkey ca.key",
      "     -CAcreateserial -days 2 -extfile $who.ext -out $who.pem",
      "   || exit 1;", " done; } > openssl.log 2>&1");
  if (std::system(script.c_str()) != 0) {
    std::ifstream log(certs.Path("openssl.log"));
    std::stringstream log_text;
    log_text << log.rdbuf();
    certs.error = absl::StrCat(
        "openssl failed (it is required, not optional):\n", log_text.str());
  }
}

}  // namespace

std::string TestCerts::Path(const std::string& name) const {
  return absl::StrCat(dir, "/", name);
}

TestCerts::~TestCerts() {
  if (!dir.empty()) std::filesystem::remove_all(dir);
}

const TestCerts& Certs() {
  static TestCerts certs;
  static const bool generated = (GenerateCerts(certs), true);
  (void)generated;
  return certs;
}

ServerOptions TlsServerOptions(bool mutual) {
  const TestCerts& certs = Certs();
  ServerOptions options;
  options.tls_cert_file = certs.Path("server.pem");
  options.tls_key_file = certs.Path("server.key");
  if (mutual) options.tls_client_ca_file = certs.Path("ca.pem");
  return options;
}

ChannelOptions TlsChannelOptions(bool with_client_cert) {
  const TestCerts& certs = Certs();
  ChannelOptions options;
  options.tls_ca_file = certs.Path("ca.pem");
  if (with_client_cert) {
    options.tls_cert_file = certs.Path("client.pem");
    options.tls_key_file = certs.Path("client.key");
  }
  return options;
}

std::string WriteRoles(const std::string& text) {
  const std::string path = Certs().Path("roles.txt");
  std::ofstream(path, std::ios::trunc) << text;
  return path;
}

}  // namespace bitewise::testing
