// ContextFile (context_file.h) on real files: its header, block-aligned
// appends read back, erasure, and files that are missing, foreign or
// shorter than the database says.
#include "services/bandit/store/context_file.h"

#include <stdlib.h>
#include <sys/stat.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <memory>
#include <string>

#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "tests/common/status_matchers.h"

namespace bitewise::bandit {
namespace {

using ::bitewise::testing::IsOk;
using ::bitewise::testing::StatusIs;
using ::testing::AllOf;
using ::testing::HasSubstr;

constexpr int64_t kBlock = ContextFile::kBlockBytes;
const std::string kHeader = "bitewise ctx v1\n";

std::string FileBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

void WriteFile(const std::string& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << bytes;
}

class ContextFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string base = ::testing::TempDir();
    if (base.empty() || base.back() != '/') base += '/';
    std::string pattern = base + "context_file_XXXXXX";
    ASSERT_NE(mkdtemp(pattern.data()), nullptr) << pattern;
    dir_ = pattern;
    path_ = dir_ + "/bandit.db.contexts";
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  std::unique_ptr<ContextFile> MustOpen(int64_t referenced_end = 0) {
    absl::StatusOr<std::unique_ptr<ContextFile>> file =
        ContextFile::Open(path_, referenced_end);
    EXPECT_THAT(file, IsOk());
    return file.ok() ? std::move(file).value() : nullptr;
  }

  int64_t MustAppend(ContextFile& file, const std::string& bytes) {
    absl::StatusOr<int64_t> offset = file.Append(bytes);
    EXPECT_THAT(offset, IsOk());
    return offset.ok() ? *offset : -1;
  }

