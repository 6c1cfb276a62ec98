#include "services/bandit/store/context_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <string>

#include "absl/strings/str_cat.h"
#include "services/bandit/store/write_faults.h"
#include "services/common/status_macros.h"

namespace bitewise::bandit {
namespace {

constexpr char kHeader[ContextFile::kHeaderBytes + 1] = "bitewise ctx v1\n";

absl::Status WriteError(const std::string& path, absl::string_view what,
                        int error) {
  return FileWriteFault(what, path, error);
}

absl::Status WriteAll(int fd, absl::string_view bytes, int64_t offset,
                      const std::string& path) {
  while (!bytes.empty()) {
    const ssize_t n = pwrite(fd, bytes.data(), bytes.size(), offset);
    if (n < 0) {
      if (errno == EINTR) continue;
      return WriteError(path, "write to", errno);
    }
    bytes.remove_prefix(static_cast<size_t>(n));
    offset += n;
  }
  return absl::OkStatus();
}

absl::Status SyncDirectoryOf(const std::string& path) {
  const size_t slash = path.rfind('/');
  const std::string dir = slash == std::string::npos
                              ? "."
                              : path.substr(0, std::max<size_t>(slash, 1));
  const int fd = open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) return WriteError(dir, "open the directory", errno);
  const int rc = fsync(fd);
  const int error = errno;
  close(fd);
  if (rc != 0) return WriteError(dir, "sync the directory", error);
  return absl::OkStatus();
}

}  // namespace

