// The lab's own haptic data: every Acquire's force/torque trace, recorded
// with its bite so that bitewise-haptic-train can retrain HapticNet on the
// lab's fork and foods (docs/haptic.md, "The lab's own data"). A recording
// is a directory of two files, appended to bite by bite:
//
//   traces.csv  the trainer's input format (services/domain/trace_csv.h):
//               one row per sample, the raw trace as the robot measured it,
//               labelled with the food's haptic class when it is known (the
//               simulation reports it) and "unknown" otherwise;
//   bites.csv   one row per trace: trace, time_utc, user, meal, event_id,
//               food, label, action, outcome, haptic (HapticNet's answer,
//               "none" if the HapticService did not answer), p_hard,
//               p_medium, p_soft, p_hard_skin, familiarity (the
//               HapticService's familiarity score) and unfamiliar (1 or 0),
//               both empty when the service did not answer or gave no
//               score, and force_limit_reached (1 when the descent stopped
//               at the action's force limit, cutting the trace short). A
//               lab labels its bites here, one row per bite, and passes the
//               file to the trainer with --labels.
//
// A bites.csv written by an earlier release (its header ends at unfamiliar,
// or at p_hard_skin before the familiarity columns) is kept in that format:
// rows appended to it have only its columns, so the file stays one table,
// and records_force_limit() (and records_familiarity()) is false; note()
// says so for the operator. A new directory gets the current header.
//
// Each bite is written with one write per file and fsync'd before Record
// returns. Trace ids continue across runs, so one directory can collect
// many meals. One process records into a directory at a time.
//
// Thread-safe.
#ifndef BITEWISE_CLIENTS_MEAL_TRACE_RECORDING_H_
#define BITEWISE_CLIENTS_MEAL_TRACE_RECORDING_H_

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "absl/base/thread_annotations.h"
#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/synchronization/mutex.h"
#include "bitewise/v1/common.pb.h"
#include "google/protobuf/repeated_ptr_field.h"
#include "services/domain/haptic_class.h"

namespace bitewise::meals {

// What is known of the bite a trace belongs to.
struct RecordedBite {
  std::string user_id;
  std::string meal_id;
  std::string event_id;
  std::string food;  // "" when unknown
  std::optional<domain::HapticClass> label;
  std::string action;   // "VS0", ...
  std::string outcome;  // success, failure, awaiting answer, ...
  // HapticNet's answer; empty when the HapticService did not answer, or
  // answered that the trace has no contact (`no_contact`).
  std::optional<domain::HapticClass> haptic;
  bool no_contact = false;
  std::vector<double> probabilities;  // 4 when `haptic` is set
  // The HapticService's familiarity score and its verdict; empty when the
  // service did not answer or gave no score (no familiarity model).
  std::optional<double> familiarity;
  bool unfamiliar = false;  // meaningful only with `familiarity`
  // The descent stopped at the action's force limit, so the trace is cut
  // short there (docs/haptic.md, "A trace the robot cut short").
  bool force_limit_reached = false;
};

class TraceRecording {
 public:
  // Opens (creating it and its files if need be) the recording in `dir`.
  // A bites.csv with the header of an earlier release is appended to in its
  // own format. INVALID_ARGUMENT naming the file if a
  // file there has any other header (a header saved with CRLF line ends
  // is its own); FAILED_PRECONDITION if another process records there
  // (the directory is flock'ed while open); INTERNAL naming the file if it
  // cannot be created or read. Trace rows without their bites.csv row (a
  // crash between the two writes) and a last row cut short are cut off.
  static absl::StatusOr<std::unique_ptr<TraceRecording>> Open(
      const std::string& dir);
  ~TraceRecording();

  // Appends `trace` with `bite`. Returns the trace's id. INVALID_ARGUMENT
  // for an empty trace or an id field holding a comma or a newline;
  // INTERNAL naming the file if a write or fsync fails (the bite's rows
  // are cut off again in both files, and the recording is then unusable:
  // what was written before stays readable).
  absl::StatusOr<std::string> Record(
      const RecordedBite& bite,
      const google::protobuf::RepeatedPtrField<v1::WrenchSample>& trace);

  const std::string& dir() const { return dir_; }
  int64_t recorded() const;  // traces recorded through this object

  // False when this directory's bites.csv predates the familiarity columns.
  bool records_familiarity() const { return records_familiarity_; }
  // False for a bites.csv started before the force_limit_reached column.
  bool records_force_limit() const { return records_force_limit_; }
  // What the operator should be told once, on opening: empty, or that
  // familiarity is not recorded in this directory and why.
  const std::string& note() const { return note_; }

 private:
  TraceRecording(std::string dir, int lock_fd, int traces_fd, int bites_fd,
                 int64_t next_id, bool records_familiarity,
                 bool records_force_limit);

  const std::string dir_;
  const int lock_fd_;  // the directory, flock'ed while it is recorded into
  const bool records_familiarity_;
  const bool records_force_limit_;
  std::string note_;  // set by Open, then only read
  mutable absl::Mutex mu_;
  int traces_fd_ ABSL_GUARDED_BY(mu_);
  int bites_fd_ ABSL_GUARDED_BY(mu_);
  int64_t next_id_ ABSL_GUARDED_BY(mu_);
  int64_t recorded_ ABSL_GUARDED_BY(mu_) = 0;
  bool broken_ ABSL_GUARDED_BY(mu_) = false;
};

}  // namespace bitewise::meals

#endif  // BITEWISE_CLIENTS_MEAL_TRACE_RECORDING_H_
