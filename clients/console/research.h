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

#include <string>
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
// contexts only when `with_contexts`.
std::string EventsCsv(const std::vector<v1::Event>& events, bool with_contexts);

// Every action's estimate at the context of `event_id` from the person's
// current model, as the learner computes it at Select (Estimate), with
// each action's count.
absl::StatusOr<consolepb::EstimatesReply> EstimatesFor(
    meals::BanditClient& bandit, const std::string& user_id,
    const std::string& event_id);

}  // namespace bitewise::console

#endif  // BITEWISE_CLIENTS_CONSOLE_RESEARCH_H_
