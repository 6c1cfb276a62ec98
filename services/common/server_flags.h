// Command-line flags shared by every bitewise service main, turned into
// ServerOptions in one place so all services spell and default them alike.
// Only mains link this; libraries take ServerOptions and never read flags.
#ifndef BITEWISE_SERVICES_COMMON_SERVER_FLAGS_H_
#define BITEWISE_SERVICES_COMMON_SERVER_FLAGS_H_

#include <string>

#include "absl/flags/declare.h"
#include "services/common/server.h"

ABSL_DECLARE_FLAG(std::string, listen);
ABSL_DECLARE_FLAG(std::string, tls_cert);
ABSL_DECLARE_FLAG(std::string, tls_key);
ABSL_DECLARE_FLAG(std::string, tls_client_ca);
ABSL_DECLARE_FLAG(int, max_message_bytes);
ABSL_DECLARE_FLAG(int, drain_timeout_s);
ABSL_DECLARE_FLAG(bool, allow_plaintext_remote);
ABSL_DECLARE_FLAG(std::string, authz_file);

namespace bitewise {

// Reads the flags above (after absl::ParseCommandLine). An empty --listen
// means 127.0.0.1:`default_port`, each service having its own well-known
// port.
ServerOptions ServerOptionsFromFlags(int default_port);

}  // namespace bitewise

#endif  // BITEWISE_SERVICES_COMMON_SERVER_FLAGS_H_
