#include "clients/console/research.h"

#include <google/protobuf/util/time_util.h>

#include <functional>
#include <map>
#include <optional>
#include <string>
#include <string_view>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "services/common/status_macros.h"
#include "services/domain/user_id.h"

namespace bitewise::console {
namespace {

using google::protobuf::util::TimeUtil;

// Enough pages for any person's history; a longer one is an error rather
// than a silent cut.
constexpr int kMaxPages = 10000;

std::string Doubles(const google::protobuf::RepeatedField<double>& values) {
  return absl::StrJoin(values, ";", [](std::string* out, double v) {
    absl::StrAppend(out, absl::StrFormat("%.17g", v));
  });
}

// A CSV cell of text: quoted when it holds a separator, a quote or a line
// break. Text that a spreadsheet would run as a formula (it begins with =,
// +, -, @, a tab or a carriage return: a meal id given on the orchestrator's
// command line can be anything) gets a leading ' and is quoted, so that
// opening events.csv shows it instead of running it.
std::string Cell(const std::string& text) {
  const bool formula =
      !text.empty() &&
      std::string_view("=+-@\t\r").find(text[0]) != std::string_view::npos;
  if (!formula && text.find_first_of(",\"\r\n") == std::string::npos) {
    return text;
  }
  std::string quoted = formula ? "\"'" : "\"";
  for (char c : text) {
    if (c == '"') quoted += '"';
    quoted += c;
  }
  return quoted + "\"";
}

std::string Time(const google::protobuf::Timestamp& t) {
  if (t.seconds() == 0 && t.nanos() == 0) return "";
  return TimeUtil::ToString(t);
}

}  // namespace

absl::StatusOr<v1::ListUsersResponse> AllUsers(meals::BanditClient& bandit) {
  v1::ListUsersResponse all;
  v1::ListUsersRequest request;
  request.set_page_size(1000);
  for (int page = 0; page < kMaxPages; ++page) {
    absl::StatusOr<v1::ListUsersResponse> response = bandit.ListUsers(request);
    if (!response.ok()) return response.status();
    for (v1::User& user : *response->mutable_users()) {
      *all.add_users() = std::move(user);
    }
    if (response->next_page_token().empty()) return all;
    request.set_page_token(response->next_page_token());
  }
  return absl::ResourceExhaustedError("more users than the console lists");
}

namespace {

// Every event of `user_id` (of `meal_id`, if not empty), a page of ListEvents
// at a time, each given to `take` until it returns false; so a caller that
// looks for one event holds one page, not a person's whole history (at d =
// 2048, 16 KB of context an event).
absl::Status ForEachEvent(meals::BanditClient& bandit,
                          const std::string& user_id,
                          const std::string& meal_id, bool* contexts_withheld,
                          const std::function<bool(v1::Event&&)>& take) {
  if (absl::Status valid = domain::ValidateUserId(user_id); !valid.ok()) {
    return valid;
  }
  v1::ListEventsRequest request;
  request.set_user_id(user_id);
  request.set_meal_id(meal_id);
  request.set_page_size(1000);
  if (contexts_withheld != nullptr) *contexts_withheld = false;
  for (int page = 0; page < kMaxPages; ++page) {
    absl::StatusOr<v1::ListEventsResponse> response =
        bandit.ListEvents(request);
    if (!response.ok()) return response.status();
    if (contexts_withheld != nullptr && response->contexts_withheld()) {
      *contexts_withheld = true;
    }
    for (v1::Event& event : *response->mutable_events()) {
      if (!take(std::move(event))) return absl::OkStatus();
    }
    if (response->next_page_token().empty()) return absl::OkStatus();
    request.set_page_token(response->next_page_token());
  }
  return absl::ResourceExhaustedError(
      absl::StrCat("more events of ", user_id, " than the console lists"));
}

}  // namespace

absl::StatusOr<std::vector<v1::Event>> AllEvents(meals::BanditClient& bandit,
                                                 const std::string& user_id,
                                                 const std::string& meal_id,
                                                 bool with_contexts,
                                                 bool* contexts_withheld) {
  std::vector<v1::Event> events;
  RETURN_IF_ERROR(ForEachEvent(bandit, user_id, meal_id, contexts_withheld,
                               [&](v1::Event&& event) {
                                 if (!with_contexts) event.clear_context();
                                 events.push_back(std::move(event));
                                 return true;
                               }));
  return events;
}

consolepb::MealsReply MealsOf(const std::string& user_id,
                              const std::vector<v1::Event>& events) {
  consolepb::MealsReply reply;
  reply.set_user_id(user_id);
  std::map<std::string, int> index;
  for (const v1::Event& event : events) {
    auto [it, added] = index.emplace(event.meal_id(), reply.meals_size());
    if (added) {
      consolepb::MealTally* tally = reply.add_meals();
      tally->set_meal_id(event.meal_id());
      tally->set_first_selected_at(Time(event.selected_at()));
    }
    consolepb::MealTally* tally = reply.mutable_meals(it->second);
    if (!event.completed()) {
      tally->set_pending(tally->pending() + 1);
      continue;
    }
    tally->set_attempts(tally->attempts() + 1);
    if (event.loss() >= 0.5) tally->set_failures(tally->failures() + 1);
  }
  return reply;
}

namespace {

std::string CsvHeader(bool with_contexts, bool withheld) {
  std::string csv = absl::StrCat(
      "event_id,user_id,meal_id,item_label,action,propensity,completed,loss,",
      withheld ? "posthoc_withheld" : "posthoc",
      ",model_version,selected_at,updated_at");
  if (with_contexts && !withheld) csv += ",context";
  csv += "\r\n";
  return csv;
}

void AppendCsvRow(const v1::Event& e, bool with_contexts, std::string* csv) {
  absl::StrAppend(csv, Cell(e.event_id()), ",", Cell(e.user_id()), ",",
                  Cell(e.meal_id()), ",", Cell(e.item_label()), ",", e.action(),
                  ",", absl::StrFormat("%.17g", e.propensity()), ",",
                  e.completed() ? "true" : "false", ",",
                  absl::StrFormat("%.17g", e.loss()), ",", Doubles(e.posthoc()),
                  ",", e.model_version(), ",", Time(e.selected_at()), ",",
                  Time(e.updated_at()));
  if (with_contexts) absl::StrAppend(csv, ",", Doubles(e.context()));
  *csv += "\r\n";
}

}  // namespace

std::string EventsCsv(const std::vector<v1::Event>& events, bool with_contexts,
                      bool withheld) {
  std::string csv = CsvHeader(with_contexts, withheld);
  for (const v1::Event& e : events) {
    AppendCsvRow(e, with_contexts && !withheld, &csv);
  }
  return csv;
}

absl::StatusOr<std::unique_ptr<EventsCsvStream>> EventsCsvStream::Start(
    meals::BanditClient& bandit, const std::string& user_id,
    const std::string& meal_id, bool with_contexts, int page_size) {
  RETURN_IF_ERROR(domain::ValidateUserId(user_id));
  v1::ListEventsRequest request;
  request.set_user_id(user_id);
  request.set_meal_id(meal_id);
  request.set_page_size(page_size);
  std::unique_ptr<EventsCsvStream> stream(
      new EventsCsvStream(bandit, std::move(request), with_contexts));
  absl::StatusOr<v1::ListEventsResponse> first =
      bandit.ListEvents(stream->request_);
  if (!first.ok()) return first.status();
  stream->withheld_ = first->contexts_withheld();
  stream->page_ = *std::move(first);
  stream->pages_ = 1;
  return stream;
}

absl::StatusOr<std::string> EventsCsvStream::Next() {
  std::string out;
  if (!header_sent_) {
    out = CsvHeader(with_contexts_, withheld_);
    header_sent_ = true;
  }
  // A page without events (but with a next one) gives nothing to send:
  // read on, so that "" means the end.
  do {
    if (done_) return out;
    RETURN_IF_ERROR(ReadPage(&out));
  } while (out.empty());
  return out;
}

absl::Status EventsCsvStream::ReadPage(std::string* out) {
  if (!page_.has_value()) {
    if (pages_ >= kMaxPages) {
      return absl::ResourceExhaustedError(absl::StrCat(
          "more events of ", request_.user_id(), " than the console lists"));
    }
    absl::StatusOr<v1::ListEventsResponse> next = bandit_.ListEvents(request_);
    if (!next.ok()) return next.status();
    page_ = *std::move(next);
    ++pages_;
  }
  for (const v1::Event& e : page_->events()) {
    AppendCsvRow(e, with_contexts_ && !withheld_, out);
  }
  if (page_->next_page_token().empty()) {
    done_ = true;
  } else {
    request_.set_page_token(page_->next_page_token());
  }
  page_.reset();
  return absl::OkStatus();
}

absl::StatusOr<consolepb::EstimatesReply> EstimatesFor(
    meals::BanditClient& bandit, const std::string& user_id,
    const std::string& event_id) {
  // As the BanditService reads it: decimal digits, no sign, spaces or
  // leading zeros (" 7", "+7" and "007" would never match an id).
  int64_t id = 0;
  const bool canonical =
      !event_id.empty() && event_id.size() <= 19 && event_id[0] != '0' &&
      event_id.find_first_not_of("0123456789") == std::string::npos;
  if (!canonical || !absl::SimpleAtoi(event_id, &id) || id <= 0) {
    return absl::InvalidArgumentError(
        absl::StrCat("event_id: expected the decimal id of a bite, got \"",
                     event_id.substr(0, 64), "\""));
  }
  bool withheld = false;
  std::optional<v1::Event> event;
  RETURN_IF_ERROR(
      ForEachEvent(bandit, user_id, "", &withheld, [&](v1::Event&& e) {
        if (e.event_id() != event_id) return true;
        event = std::move(e);
        return false;
      }));
  if (!event.has_value()) {
    return absl::NotFoundError(
        absl::StrCat("event ", event_id, " is not one of ", user_id, "'s"));
  }
  if (withheld || event->context_size() == 0) {
    return absl::PermissionDeniedError(
        "the BanditService withholds contexts from this console's identity, "
        "so no estimate can be computed");
  }
  // The learner's own estimates (the BanditService computes them as Select
  // does), and each action's count from the model of the same version: a
  // bite learned between the two calls is read again, a few times at most.
  v1::EstimateRequest request;
  request.set_user_id(user_id);
  *request.mutable_context() = event->context();
  absl::StatusOr<v1::EstimateResponse> estimated;
  absl::StatusOr<v1::Model> model;
  for (int attempt = 1;; ++attempt) {
    estimated = bandit.Estimate(request);
    if (!estimated.ok()) return estimated.status();
    model = bandit.GetModel(user_id);
    if (!model.ok()) return model.status();
    if (model->model_version() == estimated->model_version()) break;
    if (attempt == 3) {
      return absl::UnavailableError(absl::StrCat(
          user_id, "'s model changed while it was read (bites are being ",
          "learned); try again"));
    }
  }
  if (model->actions_size() != estimated->estimates_size()) {
    return absl::FailedPreconditionError(absl::StrCat(
        "the model has ", model->actions_size(), " actions but its estimates ",
        estimated->estimates_size()));
  }
  consolepb::EstimatesReply reply;
  reply.set_event_id(event_id);
  reply.set_user_id(user_id);
  reply.set_model_version(estimated->model_version());
  reply.set_learner(v1::Learner_Name(model->config().learner()));
  for (int a = 0; a < estimated->estimates_size(); ++a) {
    const v1::ActionEstimate& from = estimated->estimates(a);
    if (model->actions(a).action() != from.action()) {
      return absl::FailedPreconditionError(absl::StrCat(
          "the model's action ", model->actions(a).action(),
          " stands where its estimates have action ", from.action()));
    }
    consolepb::ActionEstimate* estimate = reply.add_estimates();
    estimate->set_action(from.action());
    estimate->set_action_name(from.action_name());
    estimate->set_predicted_loss(from.predicted_loss());
    estimate->set_width(from.width());
    estimate->set_lcb(from.lcb());
    estimate->set_count(model->actions(a).count());
  }
  return reply;
}

}  // namespace bitewise::console
