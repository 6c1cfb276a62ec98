#include "clients/meal/update_journal.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <sstream>

#include "absl/container/flat_hash_map.h"
#include "absl/strings/ascii.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_split.h"
#include "absl/strings/strip.h"

namespace bitewise::meals {
namespace {

std::string FormatLine(const JournaledUpdate& update) {
  std::string line = absl::StrCat(update.event_id, "\t",
                                  absl::StrFormat("%.17g", update.loss));
  for (double p : update.posthoc) {
    absl::StrAppend(&line, "\t", absl::StrFormat("%.17g", p));
  }
  absl::StrAppend(&line, "\n");
  return line;
}

absl::Status WriteAllAndSync(int fd, const std::string& data,
                             const std::string& path) {
  size_t written = 0;
  while (written < data.size()) {
    const ssize_t n = ::write(fd, data.data() + written, data.size() - written);
    if (n < 0) {
      if (errno == EINTR) continue;
      return absl::InternalError(absl::StrCat("cannot write journal ", path,
                                              ": ", std::strerror(errno)));
    }
    written += static_cast<size_t>(n);
  }
  if (::fsync(fd) != 0) {
    return absl::InternalError(
        absl::StrCat("cannot sync journal ", path, ": ", std::strerror(errno)));
  }
  return absl::OkStatus();
}

}  // namespace

absl::Status UpdateJournal::Append(const JournaledUpdate& update) {
  absl::MutexLock lock(&mu_);
  const int fd = ::open(path_.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0600);
  if (fd < 0) {
    return absl::FailedPreconditionError(absl::StrCat(
        "cannot open journal ", path_, ": ", std::strerror(errno)));
  }
  // Where the last whole line ends: a line cut short by a failed write or
  // a crash mid-write (never acknowledged) is cut off, so that this one
  // does not run on from it.
  struct stat file {};
  off_t end = ::fstat(fd, &file) == 0 ? file.st_size : -1;
  char c = '\n';
  while (end > 0 && ::pread(fd, &c, 1, end - 1) == 1 && c != '\n') --end;
  absl::Status status =
      end < 0 ? absl::InternalError(absl::StrCat("cannot read journal ", path_,
                                                 ": ", std::strerror(errno)))
              : absl::OkStatus();
  if (status.ok() && end != file.st_size && ::ftruncate(fd, end) != 0) {
    status = absl::InternalError(
        absl::StrCat("cannot cut journal ", path_, ": ", std::strerror(errno)));
  }
  if (status.ok() && ::lseek(fd, end, SEEK_SET) != end) {
    status = absl::InternalError(absl::StrCat("cannot seek journal ", path_,
                                              ": ", std::strerror(errno)));
  }
  if (status.ok()) status = WriteAllAndSync(fd, FormatLine(update), path_);
  // A write that failed part way (a full disk) leaves nothing behind.
  if (!status.ok() && end >= 0 && ::ftruncate(fd, end) == 0) ::fsync(fd);
  ::close(fd);
  return status;
}

absl::StatusOr<std::unique_ptr<JournalClaim>> JournalClaim::Take(
    const std::string& journal_path) {
  const std::string lock_path = journal_path + ".lock";
  const int fd = ::open(lock_path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0600);
  if (fd < 0) {
    return absl::FailedPreconditionError(
        absl::StrCat("cannot make the journal's lock file ", lock_path, ": ",
                     std::strerror(errno)));
  }
  if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
    char holder[32] = {0};
    const ssize_t n = ::pread(fd, holder, sizeof(holder) - 1, 0);
    ::close(fd);
    return absl::FailedPreconditionError(absl::StrCat(
        "journal ", journal_path, " is in use by another process (pid ",
        n > 0 ? absl::StripAsciiWhitespace(holder) : "unknown", ", holding ",
        lock_path,
        "): one process per journal, or one would lose the other's "
        "updates; give this one a --journal of its own"));
  }
  const std::string pid = absl::StrCat(::getpid(), "\n");
  if (::ftruncate(fd, 0) != 0 || ::pwrite(fd, pid.data(), pid.size(), 0) !=
                                     static_cast<ssize_t>(pid.size())) {
    // The lock is what matters; the pid is for the message.
  }
  return std::unique_ptr<JournalClaim>(new JournalClaim(fd));
}

JournalClaim::~JournalClaim() { ::close(fd_); }