absl::StatusOr<std::unique_ptr<ContextFile>> ContextFile::Open(
    const std::string& path, int64_t referenced_end) {
  int fd = open(path.c_str(), O_RDWR | O_CLOEXEC);
  if (fd < 0 && errno == ENOENT) {
    if (referenced_end > 0) {
      return absl::DataLossError(absl::StrCat(
          "the contexts file ", path, " is missing, but the database keeps ",
          referenced_end - kHeaderBytes,
          " bytes of events' contexts in it; restore it together with the "
          "database from the same backup"));
    }
    // Made whole under another name, then renamed: a crash meanwhile
    // leaves no header-less file under the real name.
    const std::string temporary = path + ".new";
    fd = open(temporary.c_str(), O_RDWR | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
    if (fd < 0) return WriteError(temporary, "create", errno);
    absl::Status made =
        WriteAll(fd, absl::string_view(kHeader, kHeaderBytes), 0, temporary);
    if (made.ok() && fdatasync(fd) != 0) {
      made = WriteError(temporary, "sync", errno);
    }
    if (made.ok() && rename(temporary.c_str(), path.c_str()) != 0) {
      made = WriteError(path, "rename a new file to", errno);
    }
    if (made.ok()) made = SyncDirectoryOf(path);
    if (!made.ok()) {
      close(fd);
      unlink(temporary.c_str());
      return made;
    }
  } else if (fd < 0) {
    return WriteError(path, "open", errno);
  }
  struct stat file {};
  if (fstat(fd, &file) != 0) {
    const absl::Status status = WriteError(path, "stat", errno);
    close(fd);
    return status;
  }
  char header[kHeaderBytes] = {};
  const ssize_t got = pread(fd, header, kHeaderBytes, 0);
  if (got != kHeaderBytes || std::memcmp(header, kHeader, kHeaderBytes) != 0) {
    close(fd);
    return absl::DataLossError(
        absl::StrCat(path,
                     " is not a bitewise contexts file (its first 16 bytes "
                     "are not \"bitewise ctx v1\")"));
  }
  // After everything the database refers to, even if the file lost its
  // end: a new context never lands where an old row still points.
  const int64_t end = std::max<int64_t>(
      {static_cast<int64_t>(file.st_size), referenced_end, kHeaderBytes});
  return std::unique_ptr<ContextFile>(
      new ContextFile(fd, path, end, static_cast<uint64_t>(file.st_dev),
                      static_cast<uint64_t>(file.st_ino)));
}

ContextFile::ContextFile(int fd, std::string path, int64_t end, uint64_t device,
                         uint64_t inode)
    : fd_(fd),
      path_(std::move(path)),
      end_(end),
      device_(device),
      inode_(inode) {}

ContextFile::~ContextFile() { close(fd_); }

absl::StatusOr<int64_t> ContextFile::Append(absl::string_view bytes) {
  // Each context starts a block: a block is written (and later freed)
  // whole, and never again for the next context, which does not share it.
  const int64_t offset = (end_ + kBlockBytes - 1) / kBlockBytes * kBlockBytes;
  // Advanced even when the write fails part-way: those bytes are never
  // referenced, and the next append starts after them.
  end_ = offset + static_cast<int64_t>(bytes.size());
  dirty_ = true;
  if (absl::Status written = WriteAll(fd_, bytes, offset, path_);
      !written.ok()) {
    return written;
  }
  return offset;
}

absl::Status ContextFile::Probe() {
  const std::string block(kBlockBytes, '\0');
  ASSIGN_OR_RETURN(const int64_t offset, Append(block));
  RETURN_IF_ERROR(Sync());
  return Erase({{offset, kBlockBytes}});
}

absl::Status ContextFile::Sync() {
  if (fdatasync(fd_) != 0) return WriteError(path_, "sync", errno);
  dirty_ = false;
  return absl::OkStatus();
}

std::string ContextFile::Read(int64_t offset, int64_t length) const {
  std::string out;
  // Never more than the file holds, whatever a damaged row says.
  struct stat file {};
  if (offset < kHeaderBytes || length <= 0 || fstat(fd_, &file) != 0 ||
      offset >= file.st_size) {
    return out;
  }
  length = std::min<int64_t>(length, file.st_size - offset);
  out.resize(static_cast<size_t>(length));
  size_t done = 0;
  while (done < out.size()) {
    const ssize_t n = pread(fd_, out.data() + done, out.size() - done,
                            offset + static_cast<int64_t>(done));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    done += static_cast<size_t>(n);
  }
  out.resize(done);
  return out;
}

absl::Status ContextFile::EraseAllBut(
    std::vector<std::pair<int64_t, int64_t>> live) {
  std::sort(live.begin(), live.end());
  std::vector<std::pair<int64_t, int64_t>> gaps;
  int64_t from = kHeaderBytes;
  auto gap_to = [&](int64_t to) {
    // Whole blocks only: a block a live context shares is kept.
    const int64_t start = (from + kBlockBytes - 1) / kBlockBytes * kBlockBytes;
    const int64_t stop = to / kBlockBytes * kBlockBytes;
    if (stop > start) gaps.emplace_back(start, stop - start);
  };
  for (const auto& [offset, length] : live) {
    gap_to(offset);
    from = std::max(from, offset + length);
  }
  struct stat file {};
  if (fstat(fd_, &file) != 0) return WriteError(path_, "stat", errno);
  // The tail, to the block boundary past the file's end.
  gap_to((static_cast<int64_t>(file.st_size) + kBlockBytes - 1) / kBlockBytes *
         kBlockBytes);
  return Erase(gaps);
}

absl::Status ContextFile::Erase(
    const std::vector<std::pair<int64_t, int64_t>>& ranges) {
  if (ranges.empty()) return absl::OkStatus();
  for (const auto& [offset, length] : ranges) {
    if (offset < kHeaderBytes || length <= 0) continue;
    // Partial blocks are zeroed and whole ones freed; where holes are not
    // supported, zeros are written instead.
    if (fallocate(fd_, FALLOC_FL_PUNCH_HOLE | FALLOC_FL_KEEP_SIZE, offset,
                  length) != 0) {
      if (errno != EOPNOTSUPP) return WriteError(path_, "erase in", errno);
      RETURN_IF_ERROR(WriteAll(
          fd_, std::string(static_cast<size_t>(length), '\0'), offset, path_));
    }
  }
  return Sync();
}

}  // namespace bitewise::bandit
