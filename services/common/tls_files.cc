#include "services/common/tls_files.h"

#include <cerrno>
#include <cstring>
#include <fstream>
#include <string>

#include "absl/strings/str_cat.h"

namespace bitewise {

absl::StatusOr<std::string> ReadPemFile(const std::string& path,
                                        absl::string_view what) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    return absl::FailedPreconditionError(absl::StrCat(
        "cannot read ", what, " file \"", path, "\": ", std::strerror(errno)));
  }
  // Read through the stream (not `<< in.rdbuf()`, which swallows a read
  // error such as a directory's and returns nothing) so that bad() tells.
  std::string contents;
  char buffer[4096];
  while (in.read(buffer, sizeof(buffer)) || in.gcount() > 0) {
    contents.append(buffer, in.gcount());
  }
  if (in.bad()) {
    return absl::FailedPreconditionError(
        absl::StrCat("error reading ", what, " file \"", path,
                     "\": ", std::strerror(errno)));
  }
  // An empty CA would make gRPC trust its default roots instead of the
  // pinned CA; an empty key or certificate is as surely a mistake.
  if (contents.empty()) {
    return absl::FailedPreconditionError(
        absl::StrCat(what, " file \"", path, "\" is empty"));
  }
  return contents;
}

}  // namespace bitewise