absl::Status UpdateJournal::CheckWritable() const {
  absl::MutexLock lock(&mu_);
  const bool existed = ::access(path_.c_str(), F_OK) == 0;
  const int fd =
      ::open(path_.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0600);
  if (fd < 0) {
    return absl::FailedPreconditionError(absl::StrCat(
        "cannot open journal ", path_, " for writing: ", std::strerror(errno),
        "; an update the BanditService cannot take would be lost"));
  }
  ::close(fd);
  if (!existed) ::unlink(path_.c_str());
  return absl::OkStatus();
}

absl::StatusOr<std::vector<JournaledUpdate>> UpdateJournal::ReadAll() const {
  absl::ReaderMutexLock lock(&mu_);
  return ReadAllLocked();
}

absl::StatusOr<std::vector<JournaledUpdate>> UpdateJournal::ReadAllLocked()
    const {
  std::vector<JournaledUpdate> out;
  std::ifstream in(path_);
  if (!in) {
    if (errno == ENOENT) return out;
    return absl::FailedPreconditionError(absl::StrCat(
        "cannot read journal ", path_, ": ", std::strerror(errno)));
  }
  const std::string text{std::istreambuf_iterator<char>(in),
                         std::istreambuf_iterator<char>()};
  std::vector<absl::string_view> lines = absl::StrSplit(text, '\n');
  // After the last newline: empty, or a line cut short by a write that
  // failed or a crash (never acknowledged), which is not read.
  lines.pop_back();
  int number = 0;
  for (absl::string_view line : lines) {
    ++number;
    if (line.empty()) continue;
    const std::vector<absl::string_view> fields = absl::StrSplit(line, '\t');
    JournaledUpdate update;
    bool ok = fields.size() >= 2 && !fields[0].empty() &&
              absl::SimpleAtod(fields[1], &update.loss);
    for (size_t i = 2; ok && i < fields.size(); ++i) {
      double value = 0.0;
      ok = absl::SimpleAtod(fields[i], &value);
      update.posthoc.push_back(value);
    }
    if (!ok) {
      return absl::DataLossError(
          absl::StrCat("journal ", path_, " line ", number, " is malformed"));
    }
    update.event_id = std::string(fields[0]);
    out.push_back(std::move(update));
  }
  return out;
}

absl::Status UpdateJournal::Rewrite(
    const std::vector<JournaledUpdate>& updates) {
  if (updates.empty()) {
    if (::unlink(path_.c_str()) != 0 && errno != ENOENT) {
      return absl::InternalError(absl::StrCat("cannot remove journal ", path_,
                                              ": ", std::strerror(errno)));
    }
    return absl::OkStatus();
  }
  const std::string tmp = path_ + ".tmp";
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
  if (fd < 0) {
    return absl::FailedPreconditionError(
        absl::StrCat("cannot open ", tmp, ": ", std::strerror(errno)));
  }
  std::string data;
  for (const JournaledUpdate& update : updates) data += FormatLine(update);
  absl::Status status = WriteAllAndSync(fd, data, tmp);
  ::close(fd);
  if (!status.ok()) return status;
  if (std::rename(tmp.c_str(), path_.c_str()) != 0) {
    return absl::InternalError(absl::StrCat("cannot replace journal ", path_,
                                            ": ", std::strerror(errno)));
  }
  return absl::OkStatus();
}

absl::StatusOr<int> UpdateJournal::Drain(
    const std::function<absl::Status(const JournaledUpdate&)>& deliver) {
  absl::MutexLock lock(&mu_);
  absl::StatusOr<std::vector<JournaledUpdate>> all = ReadAllLocked();
  if (!all.ok()) return all.status();
  if (all->empty()) return 0;
  // A later line for the same event (a changed answer) supersedes.
  absl::flat_hash_map<std::string, size_t> last;
  for (size_t i = 0; i < all->size(); ++i) last[(*all)[i].event_id] = i;
  std::vector<JournaledUpdate> failed;
  int delivered = 0;
  for (size_t i = 0; i < all->size(); ++i) {
    const JournaledUpdate& update = (*all)[i];
    if (last[update.event_id] != i) continue;
    if (deliver(update).ok()) {
      ++delivered;
    } else {
      failed.push_back(update);
    }
  }
  absl::Status status = Rewrite(failed);
  if (!status.ok()) return status;
  return delivered;
}

}  // namespace bitewise::meals
