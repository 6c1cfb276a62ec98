// UpdateJournal: a small local file of bandit updates not yet delivered. The
// meal library appends an update here when the BanditService cannot take it
// (down, network gone), and also an operator's answer as soon as it is given
// (it may still change until the next bite starts), so that no learning is
// lost when the process dies; the journal is delivered when the answer is
// final, when the next meal starts, or at the next run. Updates are
// idempotent per event_id, so delivering one twice is harmless; a later line
// for the same event supersedes the earlier ones (a changed answer).
//
// Format: one update per line, tab-separated: event_id, loss, then the post
// hoc values, all doubles printed with 17 significant digits so they read
// back exactly. Thread-safe; one process owns one journal file (programs
// take a JournalClaim at start).
#ifndef BITEWISE_CLIENTS_MEAL_UPDATE_JOURNAL_H_
#define BITEWISE_CLIENTS_MEAL_UPDATE_JOURNAL_H_

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/synchronization/mutex.h"

namespace bitewise::meals {

struct JournaledUpdate {
  std::string event_id;
  double loss = 0.0;
  std::vector<double> posthoc;
};

class UpdateJournal {
 public:
  explicit UpdateJournal(std::string path) : path_(std::move(path)) {}

  const std::string& path() const { return path_; }

  // Appends one update and flushes it to disk (fsync) before returning. A
  // write that fails part way is cut off again, and so is a line left cut
  // short before (a crash mid-write), so no line runs on from another.
  absl::Status Append(const JournaledUpdate& update);

  // FAILED_PRECONDITION naming the file unless the journal can be opened
  // for writing (a file made for the check is removed again). Callers check
  // at start: a journal found unwritable only when the BanditService is
  // down would lose the update it was for.
  absl::Status CheckWritable() const;

  // Every journaled update, oldest first. An absent file is an empty
  // journal; a malformed line is DATA_LOSS naming the line number; text
  // after the last newline (a line cut short, never acknowledged) is not
  // read.
  absl::StatusOr<std::vector<JournaledUpdate>> ReadAll() const;

  // Calls `deliver` for the last journaled update of each event, in order,
  // and rewrites the journal (atomically, by rename) with those that
  // failed. Returns how many were delivered.
  absl::StatusOr<int> Drain(
      const std::function<absl::Status(const JournaledUpdate&)>& deliver);

 private:
  absl::StatusOr<std::vector<JournaledUpdate>> ReadAllLocked() const
      ABSL_SHARED_LOCKS_REQUIRED(mu_);
  absl::Status Rewrite(const std::vector<JournaledUpdate>& updates)
      ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_);

  const std::string path_;
  mutable absl::Mutex mu_;
};

// A process's hold on a journal: an exclusive lock on "<journal>.lock"
// (flock, released when the process ends, however it ends), with the pid
// in the file for the message. Two processes draining and rewriting one
// journal would lose each other's updates; the second one to start is
// refused instead.
class JournalClaim {
 public:
  // FAILED_PRECONDITION naming the journal, the lock file and the holder's
  // pid when another process holds it, or when the lock file cannot be
  // made.
  static absl::StatusOr<std::unique_ptr<JournalClaim>> Take(
      const std::string& journal_path);
  ~JournalClaim();
  JournalClaim(const JournalClaim&) = delete;
  JournalClaim& operator=(const JournalClaim&) = delete;

 private:
  explicit JournalClaim(int fd) : fd_(fd) {}
  const int fd_;
};

}  // namespace bitewise::meals

#endif  // BITEWISE_CLIENTS_MEAL_UPDATE_JOURNAL_H_
