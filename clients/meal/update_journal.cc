#include "clients/meal/update_journal.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>

#include "absl/container/flat_hash_map.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_split.h"

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
  const int fd = ::open(path_.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0600);
  if (fd < 0) {
    return absl::FailedPreconditionError(absl::StrCat(
        "cannot open journal ", path_, ": ", std::strerror(errno)));
  }
  absl::Status status = WriteAllAndSync(fd, FormatLine(update), path_);
  ::close(fd);
  return status;
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
  std::string line;
  int number = 0;
  while (std::getline(in, line)) {
    ++number;
    if (line.empty()) continue;
    const std::vector<std::string> fields = absl::StrSplit(line, '\t');
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
    update.event_id = fields[0];
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
