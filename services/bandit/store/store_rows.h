// Store rows (internal to services/bandit/store): the encodings and row
// readers both EventStore implementations share, so a SQLite file and a
// PostgreSQL database hold the same bytes for the same user: vectors as
// little-endian float64 arrays, priors as one such array, timestamps in
// whole microseconds, page tokens in one opaque format, and the same
// checksums checked the same way on every read.
//
// ReadUserRow and ReadEventRow take any row type with the accessors
// IsNull(col), Int64(col), Double(col), Text(col) and Blob(col), over the
// columns of the stores' kUserColumns and kEventColumns in that order.
#ifndef BITEWISE_SERVICES_BANDIT_STORE_STORE_ROWS_H_
#define BITEWISE_SERVICES_BANDIT_STORE_STORE_ROWS_H_

#include <cstdint>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "absl/functional/function_ref.h"
#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"
#include "absl/time/time.h"
#include "services/bandit/store/event_checksum.h"
#include "services/bandit/store/event_store.h"
#include "services/common/status_macros.h"

namespace bitewise::bandit::store_rows {

inline int64_t ToMicros(absl::Time t) { return absl::ToUnixMicros(t); }
inline absl::Time FromMicros(int64_t us) { return absl::FromUnixMicros(us); }

// Byte by byte so the stored bytes read the same on any host.
std::string EncodeDoubles(const std::vector<double>& values);
absl::StatusOr<std::vector<double>> DecodeDoubles(absl::string_view bytes,
                                                  absl::string_view what);

// A population prior as one float64 array: pool_version, rounds,
// context_msn, posthoc_msn, K, d, q, then theta0 (K x d) and phi0 (K x q).
std::string EncodePrior(const PopulationPrior& prior);
absl::StatusOr<PopulationPrior> DecodePrior(absl::string_view bytes,
                                            absl::string_view what);

// Page tokens are opaque to clients: a kind tag ('u' users, 'e' events,
// 'a' audit) keeps one listing's token from being replayed against another,
// and base64 keeps arbitrary user ids printable.
std::string MakePageToken(char kind, absl::string_view key);
absl::StatusOr<std::string> ParsePageToken(const std::string& token, char kind);
// The id after which a page of events ('e') or audit entries ('a') goes on.
absl::StatusOr<int64_t> ParseIdPageToken(const std::string& token, char kind);

// About the encoded size of a user (ListUsers) and of an event
// (ListEvents): their strings and doubles and some overhead.
int64_t ApproxBytes(const UserRecord& user);
int64_t ApproxBytes(const EventRecord& event);
// Page.page_size clamped to [1, 1000] (0 or less: 100).
int ClampPageSize(int page_size);

// One page of a listing, built from rows read with a limit of page_size()
// + 1 (the extra row only says there is more). Before decoding a row, ask
// Room(); after, Add() it with its size. Either returns false, with the
// next page's token set from the last item kept, when the page is done.
template <typename T>
class PageBuilder {
 public:
  // `key(item)` is what the next page starts after, under the token `kind`.
  PageBuilder(const Page& page, char kind,
              std::function<std::string(const T&)> key)
      : page_(page),
        page_size_(ClampPageSize(page.page_size)),
        kind_(kind),
        key_(std::move(key)) {}

  int page_size() const { return page_size_; }

  bool Room() {
    if (static_cast<int>(result_.items.size()) < page_size_) return true;
    End();
    return false;
  }

  // `bytes`: the item's approximate encoded size (0: no byte budget).
  bool Add(T item, int64_t bytes) {
    // Past the byte budget ends the page, never before its first item.
    if (page_.max_bytes > 0 && !result_.items.empty() &&
        bytes_ + bytes > page_.max_bytes) {
      End();
      return false;
    }
    bytes_ += bytes;
    result_.items.push_back(std::move(item));
    return true;
  }

  PageResult<T> Take() { return std::move(result_); }

 private:
  void End() {
    result_.next_page_token = MakePageToken(kind_, key_(result_.items.back()));
  }

