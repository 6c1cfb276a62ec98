#include "experiments/event_log.h"

#include <cmath>
#include <fstream>
#include <iterator>
#include <memory>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "absl/strings/str_split.h"
#include "services/bandit/store/sqlite_event_store.h"

namespace bitewise::experiments {
namespace {

constexpr char kLogHeader[] =
    "item_label,action,propensity,loss,context,posthoc";
constexpr char kLabelledHeader[] = "item_label,losses,context,posthoc";

absl::Status LineError(int line, absl::string_view column,
                       absl::string_view what) {
  return absl::InvalidArgumentError(
      absl::StrCat("line ", line, ", column ", column, ": ", what));
}

absl::StatusOr<double> ParseNumber(absl::string_view text, int line,
                                   absl::string_view column) {
  double v;
  if (!absl::SimpleAtod(text, &v) || !std::isfinite(v)) {
    return LineError(line, column,
                     absl::StrCat("not a finite number: '", text, "'"));
  }
  return v;
}

absl::StatusOr<std::vector<double>> ParseVector(absl::string_view text,
                                                int line,
                                                absl::string_view column) {
  std::vector<double> out;
  for (absl::string_view item : absl::StrSplit(text, ' ', absl::SkipEmpty())) {
    auto v = ParseNumber(item, line, column);
    if (!v.ok()) return v.status();
    out.push_back(*v);
  }
  return out;
}

// `expected` < 0: not yet known (set from this row). Only the post hoc
// column may be empty (a context-only user logs none).
absl::Status CheckLength(const std::vector<double>& v, long& expected, int line,
                         absl::string_view column, bool may_be_empty) {
  if (expected < 0) expected = static_cast<long>(v.size());
  if (static_cast<long>(v.size()) != expected || (v.empty() && !may_be_empty)) {
    return LineError(
        line, column,
        absl::StrCat("has ", v.size(), " values, expected ", expected));
  }
  return absl::OkStatus();
}

std::string JoinVector(const std::vector<double>& v) {
  // %.17g round-trips every double exactly.
  return absl::StrJoin(v, " ", [](std::string* out, double x) {
    absl::StrAppend(out, absl::StrFormat("%.17g", x));
  });
}

}  // namespace

absl::StatusOr<EventLog> ParseEventLogCsv(absl::string_view text,
                                          int num_actions) {
  EventLog log;
  bool have_header = false;
  long context_dim = -1, posthoc_dim = -1, loss_dim = -1;
  int line_number = 0;
  for (absl::string_view line : absl::StrSplit(text, '\n')) {
    ++line_number;
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    if (line.empty() || line.front() == '#') continue;
    if (!have_header) {
      if (line == kLogHeader) {
        log.labelled = false;
      } else if (line == kLabelledHeader) {
        log.labelled = true;
      } else {
        return absl::InvalidArgumentError(
            absl::StrCat("line ", line_number, ": header must be '", kLogHeader,
                         "' or '", kLabelledHeader, "'"));
      }
      if (!log.labelled && num_actions < 1) {
        return absl::InvalidArgumentError(
            "an event log needs the number of actions");
      }
      have_header = true;
      continue;
    }
    const std::vector<absl::string_view> f = absl::StrSplit(line, ',');
    const size_t fields = log.labelled ? 4 : 6;
    if (f.size() != fields) {
      return absl::InvalidArgumentError(absl::StrCat(
          "line ", line_number, ": ", f.size(), " fields, expected ", fields));
    }
    LoggedEvent e;
    e.item_label = std::string(f[0]);
    size_t next = 1;
    if (log.labelled) {
      auto losses = ParseVector(f[next++], line_number, "losses");
      if (!losses.ok()) return losses.status();
      if (loss_dim < 0 && num_actions > 0) loss_dim = num_actions;
      if (auto s = CheckLength(*losses, loss_dim, line_number, "losses", false);
          !s.ok()) {
        return s;
      }
      for (double l : *losses) {
        if (l < 0.0 || l > 1.0) {
          return LineError(line_number, "losses", "a loss is outside [0, 1]");
        }
      }
      e.losses = *std::move(losses);
    } else {
      auto action = ParseNumber(f[next++], line_number, "action");
      if (!action.ok()) return action.status();
      if (*action != std::floor(*action) || *action < 0 ||
          *action >= num_actions) {
        return LineError(
            line_number, "action",
            absl::StrCat("must be an integer in [0, ", num_actions, ")"));
      }
      e.action = static_cast<int>(*action);
      auto propensity = ParseNumber(f[next++], line_number, "propensity");
      if (!propensity.ok()) return propensity.status();
      if (*propensity <= 0.0 || *propensity > 1.0) {
        return LineError(line_number, "propensity", "must be in (0, 1]");
      }
      e.propensity = *propensity;
      auto loss = ParseNumber(f[next++], line_number, "loss");
      if (!loss.ok()) return loss.status();
      if (*loss < 0.0 || *loss > 1.0) {
        return LineError(line_number, "loss", "must be in [0, 1]");
      }
      e.loss = *loss;
    }
    auto context = ParseVector(f[next++], line_number, "context");
    if (!context.ok()) return context.status();
    if (auto s =
            CheckLength(*context, context_dim, line_number, "context", false);
        !s.ok()) {
      return s;
    }
    e.context = *std::move(context);
    auto posthoc = ParseVector(f[next++], line_number, "posthoc");
    if (!posthoc.ok()) return posthoc.status();
    if (auto s =
            CheckLength(*posthoc, posthoc_dim, line_number, "posthoc", true);
        !s.ok()) {
      return s;
    }
    e.posthoc = *std::move(posthoc);
    log.events.push_back(std::move(e));
  }
  if (!have_header) return absl::InvalidArgumentError("no header line");
  log.num_actions =
      log.labelled && loss_dim >= 0 ? static_cast<int>(loss_dim) : num_actions;
  return log;
}

absl::StatusOr<EventLog> ReadEventLogCsv(const std::string& path,
                                         int num_actions) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return absl::NotFoundError(absl::StrCat("cannot open ", path));
  const std::string text(std::istreambuf_iterator<char>(in), {});
  auto log = ParseEventLogCsv(text, num_actions);
  if (!log.ok()) {
    return absl::Status(log.status().code(),
                        absl::StrCat(path, ": ", log.status().message()));
  }
  return log;
}

