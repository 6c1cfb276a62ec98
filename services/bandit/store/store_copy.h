// Moving users between EventStores (bitewise-admin copy / verify): a
// workstation replaced, a backup restored, one person's history moved to
// another robot's store. Works through the EventStore interface only, so
// any two stores can be copied between.
//
// A copy recreates each user (configuration, population prior, creation
// time) and replays its events through the store's own writes: completed
// events in model_version order (so each gets the same model_version and
// the model is the same), then pending events. Event ids are the target's
// own (a client holding an id from the source must select again);
// checkpoints are not copied (they are derived, and rebuilt as users eat).
// A copy of every user also copies the audit log, entry for entry, after
// the target's own; population pools are not copied (they are derived:
// BuildPopulationPrior makes one from the copied users).
#ifndef BITEWISE_SERVICES_BANDIT_STORE_STORE_COPY_H_
#define BITEWISE_SERVICES_BANDIT_STORE_STORE_COPY_H_

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "services/bandit/store/event_store.h"

namespace bitewise::bandit {

struct CopyReport {
  int64_t users = 0;
  int64_t events = 0;
  int64_t audit_entries = 0;
};

// Copies every user of `from` (or only `user_id`, if not empty) into `to`,
// and with every user the audit log. ALREADY_EXISTS naming the user if
// `to` has it; a user whose copy fails halfway is deleted from `to` again,
// and the error says which user and event. Users copied before the failure
// stay (each is whole). `interrupted`, if given, is asked between events:
// when it says so, the user being copied is deleted from `to` again and
// the copy ends with CANCELLED saying how many users were copied whole.
absl::StatusOr<CopyReport> CopyUsers(
    EventStore& from, EventStore& to, const std::string& user_id = "",
    const std::function<bool()>& interrupted = nullptr);

struct VerifyReport {
  // Empty when the copy is equal (at most 100, each naming the user and
  // what differs).
  std::vector<std::string> differences;
  int64_t users = 0;
  int64_t events = 0;
  int64_t audit_entries = 0;  // of `a`, when comparing all users
  // Largest relative difference of any action's theta and phi between the
  // models rebuilt from either store's log.
  double worst_model_difference = 0.0;
};

// Compares every user of `a` (or only `user_id`) with the same user in `b`:
// configuration, creation time, model_version, each completed event field
// for field (bit for bit) in model_version order, the pending events, and
// the models rebuilt from both logs (equal within `model_tolerance`,
// relative). Users `b` has and `a` has not are differences too (when
// comparing all users), and so, then, is every audit entry of `a` that
// `b` lacks or holds otherwise (time, method, target, identity, role, peer,
// result; ids may differ, and `b` may have entries of its own before
// them). An error means the comparison could not run.
absl::StatusOr<VerifyReport> VerifyCopy(EventStore& a, EventStore& b,
                                        const std::string& user_id = "",
                                        double model_tolerance = 1e-12);

}  // namespace bitewise::bandit

#endif  // BITEWISE_SERVICES_BANDIT_STORE_STORE_COPY_H_
