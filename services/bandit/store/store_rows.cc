#include "services/bandit/store/store_rows.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include "absl/strings/escaping.h"
#include "absl/strings/numbers.h"
#include "services/bandit/core/learners.h"

namespace bitewise::bandit::store_rows {
namespace {

constexpr int kDefaultPageSize = 100;
constexpr int kMaxPageSize = 1000;

}  // namespace

std::string EncodeDoubles(const std::vector<double>& values) {
  std::string out(values.size() * 8, '\0');
  for (size_t i = 0; i < values.size(); ++i) {
    uint64_t bits;
    std::memcpy(&bits, &values[i], sizeof(bits));
    for (int b = 0; b < 8; ++b) {
      out[i * 8 + b] = static_cast<char>((bits >> (8 * b)) & 0xff);
    }
  }
  return out;
}

absl::StatusOr<std::vector<double>> DecodeDoubles(absl::string_view bytes,
                                                  absl::string_view what) {
  if (bytes.size() % 8 != 0) {
    return absl::DataLossError(absl::StrCat(what, ": stored vector has ",
                                            bytes.size(),
                                            " bytes, not a multiple of 8"));
  }
  std::vector<double> values(bytes.size() / 8);
  for (size_t i = 0; i < values.size(); ++i) {
    uint64_t bits = 0;
    for (int b = 0; b < 8; ++b) {
      bits |=
          static_cast<uint64_t>(static_cast<unsigned char>(bytes[i * 8 + b]))
          << (8 * b);
    }
    std::memcpy(&values[i], &bits, sizeof(bits));
  }
  return values;
}

std::string EncodePrior(const PopulationPrior& prior) {
  const size_t k = prior.theta0.size();
  const size_t d = k > 0 ? prior.theta0[0].size() : 0;
  const size_t q = prior.phi0.empty() ? 0 : prior.phi0[0].size();
  std::vector<double> v = {static_cast<double>(prior.pool_version),
                           prior.rounds,
                           prior.context_msn,
                           prior.posthoc_msn,
                           static_cast<double>(k),
                           static_cast<double>(d),
                           static_cast<double>(q)};
  for (const auto& row : prior.theta0)
    v.insert(v.end(), row.begin(), row.end());
  for (const auto& row : prior.phi0) v.insert(v.end(), row.begin(), row.end());
  return EncodeDoubles(v);
}

absl::StatusOr<PopulationPrior> DecodePrior(absl::string_view bytes,
                                            absl::string_view what) {
  ASSIGN_OR_RETURN(const std::vector<double> v, DecodeDoubles(bytes, what));
  auto bad = [&] {
    return absl::DataLossError(
        absl::StrCat(what, ": stored population prior is malformed"));
  };
  if (v.size() < 7) return bad();
  for (int i = 4; i < 7; ++i) {
    if (!(v[i] >= 0 && v[i] <= (1 << 16) && v[i] == std::floor(v[i]))) {
      return bad();
    }
  }
  const size_t k = static_cast<size_t>(v[4]), d = static_cast<size_t>(v[5]),
               q = static_cast<size_t>(v[6]);
  if (v.size() != 7 + k * d + k * q) return bad();
  PopulationPrior prior;
  prior.pool_version = static_cast<int64_t>(v[0]);
  prior.rounds = v[1];
  prior.context_msn = v[2];
  prior.posthoc_msn = v[3];
  size_t at = 7;
  for (size_t a = 0; a < k; ++a, at += d) {
    prior.theta0.emplace_back(v.begin() + at, v.begin() + at + d);
  }
  for (size_t a = 0; a < k && q > 0; ++a, at += q) {
    prior.phi0.emplace_back(v.begin() + at, v.begin() + at + q);
  }
  return prior;
}

std::string MakePageToken(char kind, absl::string_view key) {
  return absl::WebSafeBase64Escape(
      absl::StrCat(std::string(1, kind), ":", key));
}

absl::StatusOr<std::string> ParsePageToken(const std::string& token,
                                           char kind) {
  std::string raw;
  if (!absl::WebSafeBase64Unescape(token, &raw) || raw.size() < 2 ||
      raw[0] != kind || raw[1] != ':') {
    return absl::InvalidArgumentError("invalid page_token");
  }
  // Keys are user ids and decimal ids: printable ASCII. Anything else is
  // forged, and must not reach a query (PostgreSQL refuses a NUL or a byte
  // that is not UTF-8 with a message naming the server, not the field).
  for (size_t i = 2; i < raw.size(); ++i) {
    if (raw[i] < 0x21 || raw[i] > 0x7e) {
      return absl::InvalidArgumentError("invalid page_token");
    }
  }
  return raw.substr(2);
}

absl::StatusOr<int64_t> ParseIdPageToken(const std::string& token, char kind) {
  ASSIGN_OR_RETURN(const std::string key, ParsePageToken(token, kind));
  int64_t last_id = 0;
  if (!absl::SimpleAtoi(key, &last_id) || last_id <= 0) {
    return absl::InvalidArgumentError("invalid page_token");
  }
  return last_id;
}

int64_t ApproxBytes(const UserRecord& user) {
  int64_t bytes = 256 + static_cast<int64_t>(user.user_id.size());
  for (const std::string& name : user.config.action_names) {
    bytes += static_cast<int64_t>(name.size()) + 4;
  }
  for (const auto& row : user.config.prior.theta0) bytes += 8 * row.size();
  for (const auto& row : user.config.prior.phi0) bytes += 8 * row.size();
  return bytes;
}

int64_t ApproxBytes(const EventRecord& event) {
  return 128 +
         static_cast<int64_t>(event.user_id.size() + event.meal_id.size() +
                              event.item_label.size()) +
         8 * static_cast<int64_t>(event.context.size() + event.posthoc.size());
}

int ClampPageSize(int page_size) {
  if (page_size <= 0) return kDefaultPageSize;
  return std::min(page_size, kMaxPageSize);
}

absl::StatusOr<int> ToInt(int64_t value, absl::string_view what) {
  if (value < std::numeric_limits<int>::min() ||
      value > std::numeric_limits<int>::max()) {
    return absl::DataLossError(
        absl::StrCat(what, ": stored value ", value, " is out of range"));
  }
  return static_cast<int>(value);
}

absl::Status UserNotFound(absl::string_view user_id) {
  return absl::NotFoundError(absl::StrCat("user \"", user_id, "\" not found"));
}

absl::Status EventNotFound(int64_t event_id) {
  return absl::NotFoundError(absl::StrCat("event ", event_id, " not found"));
}

absl::Status CheckOutcome(double loss, double weight) {
  if (std::isnan(loss)) {
    return absl::InvalidArgumentError("loss must not be NaN");
  }
  if (std::isnan(weight)) {
    return absl::InvalidArgumentError("weight must not be NaN");
  }
  return absl::OkStatus();
}

absl::Status AlreadyCompleted(int64_t event_id) {
  return absl::FailedPreconditionError(
      absl::StrCat("event ", event_id, " is already completed"));
}

absl::Status CheckUserCodes(int64_t learner, int64_t strategy,
                            absl::string_view what) {
  if (FindLearner(static_cast<Learner>(learner)) == nullptr) {
    return absl::DataLossError(
        absl::StrCat(what, ": unknown learner ", learner));
  }
  if (strategy < static_cast<int>(Strategy::kLinUcb) ||
      strategy > static_cast<int>(Strategy::kUniform)) {
    return absl::DataLossError(
        absl::StrCat(what, ": unknown strategy ", strategy));
  }
  return absl::OkStatus();
}

absl::Status ChecksumMismatch(int64_t event_id, absl::string_view user_id,
                              absl::string_view part) {
  return absl::DataLossError(absl::StrCat(
      "event ", event_id, " of user \"", user_id, "\": its ", part,
      " does not match its checksum (altered or damaged on disk); it is not "
      "learned from. Restore the last backup or ResetUser "
      "(docs/operations.md)"));
}

absl::Status ActionNamesReader::Add(int64_t action, std::string name) {
  if (action != static_cast<int64_t>(names_.size())) {
    return absl::DataLossError(absl::StrCat(what_, ": action ", names_.size(),
                                            " has no name in ", table_));
  }
  names_.push_back(std::move(name));
  return absl::OkStatus();
}

absl::StatusOr<std::vector<std::string>> ActionNamesReader::Take() {
  if (names_.empty()) {
    return absl::DataLossError(
        absl::StrCat(what_, ": no action names in ", table_));
  }
  return std::move(names_);
}

CheckReportBuilder::CheckReportBuilder(std::vector<std::string> findings) {
  report_.findings = std::move(findings);
}

absl::Status CheckReportBuilder::Note(const absl::Status& status) {
  if (status.ok()) return absl::OkStatus();
  if (!absl::IsDataLoss(status)) return status;  // the check could not run
  constexpr size_t kMaxFindings = 100;
  if (report_.findings.size() < kMaxFindings) {
    report_.findings.push_back(std::string(status.message()));
  }
  return absl::OkStatus();
}

absl::Status CheckReportBuilder::User(const absl::StatusOr<UserRecord>& user) {
  ++report_.users_checked;
  if (!user.ok()) return Note(user.status());
  if (absl::Status valid = ValidateConfig(user->config); !valid.ok()) {
    return Note(absl::DataLossError(
        absl::StrCat("user \"", user->user_id, "\": ", valid.message())));
  }
  return absl::OkStatus();
}

absl::Status CheckReportBuilder::Event(const absl::Status& event) {
  ++report_.events_checked;
  return Note(event);
}

absl::Status CheckReportBuilder::Checkpoint(const absl::Status& checkpoint) {
  if (!absl::IsDataLoss(checkpoint)) return Note(checkpoint);
  return Note(absl::DataLossError(absl::StrCat(
      checkpoint.message(),
      " (the service ignores it and rebuilds that model from the log)")));
}

absl::Status CheckpointDamaged(absl::string_view user_id, int64_t model_version,
                               size_t got_bytes, int64_t bytes,
                               int64_t got_chunks, int64_t chunks) {
  return absl::DataLossError(absl::StrCat(
      "the model checkpoint of user ", user_id, " at model version ",
      model_version, " is damaged (", got_bytes, " of ", bytes, " bytes in ",
      got_chunks, " of ", chunks, " chunks, or a checksum mismatch)"));
}

absl::Status CheckpointNotKept(absl::string_view user_id,
                               const ModelCheckpoint& checkpoint) {
  return absl::FailedPreconditionError(absl::StrCat(
      "checkpoint of user ", user_id, " at model version ",
      checkpoint.model_version, " (", LearnerName(checkpoint.learner),
      "): the log no longer has event ", checkpoint.last_event_id,
      " there, or the user has another learner now (reset or SetLearner "
      "meanwhile?); not kept"));
}

absl::Status LogMovedSince(absl::string_view user_id, int64_t expected,
                           int64_t model_version, absl::string_view op) {
  if (model_version == expected) return absl::OkStatus();
  return absl::AbortedError(absl::StrCat(
      op, ": user \"", user_id, "\" has ", model_version,
      " completed events, not the ", expected,
      " it was checked on (a bite was learned meanwhile); nothing changed, "
      "try again"));
}

absl::Status NoPoolFor(const BanditConfig& config, int posthoc_dim) {
  return absl::NotFoundError(absl::StrCat(
      "no population pool for ", LearnerName(config.learner),
      " users with context_dim ", config.context_dim, ", posthoc_dim ",
      posthoc_dim, " and these ", config.num_actions(),
      " actions; build one with BuildPopulationPrior"));
}

}  // namespace bitewise::bandit::store_rows