  std::string dir_;
  std::string path_;
};

TEST_F(ContextFileTest, ANewFileIsItsHeaderAloneAndOwnerOnly) {
  std::unique_ptr<ContextFile> file = MustOpen();
  ASSERT_NE(file, nullptr);
  EXPECT_EQ(file->path(), path_);
  EXPECT_EQ(FileBytes(path_), kHeader);
  EXPECT_FALSE(std::filesystem::exists(path_ + ".new"));
  struct stat info {};
  ASSERT_EQ(stat(path_.c_str(), &info), 0);
  EXPECT_EQ(info.st_mode & 0777, 0600u);
  EXPECT_EQ(file->inode(), static_cast<uint64_t>(info.st_ino));
  EXPECT_EQ(file->device(), static_cast<uint64_t>(info.st_dev));
  EXPECT_FALSE(file->dirty());
}

TEST_F(ContextFileTest, EachContextStartsABlockAndReadsBackAfterReopening) {
  const std::string small = "abc";
  const std::string large(5000, 'L');
  const std::string block(kBlock, 'B');
  {
    std::unique_ptr<ContextFile> file = MustOpen();
    ASSERT_NE(file, nullptr);
    EXPECT_EQ(MustAppend(*file, small), kBlock);
    EXPECT_TRUE(file->dirty());
    EXPECT_EQ(MustAppend(*file, large), 2 * kBlock);
    // 2 blocks + 5000 bytes end inside the fourth block: the next starts
    // the fifth.
    EXPECT_EQ(MustAppend(*file, block), 4 * kBlock);
    ASSERT_THAT(file->Sync(), IsOk());
    EXPECT_FALSE(file->dirty());
    EXPECT_EQ(file->Read(kBlock, 3), small);
    EXPECT_EQ(file->Read(2 * kBlock, 5000), large);
  }
  const std::string bytes = FileBytes(path_);
  ASSERT_EQ(bytes.size(), static_cast<size_t>(5 * kBlock));
  EXPECT_EQ(bytes.substr(0, 16), kHeader);
  EXPECT_EQ(bytes.substr(16, kBlock - 16), std::string(kBlock - 16, '\0'));
  EXPECT_EQ(bytes.substr(kBlock, 3), small);

  std::unique_ptr<ContextFile> file = MustOpen(5 * kBlock);
  ASSERT_NE(file, nullptr);
  EXPECT_EQ(file->Read(kBlock, 3), small);
  EXPECT_EQ(file->Read(2 * kBlock, 5000), large);
  EXPECT_EQ(file->Read(4 * kBlock, kBlock), block);
  // Appends go after everything already there.
  EXPECT_EQ(MustAppend(*file, small), 5 * kBlock);
}

TEST_F(ContextFileTest, ReadsNeverReachPastTheFileOrIntoTheHeader) {
  std::unique_ptr<ContextFile> file = MustOpen();
  ASSERT_NE(file, nullptr);
  const int64_t at = MustAppend(*file, "0123456789");
  EXPECT_EQ(file->Read(0, 16), "");  // the header is not a context
  EXPECT_EQ(file->Read(15, 4), "");
  EXPECT_EQ(file->Read(at, 0), "");
  EXPECT_EQ(file->Read(at, -5), "");
  EXPECT_EQ(file->Read(at + 6, 1000), "6789");  // cut at the file's end
  EXPECT_EQ(file->Read(at + 10, 1), "");
  EXPECT_EQ(file->Read(1 << 30, 8), "");
}

TEST_F(ContextFileTest, AMissingFileTheDatabaseReliesOnIsDataLoss) {
  EXPECT_THAT(ContextFile::Open(path_, 3 * kBlock),
              StatusIs(absl::StatusCode::kDataLoss,
                       AllOf(HasSubstr(path_), HasSubstr("is missing"),
                             HasSubstr("12272 bytes"))));
  // Nothing is made in its place.
  EXPECT_FALSE(std::filesystem::exists(path_));
  EXPECT_FALSE(std::filesystem::exists(path_ + ".new"));
}

TEST_F(ContextFileTest, AForeignOrShortFileIsDataLossAndLeftAsItWas) {
  for (const std::string& bytes :
       {std::string("SQLite format 3\0 and more bytes after it", 40),
        std::string("bitewise ctx v2\n"), std::string("bitewise"),
        std::string()}) {
    WriteFile(path_, bytes);
    EXPECT_THAT(ContextFile::Open(path_, 0),
                StatusIs(absl::StatusCode::kDataLoss,
                         AllOf(HasSubstr(path_),
                               HasSubstr("is not a bitewise contexts file"))))
        << bytes;
    EXPECT_EQ(FileBytes(path_), bytes);
  }
}

TEST_F(ContextFileTest, AFileThatCannotBeMadeIsUnavailableNamingIt) {
  path_ = dir_ + "/no/such/dir/bandit.db.contexts";
  EXPECT_THAT(
      ContextFile::Open(path_, 0),
      StatusIs(absl::StatusCode::kUnavailable,
               AllOf(HasSubstr("cannot create"), HasSubstr(path_ + ".new"))));
}

TEST_F(ContextFileTest, AppendsGoAfterWhatTheDatabaseReferences) {
  ASSERT_NE(MustOpen(), nullptr);  // the header alone
  // The database points further than the file holds (the file lost its
  // end): a new context must not land under an old row.
  std::unique_ptr<ContextFile> file = MustOpen(2 * kBlock + 100);
  ASSERT_NE(file, nullptr);
  EXPECT_EQ(MustAppend(*file, "x"), 3 * kBlock);
  file->ExtendTo(7 * kBlock + 1);
  EXPECT_EQ(MustAppend(*file, "y"), 8 * kBlock);
  file->ExtendTo(kBlock);  // never backwards
  EXPECT_EQ(MustAppend(*file, "z"), 9 * kBlock);
}

TEST_F(ContextFileTest, ErasedContextsReadAsZerosAndTheirPlaceIsNotReused) {
  std::unique_ptr<ContextFile> file = MustOpen();
  ASSERT_NE(file, nullptr);
  const std::string a(kBlock, 'a'), b(300, 'b');
  const int64_t at_a = MustAppend(*file, a);
  const int64_t at_b = MustAppend(*file, b);
  ASSERT_THAT(file->Sync(), IsOk());
  ASSERT_THAT(file->Erase({{at_a, kBlock}}), IsOk());
  EXPECT_EQ(file->Read(at_a, kBlock), std::string(kBlock, '\0'));
  EXPECT_EQ(file->Read(at_b, 300), b);
  EXPECT_EQ(FileBytes(path_).substr(0, 16), kHeader);
  // Ranges in the header or empty ones are ignored.
  ASSERT_THAT(file->Erase({{0, 16}, {at_b, 0}}), IsOk());
  EXPECT_EQ(FileBytes(path_).substr(0, 16), kHeader);
  EXPECT_EQ(file->Read(at_b, 300), b);
  EXPECT_EQ(MustAppend(*file, "c"), at_b + kBlock);
}

TEST_F(ContextFileTest, EraseAllButKeepsOnlyTheBlocksOfLiveContexts) {
  std::unique_ptr<ContextFile> file = MustOpen();
  ASSERT_NE(file, nullptr);
  const std::string a(100, 'a'), b(kBlock + 10, 'b'), c(200, 'c'), d(50, 'd');
  const int64_t at_a = MustAppend(*file, a);
  const int64_t at_b = MustAppend(*file, b);
  const int64_t at_c = MustAppend(*file, c);
  const int64_t at_d = MustAppend(*file, d);
  ASSERT_THAT(file->Sync(), IsOk());
  // Live: b (two blocks) and d, given out of order.
  ASSERT_THAT(file->EraseAllBut({{at_d, 50}, {at_b, kBlock + 10}}), IsOk());
  EXPECT_EQ(file->Read(at_a, 100), std::string(100, '\0'));
  EXPECT_EQ(file->Read(at_b, kBlock + 10), b);
  EXPECT_EQ(file->Read(at_c, 200), std::string(200, '\0'));
  EXPECT_EQ(file->Read(at_d, 50), d);
  EXPECT_EQ(FileBytes(path_).substr(0, 16), kHeader);
  // Nothing live: everything but the header goes.
  ASSERT_THAT(file->EraseAllBut({}), IsOk());
  const std::string bytes = FileBytes(path_);
  EXPECT_EQ(bytes.substr(0, 16), kHeader);
  EXPECT_EQ(bytes.find_first_not_of('\0', 16), std::string::npos);
}

TEST_F(ContextFileTest, AProbeWritesABlockAndLeavesNothingBehind) {
  std::unique_ptr<ContextFile> file = MustOpen();
  ASSERT_NE(file, nullptr);
  const int64_t at = MustAppend(*file, "kept");
  ASSERT_THAT(file->Probe(), IsOk());
  EXPECT_FALSE(file->dirty());
  EXPECT_EQ(file->Read(at, 4), "kept");
  const std::string bytes = FileBytes(path_);
  EXPECT_EQ(bytes.size(), static_cast<size_t>(3 * kBlock));
  EXPECT_EQ(bytes.find_first_not_of('\0', 2 * kBlock), std::string::npos);
  // The probe's block is never handed out again.
  EXPECT_EQ(MustAppend(*file, "next"), 3 * kBlock);
}

}  // namespace
}  // namespace bitewise::bandit
