#include "services/common/tls_files.h"

#include <sys/stat.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <string>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"

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

absl::Status CheckPrivateKeyMode(const std::string& path,
                                 absl::string_view what) {
  struct stat st;
  if (stat(path.c_str(), &st) != 0 || !S_ISREG(st.st_mode)) {
    return absl::OkStatus();  // ReadPemFile (or the library) names it
  }
  if ((st.st_mode & (S_IROTH | S_IWOTH)) == 0) return absl::OkStatus();
  return absl::FailedPreconditionError(absl::StrFormat(
      "%s file \"%s\" may be %s by every user of this machine (mode %04o): "
      "chmod o-rwx it and give it to the service's user only",
      what, path, (st.st_mode & S_IROTH) != 0 ? "read" : "overwritten",
      st.st_mode & 07777));
}

absl::StatusOr<std::string> ReadPrivateKeyFile(const std::string& path,
                                               absl::string_view what) {
  if (absl::Status mode = CheckPrivateKeyMode(path, what); !mode.ok()) {
    return mode;
  }
  return ReadPemFile(path, what);
}

}  // namespace bitewise