absl::StatusOr<EventLog> ReadEventLogSqlite(const std::string& path,
                                            const std::string& user_id) {
  // SqliteEventStore::Open would create a missing file; an offline tool
  // must never do that.
  if (!std::ifstream(path).good()) {
    return absl::NotFoundError(absl::StrCat("cannot open ", path));
  }
  bandit::SqliteStoreOptions options;
  options.path = path;
  auto store = bandit::SqliteEventStore::Open(options);
  if (!store.ok()) return store.status();
  auto user = (*store)->GetUser(user_id);
  if (!user.ok()) return user.status();
  auto events = (*store)->CompletedEvents(user_id);
  if (!events.ok()) return events.status();
  EventLog log;
  log.num_actions = user->config.num_actions();
  for (const bandit::EventRecord& r : *events) {
    LoggedEvent e;
    e.item_label = r.item_label;
    e.context = r.context;
    e.posthoc = r.posthoc;
    e.action = r.action;
    e.propensity = r.propensity;
    e.loss = r.loss;
    log.events.push_back(std::move(e));
  }
  return log;
}

std::string FormatEventLogCsv(const EventLog& log) {
  std::string out =
      absl::StrCat(log.labelled ? kLabelledHeader : kLogHeader, "\n");
  for (const LoggedEvent& e : log.events) {
    if (log.labelled) {
      absl::StrAppend(&out, e.item_label, ",", JoinVector(e.losses), ",",
                      JoinVector(e.context), ",", JoinVector(e.posthoc), "\n");
    } else {
      absl::StrAppend(&out, e.item_label, ",", e.action, ",",
                      absl::StrFormat("%.17g", e.propensity), ",",
                      absl::StrFormat("%.17g", e.loss), ",",
                      JoinVector(e.context), ",", JoinVector(e.posthoc), "\n");
    }
  }
  return out;
}

}  // namespace bitewise::experiments
