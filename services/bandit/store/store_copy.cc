#include "services/bandit/store/store_copy.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <memory>
#include <utility>

#include "Eigen/Core"
#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "services/bandit/core/learners.h"
#include "services/common/status_macros.h"

namespace bitewise::bandit {
namespace {

constexpr size_t kMaxDifferences = 100;

absl::StatusOr<std::vector<std::string>> AllUserIds(EventStore& store) {
  std::vector<std::string> ids;
  Page page;
  page.page_size = 1000;
  while (true) {
    ASSIGN_OR_RETURN(PageResult<UserRecord> result, store.ListUsers(page));
    for (const UserRecord& user : result.items) ids.push_back(user.user_id);
    if (result.next_page_token.empty()) return ids;
    page.page_token = result.next_page_token;
  }
}

absl::StatusOr<std::vector<EventRecord>> PendingEvents(
    EventStore& store, const std::string& user_id) {
  std::vector<EventRecord> pending;
  Page page;
  page.page_size = 1000;
  while (true) {
    ASSIGN_OR_RETURN(PageResult<EventRecord> result,
                     store.ListEvents(user_id, "", page));
    for (EventRecord& event : result.items) {
      if (!event.completed) pending.push_back(std::move(event));
    }
    if (result.next_page_token.empty()) return pending;
    page.page_token = result.next_page_token;
  }
}

absl::StatusOr<std::vector<AuditEntry>> AllAudit(EventStore& store) {
  std::vector<AuditEntry> entries;
  Page page;
  page.page_size = 1000;
  while (true) {
    ASSIGN_OR_RETURN(PageResult<AuditEntry> result, store.ListAudit(page));
    for (AuditEntry& entry : result.items) entries.push_back(std::move(entry));
    if (result.next_page_token.empty()) return entries;
    page.page_token = result.next_page_token;
  }
}

bool SameAudit(const AuditEntry& a, const AuditEntry& b) {
  return a.time == b.time && a.method == b.method && a.target == b.target &&
         a.identity == b.identity && a.role == b.role && a.peer == b.peer &&
         a.result == b.result;
}

absl::Status CopyUser(EventStore& from, EventStore& to,
                      const std::string& user_id,
                      const std::function<bool()>& interrupted,
                      CopyReport& report) {
  ASSIGN_OR_RETURN(UserRecord user, from.GetUser(user_id));
  ASSIGN_OR_RETURN(std::vector<EventRecord> completed,
                   from.CompletedEvents(user_id));
  ASSIGN_OR_RETURN(std::vector<EventRecord> pending,
                   PendingEvents(from, user_id));
  user.model_version = 0;
  user.pending_events = 0;
  RETURN_IF_ERROR(to.CreateUser(user));
  // From here on a failure takes the half-copied user away again.
  auto undo = [&](const absl::Status& status, int64_t event_id) {
    const absl::Status removed = to.DeleteUser(user_id);
    return absl::Status(
        status.code(),
        absl::StrCat("copying user \"", user_id, "\", event ", event_id, ": ",
                     status.message(),
                     removed.ok() ? "; the user was removed from the copy"
                                  : absl::StrCat("; removing the half-copied "
                                                 "user failed too: ",
                                                 removed.message())));
  };
  const auto stop = [&](int64_t event_id) {
    return undo(absl::CancelledError(
                    absl::StrCat("interrupted; ", report.users,
                                 " users before it were copied whole")),
                event_id);
  };
  for (const EventRecord& event : completed) {
    if (interrupted && interrupted()) return stop(event.event_id);
    absl::StatusOr<int64_t> id = to.AppendPending(event);
    if (!id.ok()) return undo(id.status(), event.event_id);
    absl::StatusOr<EventRecord> done = to.CompleteEvent(
        *id, event.loss, event.posthoc, event.weight, event.updated_at);
    if (!done.ok()) return undo(done.status(), event.event_id);
    if (done->model_version != event.model_version) {
      return undo(absl::DataLossError(absl::StrCat(
                      "completed as model_version ", done->model_version,
                      " instead of ", event.model_version)),
                  event.event_id);
    }
  }
  for (const EventRecord& event : pending) {
    if (interrupted && interrupted()) return stop(event.event_id);
    absl::StatusOr<int64_t> id = to.AppendPending(event);
    if (!id.ok()) return undo(id.status(), event.event_id);
  }
  ++report.users;
  report.events += static_cast<int64_t>(completed.size() + pending.size());
  return absl::OkStatus();
}

bool SameBits(double a, double b) { return std::memcmp(&a, &b, 8) == 0; }

bool SameBits(const std::vector<double>& a, const std::vector<double>& b) {
  return a.size() == b.size() &&
         (a.empty() || std::memcmp(a.data(), b.data(), 8 * a.size()) == 0);
}

// What differs between two configurations, or "".
std::string ConfigDifference(const BanditConfig& a, const BanditConfig& b) {
  if (a.learner != b.learner) return "learner";
  if (a.strategy != b.strategy) return "strategy";
  if (!SameBits(a.alpha, b.alpha)) return "alpha";
  if (!SameBits(a.lambda_c, b.lambda_c)) return "lambda_c";
  if (!SameBits(a.lambda_p, b.lambda_p)) return "lambda_p";
  if (!SameBits(a.epsilon, b.epsilon)) return "epsilon";
  if (!SameBits(a.phi_radius, b.phi_radius)) return "phi_radius";
  if (a.importance_weighting != b.importance_weighting) {
    return "importance_weighting";
  }
  if (a.context_dim != b.context_dim) return "context_dim";
  if (a.posthoc_dim != b.posthoc_dim) return "posthoc_dim";
  if (a.action_names != b.action_names) return "action_names";
  if (a.seed != b.seed) return "seed";
  const PopulationPrior& p = a.prior;
  const PopulationPrior& q = b.prior;
  if (p.pool_version != q.pool_version || !SameBits(p.rounds, q.rounds) ||
      !SameBits(p.context_msn, q.context_msn) ||
      !SameBits(p.posthoc_msn, q.posthoc_msn) ||
      p.theta0.size() != q.theta0.size() || p.phi0.size() != q.phi0.size()) {
    return "prior";
  }
  for (size_t k = 0; k < p.theta0.size(); ++k) {
    if (!SameBits(p.theta0[k], q.theta0[k])) return "prior";
  }
  for (size_t k = 0; k < p.phi0.size(); ++k) {
    if (!SameBits(p.phi0[k], q.phi0[k])) return "prior";
  }
  return "";
}

// What differs between the selections of two events, or "".
std::string SelectionDifference(const EventRecord& a, const EventRecord& b) {
  if (a.meal_id != b.meal_id) return "meal_id";
  if (a.item_label != b.item_label) return "item_label";
  if (!SameBits(a.context, b.context)) return "context";
  if (a.action != b.action) return "action";
  if (!SameBits(a.propensity, b.propensity)) return "propensity";
  if (a.selected_at != b.selected_at) return "selected_at";
  return "";
}

std::string OutcomeDifference(const EventRecord& a, const EventRecord& b) {
  if (!SameBits(a.loss, b.loss)) return "loss";
  if (!SameBits(a.posthoc, b.posthoc)) return "posthoc";
  if (!SameBits(a.weight, b.weight)) return "weight";
  if (a.model_version != b.model_version) return "model_version";
  if (a.updated_at != b.updated_at) return "updated_at";
  return "";
}

std::vector<Round> Rounds(const std::vector<EventRecord>& events) {
  std::vector<Round> rounds;
  rounds.reserve(events.size());
  for (const EventRecord& event : events) rounds.push_back(EventRound(event));
  return rounds;
}

double RelativeDifference(const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
  if (a.size() != b.size()) return INFINITY;
  const double scale = std::max({a.norm(), b.norm(), 1e-300});
  return (a - b).norm() / scale;
}

// Compares one user; appends what differs.
absl::Status VerifyUser(EventStore& a, EventStore& b,
                        const std::string& user_id, double tolerance,
                        VerifyReport& report) {
  auto differ = [&](const std::string& what) {
    if (report.differences.size() < kMaxDifferences) {
      report.differences.push_back(
          absl::StrCat("user \"", user_id, "\": ", what));
    }
  };
  ASSIGN_OR_RETURN(const UserRecord ua, a.GetUser(user_id));
  absl::StatusOr<UserRecord> ub = b.GetUser(user_id);
  if (absl::IsNotFound(ub.status())) {
    differ("missing in the copy");
    return absl::OkStatus();
  }
  RETURN_IF_ERROR(ub.status());
  ++report.users;
  if (const std::string d = ConfigDifference(ua.config, ub->config);
      !d.empty()) {
    differ(absl::StrCat("configuration differs in ", d));
  }
  if (ua.created_at != ub->created_at) differ("created_at differs");
  if (ua.model_version != ub->model_version) {
    differ(absl::StrCat("model_version ", ua.model_version, " against ",
                        ub->model_version));
  }
  ASSIGN_OR_RETURN(const std::vector<EventRecord> ca,
                   a.CompletedEvents(user_id));
  ASSIGN_OR_RETURN(const std::vector<EventRecord> cb,
                   b.CompletedEvents(user_id));
  ASSIGN_OR_RETURN(const std::vector<EventRecord> pa,
                   PendingEvents(a, user_id));
  ASSIGN_OR_RETURN(const std::vector<EventRecord> pb,
                   PendingEvents(b, user_id));
  report.events += static_cast<int64_t>(ca.size() + pa.size());
  if (ca.size() != cb.size()) {
    differ(absl::StrCat(ca.size(), " completed events against ", cb.size()));
  }
  for (size_t i = 0; i < std::min(ca.size(), cb.size()); ++i) {
    std::string d = SelectionDifference(ca[i], cb[i]);
    if (d.empty()) d = OutcomeDifference(ca[i], cb[i]);
    if (!d.empty()) {
      differ(absl::StrCat("completed event ", i + 1, " (model_version ",
                          ca[i].model_version, ") differs in ", d));
    }
  }
  if (pa.size() != pb.size()) {
    differ(absl::StrCat(pa.size(), " pending events against ", pb.size()));
  }
  for (size_t i = 0; i < std::min(pa.size(), pb.size()); ++i) {
    if (const std::string d = SelectionDifference(pa[i], pb[i]); !d.empty()) {
      differ(absl::StrCat("pending event ", i + 1, " differs in ", d));
    }
  }
  // The models themselves, rebuilt from either log.
  absl::StatusOr<std::unique_ptr<LearnerModel>> ma =
      RebuildModel(ua.config, Rounds(ca));
  absl::StatusOr<std::unique_ptr<LearnerModel>> mb =
      RebuildModel(ub->config, Rounds(cb));
  if (!ma.ok() || !mb.ok()) {
    differ(absl::StrCat("a model cannot be rebuilt: ",
                        (ma.ok() ? mb.status() : ma.status()).message()));
    return absl::OkStatus();
  }
  const LearnerModel& model_a = **ma;
  const LearnerModel& model_b = **mb;
  if (model_a.num_actions() != model_b.num_actions()) return absl::OkStatus();
  double worst = 0.0;
  for (int k = 0; k < model_a.num_actions(); ++k) {
    worst =
        std::max(worst, RelativeDifference(model_a.Theta(k), model_b.Theta(k)));
    worst = std::max(worst, RelativeDifference(model_a.Phi(k), model_b.Phi(k)));
  }
  report.worst_model_difference =
      std::max(report.worst_model_difference, worst);
  if (!(worst <= tolerance)) {
    differ(absl::StrCat("models differ by ", worst, " (relative; tolerance ",
                        tolerance, ")"));
  }
  return absl::OkStatus();
}

}  // namespace

absl::StatusOr<CopyReport> CopyUsers(EventStore& from, EventStore& to,
                                     const std::string& user_id,
                                     const std::function<bool()>& interrupted) {
  std::vector<std::string> ids;
  if (user_id.empty()) {
    ASSIGN_OR_RETURN(ids, AllUserIds(from));
  } else {
    ids.push_back(user_id);
  }
  CopyReport report;
  for (const std::string& id : ids) {
    if (interrupted && interrupted()) {
      return absl::CancelledError(
          absl::StrCat("interrupted before user \"", id, "\"; ", report.users,
                       " users before it were copied whole"));
    }
    RETURN_IF_ERROR(CopyUser(from, to, id, interrupted, report));
  }
  if (!user_id.empty()) return report;
  // The administrative history goes with everyone: who reset, deleted or
  // changed whom, and when.
  ASSIGN_OR_RETURN(const std::vector<AuditEntry> audit, AllAudit(from));
  for (const AuditEntry& entry : audit) {
    if (interrupted && interrupted()) {
      return absl::CancelledError(absl::StrCat(
          "interrupted while copying the audit log (", report.audit_entries,
          " of ", audit.size(), " entries copied; every user was copied)"));
    }
    absl::StatusOr<int64_t> id = to.AppendAudit(entry);
    if (!id.ok()) {
      return absl::Status(
          id.status().code(),
          absl::StrCat("copying audit entry ", entry.audit_id, " (",
                       report.audit_entries,
                       " copied before it; every user was copied): ",
                       id.status().message()));
    }
    ++report.audit_entries;
  }
  return report;
}

absl::StatusOr<VerifyReport> VerifyCopy(EventStore& a, EventStore& b,
                                        const std::string& user_id,
                                        double model_tolerance) {
  VerifyReport report;
  if (!user_id.empty()) {
    RETURN_IF_ERROR(VerifyUser(a, b, user_id, model_tolerance, report));
    return report;
  }
  ASSIGN_OR_RETURN(const std::vector<std::string> ids_a, AllUserIds(a));
  ASSIGN_OR_RETURN(const std::vector<std::string> ids_b, AllUserIds(b));
  for (const std::string& id : ids_a) {
    RETURN_IF_ERROR(VerifyUser(a, b, id, model_tolerance, report));
  }
  for (const std::string& id : ids_b) {
    if (!std::binary_search(ids_a.begin(), ids_a.end(), id) &&
        report.differences.size() < kMaxDifferences) {
      report.differences.push_back(
          absl::StrCat("user \"", id, "\": only in the copy"));
    }
  }
  // The audit log: a's entries, in order, at the end of b's.
  ASSIGN_OR_RETURN(const std::vector<AuditEntry> audit_a, AllAudit(a));
  ASSIGN_OR_RETURN(const std::vector<AuditEntry> audit_b, AllAudit(b));
  report.audit_entries = static_cast<int64_t>(audit_a.size());
  if (report.differences.size() >= kMaxDifferences) {
    // already full
  } else if (audit_b.size() < audit_a.size()) {
    report.differences.push_back(absl::StrCat(
        "audit log: ", audit_a.size(), " entries against ", audit_b.size()));
  } else {
    const size_t offset = audit_b.size() - audit_a.size();
    for (size_t i = 0; i < audit_a.size(); ++i) {
      if (!SameAudit(audit_a[i], audit_b[offset + i])) {
        report.differences.push_back(absl::StrCat(
            "audit log: entry ", audit_a[i].audit_id, " differs in the copy (",
            audit_b[offset + i].audit_id, ")"));
        break;
      }
    }
  }
  return report;
}

}  // namespace bitewise::bandit