  const Page page_;
  const int page_size_;
  const char kind_;
  const std::function<std::string(const T&)> key_;
  int64_t bytes_ = 0;
  PageResult<T> result_;
};

// CheckStore's report, filled as every row is read back: damaged data
// (DATA_LOSS) is a finding (at most 100); any other error means the check
// could not run and is returned.
class CheckReportBuilder {
 public:
  explicit CheckReportBuilder(std::vector<std::string> findings = {});
  // A user read back; its configuration is validated too.
  absl::Status User(const absl::StatusOr<UserRecord>& user);
  absl::Status Event(const absl::Status& event);
  // A checkpoint read back (derived data: the service ignores a damaged
  // one and rebuilds that model from the log).
  absl::Status Checkpoint(const absl::Status& checkpoint);
  StoreCheckReport Take() { return std::move(report_); }

 private:
  absl::Status Note(const absl::Status& status);
  StoreCheckReport report_;
};

// The messages both stores give for a damaged checkpoint, a checkpoint not
// kept because the log moved on, and a missing population pool.
absl::Status CheckpointDamaged(absl::string_view user_id, int64_t model_version,
                               size_t got_bytes, int64_t bytes,
                               int64_t got_chunks, int64_t chunks);
absl::Status CheckpointNotKept(absl::string_view user_id,
                               const ModelCheckpoint& checkpoint);
// ABORTED naming the user and both counts unless `model_version` (the
// user's completed events now) is `expected` (what `op` was checked on).
absl::Status LogMovedSince(absl::string_view user_id, int64_t expected,
                           int64_t model_version, absl::string_view op);
absl::Status NoPoolFor(const BanditConfig& config, int posthoc_dim);

// The action names of one user or pool, read row by row (action, name) in
// action order: DATA_LOSS naming `what` and `table` unless the actions are
// 0, 1, ... with at least one.
class ActionNamesReader {
 public:
  ActionNamesReader(absl::string_view what, absl::string_view table)
      : what_(what), table_(table) {}
  absl::Status Add(int64_t action, std::string name);
  absl::StatusOr<std::vector<std::string>> Take();

