// UpdateJournal: a small local file of bandit updates that could not be
// delivered (BanditService down, network gone). The orchestrator appends an
// update here before giving up on it and delivers the journal at the start
// of the next run, so no learning is lost. Updates are idempotent per
// event_id, so delivering one twice is harmless.
//
// Format: one update per line, tab-separated: event_id, loss, then the post
// hoc values, all doubles printed with 17 significant digits so they read
// back exactly. Not thread-safe; one orchestrator owns one journal.
#ifndef BITEWISE_CLIENTS_ORCHESTRATOR_UPDATE_JOURNAL_H_
#define BITEWISE_CLIENTS_ORCHESTRATOR_UPDATE_JOURNAL_H_

#include <functional>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"

namespace bitewise::orchestrator {

struct JournaledUpdate {
  std::string event_id;
  double loss = 0.0;
  std::vector<double> posthoc;
};

class UpdateJournal {
 public:
  explicit UpdateJournal(std::string path) : path_(std::move(path)) {}

  const std::string& path() const { return path_; }

  // Appends one update and flushes it to disk (fsync) before returning.
  absl::Status Append(const JournaledUpdate& update);

  // Every journaled update, oldest first. An absent file is an empty
  // journal; a malformed line is DATA_LOSS naming the line number.
  absl::StatusOr<std::vector<JournaledUpdate>> ReadAll() const;

  // Calls `deliver` for each journaled update in order and rewrites the
  // journal (atomically, by rename) with those that failed. Returns how
  // many were delivered.
  absl::StatusOr<int> Drain(
      const std::function<absl::Status(const JournaledUpdate&)>& deliver);

 private:
  absl::Status Rewrite(const std::vector<JournaledUpdate>& updates);

  std::string path_;
};

}  // namespace bitewise::orchestrator

#endif  // BITEWISE_CLIENTS_ORCHESTRATOR_UPDATE_JOURNAL_H_
