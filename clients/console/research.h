// Research: the researcher view's questions, answered from the
// BanditService alone (ListUsers, ListEvents, GetModel, Estimate), so what a
// researcher sees is what the store holds: failures per meal, events as
// CSV, and per-action estimates for a bite's context.
//
// Thread-safe (the clients are). Errors are the BanditService's, plus
// INVALID_ARGUMENT for a malformed id and PERMISSION_DENIED when contexts
// are needed but the BanditService withholds them.
#ifndef BITEWISE_CLIENTS_CONSOLE_RESEARCH_H_
#define BITEWISE_CLIENTS_CONSOLE_RESEARCH_H_

#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/statusor.h"
#include "bitewise/console/v1/console.pb.h"
#include "clients/meal/service_clients.h"

namespace bitewise::console {

namespace consolepb = ::bitewise::webapi::v1;

// Every user, all pages.
absl::StatusOr<v1::ListUsersResponse> AllUsers(meals::BanditClient& bandit);

// Every event of `user_id` (of `meal_id` when not empty), all pages, in the
// store's order. Contexts are dropped unless `with_contexts`.
absl::StatusOr<std::vector<v1::Event>> AllEvents(meals::BanditClient& bandit,
                                                 const std::string& user_id,
                                                 const std::string& meal_id,
                                                 bool with_contexts,
                                                 bool* contexts_withheld);

// Attempts (completed events), failures (completed with loss >= 0.5) and
// pending events per meal, meals in the order of their first event.
consolepb::MealsReply MealsOf(const std::string& user_id,
                              const std::vector<v1::Event>& events);

// The events as CSV: a header, then one row per event with the fields of
// ListEvents in its order; repeated fields are ';'-joined in one cell;
// contexts only when `with_contexts`. When the BanditService withholds
// this identity's vectors (`withheld`), the post hoc column is headed
// posthoc_withheld and its cells are empty, and there is no context column.
std::string EventsCsv(const std::vector<v1::Event>& events, bool with_contexts,
                      bool withheld = false);

// The same CSV for a download, a page of ListEvents at a time, so that a
// long history (at d = 2048, 43 KB of CSV a bite) is never held whole.
class EventsCsvStream {
 public:
  // Reads the first page: its error (an unknown person, a bad id) is the
  // download's, before anything is sent.
  static absl::StatusOr<std::unique_ptr<EventsCsvStream>> Start(
      meals::BanditClient& bandit, const std::string& user_id,
      const std::string& meal_id, bool with_contexts, int page_size = 1000);
  bool contexts_withheld() const { return withheld_; }
  // The next piece: the header and the first page's rows, then a page's
  // rows at a time; "" when done. An error when a later page cannot be
  // read (the download is then cut off).
  absl::StatusOr<std::string> Next();

 private:
  // Appends the next page's rows to `out` (reading it if need be).
  absl::Status ReadPage(std::string* out);

  EventsCsvStream(meals::BanditClient& bandit, v1::ListEventsRequest request,
                  bool with_contexts)
      : bandit_(bandit),
        request_(std::move(request)),
        with_contexts_(with_contexts) {}

  meals::BanditClient& bandit_;
  v1::ListEventsRequest request_;
  const bool with_contexts_;
  bool withheld_ = false;
  bool header_sent_ = false;
  bool done_ = false;
  int pages_ = 0;
  std::optional<v1::ListEventsResponse> page_;  // read, not yet sent
};

// Every action's estimate at the context of `event_id` from the person's
// current model, as the learner computes it at Select (Estimate), with
// each action's count.
absl::StatusOr<consolepb::EstimatesReply> EstimatesFor(
    meals::BanditClient& bandit, const std::string& user_id,
    const std::string& event_id);

}  // namespace bitewise::console

#endif  // BITEWISE_CLIENTS_CONSOLE_RESEARCH_H_