 private:
  const std::string what_;
  const std::string table_;
  std::vector<std::string> names_;
};

// A row of the audit columns, in this order: audit_id, at_us, method,
// target, identity, role, peer, result.
template <typename Row>
AuditEntry ReadAuditRow(Row& row) {
  AuditEntry entry;
  entry.audit_id = row.Int64(0);
  entry.time = FromMicros(row.Int64(1));
  entry.method = row.Text(2);
  entry.target = row.Text(3);
  entry.identity = row.Text(4);
  entry.role = row.Text(5);
  entry.peer = row.Text(6);
  entry.result = row.Text(7);
  return entry;
}

// DATA_LOSS naming `what` when a stored integer does not fit an int.
absl::StatusOr<int> ToInt(int64_t value, absl::string_view what);

absl::Status UserNotFound(absl::string_view user_id);
absl::Status EventNotFound(int64_t event_id);
absl::Status AlreadyCompleted(int64_t event_id);
// A completion's scalars: INVALID_ARGUMENT for a NaN loss or weight, which
// neither store can keep.
absl::Status CheckOutcome(double loss, double weight);

// The checks of a user's stored learner and strategy codes.
absl::Status CheckUserCodes(int64_t learner, int64_t strategy,
                            absl::string_view what);

// A row of the user columns, in this order: user_id, learner, strategy,
// alpha, lambda_c, lambda_p, epsilon, importance_weighting, context_dim,
// posthoc_dim, seed, created_at_us, model_version, pending events, prior,
// phi_radius.
// `read_names(user_id, what)` reads the user's action names.
template <typename Row>
absl::StatusOr<UserRecord> ReadUserRow(
    Row& row, absl::FunctionRef<absl::StatusOr<std::vector<std::string>>(
                  const std::string& user_id, const std::string& what)>
                  read_names) {
  UserRecord user;
  user.user_id = row.Text(0);
  const std::string what = absl::StrCat("user \"", user.user_id, "\"");
  BanditConfig& config = user.config;
  const int64_t learner = row.Int64(1);
  const int64_t strategy = row.Int64(2);
  RETURN_IF_ERROR(CheckUserCodes(learner, strategy, what));
  config.learner = static_cast<Learner>(learner);
  config.strategy = static_cast<Strategy>(strategy);
  config.alpha = row.Double(3);
  config.lambda_c = row.Double(4);
  config.lambda_p = row.Double(5);
  config.epsilon = row.Double(6);
  config.importance_weighting = row.Int64(7) != 0;
  ASSIGN_OR_RETURN(config.context_dim,
                   ToInt(row.Int64(8), absl::StrCat(what, " context_dim")));
  ASSIGN_OR_RETURN(config.posthoc_dim,
                   ToInt(row.Int64(9), absl::StrCat(what, " posthoc_dim")));
  ASSIGN_OR_RETURN(config.action_names, read_names(user.user_id, what));
  config.seed = static_cast<uint64_t>(row.Int64(10));
  user.created_at = FromMicros(row.Int64(11));
  user.model_version = row.Int64(12);
  user.pending_events = row.Int64(13);
  config.phi_radius = row.Double(15);
  if (!row.IsNull(14)) {
    ASSIGN_OR_RETURN(config.prior,
                     DecodePrior(row.Blob(14), absl::StrCat(what, " prior")));
    // A stored prior that does not fit the stored configuration is
    // damaged data, not a bad request.
    if (absl::Status valid = ValidateConfig(config); !valid.ok()) {
      return absl::DataLossError(absl::StrCat(what, ": ", valid.message()));
    }
  }
  return user;
}

// DATA_LOSS naming the event and its user when a checksum does not match.
absl::Status ChecksumMismatch(int64_t event_id, absl::string_view user_id,
                              absl::string_view part);

// A row of the event columns, in this order: event_id, user_id, meal_id,
// item_label, context, action, propensity, selected_at_us, completed, loss,
// posthoc, weight, model_version, updated_at_us, selection_checksum,
// outcome_checksum. Both checksums are checked.
template <typename Row>
absl::StatusOr<EventRecord> ReadEventRow(Row& row) {
  EventRecord event;
  event.event_id = row.Int64(0);
  const std::string what = absl::StrCat("event ", event.event_id);
  event.user_id = row.Text(1);
  event.meal_id = row.Text(2);
  event.item_label = row.Text(3);
  ASSIGN_OR_RETURN(event.context,
                   DecodeDoubles(row.Blob(4), absl::StrCat(what, " context")));
  ASSIGN_OR_RETURN(event.action,
                   ToInt(row.Int64(5), absl::StrCat(what, " action")));
  event.propensity = row.Double(6);
  event.selected_at = FromMicros(row.Int64(7));
  event.completed = row.Int64(8) != 0;
  if (row.Int64(14) != SelectionChecksum(event.user_id, event.meal_id,
                                         event.item_label, row.Blob(4),
                                         event.action, event.propensity,
                                         row.Int64(7))) {
    return ChecksumMismatch(event.event_id, event.user_id, "selection");
  }
  if (event.completed &&
      (row.IsNull(15) || row.IsNull(9) || row.IsNull(11) || row.IsNull(12) ||
       row.IsNull(13) ||
       row.Int64(15) != OutcomeChecksum(row.Double(9), row.Blob(10),
                                        row.Double(11), row.Int64(12),
                                        row.Int64(13)))) {
    return ChecksumMismatch(event.event_id, event.user_id, "outcome");
  }
  if (event.completed) {
    event.loss = row.Double(9);
    if (!row.IsNull(10)) {
      ASSIGN_OR_RETURN(
          event.posthoc,
          DecodeDoubles(row.Blob(10), absl::StrCat(what, " posthoc")));
    }
    event.weight = row.Double(11);
    event.model_version = row.Int64(12);
    event.updated_at = FromMicros(row.Int64(13));
  }
  return event;
}

}  // namespace bitewise::bandit::store_rows

namespace bitewise::bandit {

// The names the stores' own files use unqualified (this header is internal
// to services/bandit/store).
using store_rows::ApproxBytes;
using store_rows::DecodePrior;
using store_rows::EncodeDoubles;
using store_rows::EncodePrior;
using store_rows::EventNotFound;
using store_rows::FromMicros;
using store_rows::ParsePageToken;
using store_rows::ToMicros;
using store_rows::UserNotFound;

}  // namespace bitewise::bandit

#endif  // BITEWISE_SERVICES_BANDIT_STORE_STORE_ROWS_H_
