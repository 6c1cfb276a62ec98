// A user's bandit history as the offline tuner reads it: either an event
// log exported from the BanditService (one action and its loss per row), or
// a labelled dataset (the full loss vector per row). Two sources:
//  - the BanditService's SQLite file, read through SqliteEventStore (the
//    completed events of one user, in model order);
//  - a CSV file, the documented export format (docs/experiments.md):
//      item_label,action,propensity,loss,context,posthoc   (event log)
//      item_label,losses,context,posthoc                   (labelled)
//    one header line, then one row per round; vector columns hold numbers
//    separated by single spaces; lines starting with '#' are comments.
#ifndef BITEWISE_EXPERIMENTS_EVENT_LOG_H_
#define BITEWISE_EXPERIMENTS_EVENT_LOG_H_

#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"

namespace bitewise::experiments {

struct LoggedEvent {
  std::string item_label;  // the food: imputation groups by it
  std::vector<double> context;
  std::vector<double> posthoc;
  // Event log rows: the action taken, its propensity and loss.
  int action = -1;
  double propensity = 1.0;
  double loss = 0.0;
  // Labelled rows: every action's loss (empty for event log rows).
  std::vector<double> losses;
};

struct EventLog {
  int num_actions = 0;
  bool labelled = false;
  std::vector<LoggedEvent> events;
};

// Parses the CSV export format. `num_actions` is required for an event log
// (the log only names actions taken) and checked against a labelled file's
// loss vectors if positive. INVALID_ARGUMENT naming the line and column for
// anything malformed: unknown header, wrong field count, non-numbers, action
// out of range, loss outside [0, 1], propensity outside (0, 1], vectors whose
// length differs from the first row's.
absl::StatusOr<EventLog> ParseEventLogCsv(absl::string_view text,
                                          int num_actions);
absl::StatusOr<EventLog> ReadEventLogCsv(const std::string& path,
                                         int num_actions);

// The completed events of `user_id` in a BanditService SQLite file.
// NOT_FOUND if the file or the user does not exist (the file is never
// created).
absl::StatusOr<EventLog> ReadEventLogSqlite(const std::string& path,
                                            const std::string& user_id);

// The CSV export format of `log` (round-trips through ParseEventLogCsv).
std::string FormatEventLogCsv(const EventLog& log);

}  // namespace bitewise::experiments

#endif  // BITEWISE_EXPERIMENTS_EVENT_LOG_H_
