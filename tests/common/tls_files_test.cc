// ReadPemFile (services/common/tls_files.h): a file is read whole, byte for
// byte, and one that cannot be read (absent, a directory) or is empty is
// FAILED_PRECONDITION naming what it was for, the path and the OS error.
#include "services/common/tls_files.h"

#include <stdlib.h>

#include <fstream>
#include <string>

#include "absl/strings/str_cat.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace bitewise {
namespace {

using ::testing::HasSubstr;

std::string MakeTempDir() {
  std::string pattern = absl::StrCat(::testing::TempDir(), "/tls_files_XXXXXX");
  EXPECT_NE(mkdtemp(pattern.data()), nullptr);
  return pattern;
}

TEST(ReadPemFileTest, ReadsTheWholeFileByteForByte) {
  const std::string dir = MakeTempDir();
  // Longer than any stream buffer, with NULs, CRs and no final newline.
  std::string contents = "-----BEGIN CERTIFICATE-----\r\n";
  for (int i = 0; i < 20000; ++i)
    contents.push_back(static_cast<char>(i % 256));
  contents += "-----END CERTIFICATE-----";
  const std::string path = dir + "/cert.pem";
  std::ofstream(path, std::ios::binary) << contents;
  const absl::StatusOr<std::string> read = ReadPemFile(path, "TLS certificate");
  ASSERT_TRUE(read.ok()) << read.status();
  EXPECT_EQ(*read, contents);
}

TEST(ReadPemFileTest, AMissingFileIsNamedWithWhatItWasForAndTheOsError) {
  const std::string path = MakeTempDir() + "/absent.pem";
  const absl::Status status = ReadPemFile(path, "TLS client CA").status();
  EXPECT_EQ(status.code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(status.message(), HasSubstr("TLS client CA"));
  EXPECT_THAT(status.message(), HasSubstr(absl::StrCat("\"", path, "\"")));
  EXPECT_THAT(status.message(), HasSubstr("No such file or directory"));
}

// A directory opens like a file but cannot be read; taking it as an empty
// PEM would, for a client's CA, mean gRPC's default roots instead of the
// pinned CA.
TEST(ReadPemFileTest, ADirectoryIsNotReadAsAnEmptyFile) {
  const std::string dir = MakeTempDir();
  const absl::StatusOr<std::string> read = ReadPemFile(dir, "TLS CA");
  ASSERT_FALSE(read.ok()) << "read \"" << *read << "\"";
  EXPECT_EQ(read.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(read.status().message(), HasSubstr("TLS CA"));
  EXPECT_THAT(read.status().message(), HasSubstr(dir));
  EXPECT_THAT(read.status().message(), HasSubstr("Is a directory"));
}

// An empty file is refused: as a client's CA it would mean gRPC's default
// roots instead of the pinned CA.
TEST(ReadPemFileTest, AnEmptyFileIsRefused) {
  const std::string path = MakeTempDir() + "/empty.pem";
  std::ofstream(path, std::ios::binary).close();
  const absl::Status status = ReadPemFile(path, "TLS CA").status();
  EXPECT_EQ(status.code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_EQ(status.message(),
            absl::StrCat("TLS CA file \"", path, "\" is empty"));
}

}  // namespace
}  // namespace bitewise
