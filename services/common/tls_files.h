// Reading the PEM files behind the TLS flags, shared by the server and the
// client channel so that both report an unreadable file the same way.
#ifndef BITEWISE_SERVICES_COMMON_TLS_FILES_H_
#define BITEWISE_SERVICES_COMMON_TLS_FILES_H_

#include <string>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"

namespace bitewise {

// The whole file. FAILED_PRECONDITION naming `what` (e.g. "server
// certificate"), the path and the OS error if it cannot be read, or saying
// it is empty (an empty CA would let gRPC fall back to its default roots).
absl::StatusOr<std::string> ReadPemFile(const std::string& path,
                                        absl::string_view what);

// A private key: as ReadPemFile, and FAILED_PRECONDITION, naming the file
// and its mode, when every user of the machine may read or write it (ssh
// refuses such a key too). A group may read it (Debian's ssl-cert group).
absl::StatusOr<std::string> ReadPrivateKeyFile(const std::string& path,
                                               absl::string_view what);
// The mode check alone, for a library that opens the key itself.
absl::Status CheckPrivateKeyMode(const std::string& path,
                                 absl::string_view what);

}  // namespace bitewise

#endif  // BITEWISE_SERVICES_COMMON_TLS_FILES_H_
