#include "services/bandit/converters.h"

#include <algorithm>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "google/protobuf/timestamp.pb.h"
#include "services/bandit/core/learners.h"

namespace bitewise::bandit {
namespace {

void TimeToProto(absl::Time t, google::protobuf::Timestamp* proto) {
  const int64_t micros = absl::ToUnixMicros(t);
  int64_t seconds = micros / 1000000;
  int64_t rem = micros % 1000000;
  if (rem < 0) {
    rem += 1000000;
    --seconds;
  }
  proto->set_seconds(seconds);
  proto->set_nanos(static_cast<int32_t>(rem * 1000));
}

// A stable default seed per user, the same on every platform: FNV-1a's
// steps and prime, from an offset basis one digit short of FNV's
// (14695981039346656037). Kept as it is: a user's seed is stored when the
// user is made, and every earlier release made seeds with this value.
uint64_t StableHash(const std::string& s) {
  uint64_t h = 1469598103934665603ull;
  for (const unsigned char ch : s) {
    h ^= ch;
    h *= 1099511628211ull;
  }
  return h;
}

// Every action's estimate, named.
void EstimatesToProto(
    const std::vector<ActionEstimate>& estimates,
    const std::vector<std::string>& action_names,
    google::protobuf::RepeatedPtrField<v1::ActionEstimate>* proto) {
  for (size_t a = 0; a < estimates.size(); ++a) {
    v1::ActionEstimate* e = proto->Add();
    e->set_action(static_cast<int32_t>(a));
    e->set_action_name(action_names[a]);
    e->set_predicted_loss(estimates[a].predicted_loss);
    e->set_width(estimates[a].width);
    e->set_lcb(estimates[a].lcb);
  }
}

}  // namespace

absl::StatusOr<BanditConfig> ConfigFromProto(const v1::UserConfig& proto,
                                             const BanditConfig& defaults,
                                             const std::string& user_id) {
  BanditConfig config = defaults;
  // The API's LEARNER_* numbers are the learners' own (learners.h).
  if (proto.learner() != v1::LEARNER_UNSPECIFIED) {
    const LearnerSpec* spec =
        FindLearner(static_cast<Learner>(proto.learner()));
    if (spec == nullptr) {
      return absl::InvalidArgumentError(
          absl::StrCat("config.learner: unknown value ", proto.learner(),
                       " (known: ", LearnerNames(), ")"));
    }
    config.learner = spec->learner;
  }
  switch (proto.strategy()) {
    case v1::STRATEGY_UNSPECIFIED:
      break;
    case v1::STRATEGY_LINUCB:
      config.strategy = Strategy::kLinUcb;
      break;
    case v1::STRATEGY_GREEDY:
      config.strategy = Strategy::kGreedy;
      break;
    case v1::STRATEGY_EPSILON_GREEDY:
      config.strategy = Strategy::kEpsilonGreedy;
      break;
    case v1::STRATEGY_THOMPSON:
      config.strategy = Strategy::kThompson;
      break;
    case v1::STRATEGY_UNIFORM:
      config.strategy = Strategy::kUniform;
      break;
    default:
      return absl::InvalidArgumentError(
          absl::StrCat("config.strategy: unknown value ", proto.strategy()));
  }
  if (proto.has_alpha()) config.alpha = proto.alpha();
  if (proto.has_lambda_c()) config.lambda_c = proto.lambda_c();
  if (proto.has_lambda_p()) config.lambda_p = proto.lambda_p();
  if (proto.has_epsilon()) config.epsilon = proto.epsilon();
  if (proto.has_phi_radius()) config.phi_radius = proto.phi_radius();
  // Checked here, on the value sent, so that the message names it (an int
  // cannot hold every uint32); ValidateConfig checks the rest.
  if (proto.context_dim() > (1u << 16)) {
    return absl::InvalidArgumentError(
        absl::StrCat("config.context_dim: must be in [1, 65536], got ",
                     proto.context_dim()));
  }
  if (proto.posthoc_dim() > 1024) {
    return absl::InvalidArgumentError(absl::StrCat(
        "config.posthoc_dim: must be in [0, 1024], got ", proto.posthoc_dim()));
  }
  if (proto.context_dim() > 0) {
    config.context_dim = static_cast<int>(proto.context_dim());
  }
  if (proto.posthoc_dim() > 0) {
    config.posthoc_dim = static_cast<int>(proto.posthoc_dim());
  }
  if (proto.action_names_size() > 0) {
    config.action_names.assign(proto.action_names().begin(),
                               proto.action_names().end());
  }
  config.seed = proto.has_seed() ? proto.seed() : StableHash(user_id);
  config.importance_weighting = proto.importance_weighting();
  absl::Status status = ValidateConfig(config);
  if (!status.ok()) {
    return absl::InvalidArgumentError(
        absl::StrCat("config.", status.message()));
  }
  return config;
}

void ConfigToProto(const BanditConfig& config, v1::UserConfig* proto) {
  proto->set_learner(static_cast<v1::Learner>(config.learner));
  proto->set_strategy(static_cast<v1::Strategy>(config.strategy));
  proto->set_alpha(config.alpha);
  proto->set_lambda_c(config.lambda_c);
  proto->set_lambda_p(config.lambda_p);
  proto->set_epsilon(config.epsilon);
  proto->set_phi_radius(config.phi_radius);
  proto->set_context_dim(static_cast<uint32_t>(config.context_dim));
  proto->set_posthoc_dim(static_cast<uint32_t>(config.posthoc_dim));
  for (const std::string& name : config.action_names) {
    proto->add_action_names(name);
  }
  proto->set_seed(config.seed);
  proto->set_importance_weighting(config.importance_weighting);
  if (config.prior.enabled()) {
    proto->set_prior_rounds(config.prior.rounds);
    proto->set_prior_pool_version(config.prior.pool_version);
  }
}

void PoolToProto(const PoolRecord& pool, v1::PopulationPool* proto) {
  proto->set_pool_version(pool.pool_version);
  proto->set_users(pool.users);
  TimeToProto(pool.created_at, proto->mutable_created_at());
  v1::UserConfig* like = proto->mutable_like();
  like->set_learner(static_cast<v1::Learner>(pool.learner));
  like->set_context_dim(static_cast<uint32_t>(pool.context_dim));
  like->set_posthoc_dim(static_cast<uint32_t>(pool.posthoc_dim));
  for (const std::string& name : pool.action_names) {
    like->add_action_names(name);
  }
  proto->set_context_msn(pool.prior.context_msn);
  proto->set_posthoc_msn(pool.prior.posthoc_msn);
}

void UserToProto(const UserRecord& user, v1::User* proto) {
  proto->set_user_id(user.user_id);
  ConfigToProto(user.config, proto->mutable_config());
  proto->set_model_version(user.model_version);
  proto->set_pending_events(user.pending_events);
  TimeToProto(user.created_at, proto->mutable_created_at());
}

void EventToProto(const EventRecord& event, v1::Event* proto) {
  proto->set_event_id(absl::StrCat(event.event_id));
  proto->set_user_id(event.user_id);
  proto->set_meal_id(event.meal_id);
  proto->set_item_label(event.item_label);
  proto->mutable_context()->Add(event.context.begin(), event.context.end());
  proto->set_action(event.action);
  proto->set_propensity(event.propensity);
  proto->set_completed(event.completed);
  TimeToProto(event.selected_at, proto->mutable_selected_at());
  if (event.completed) {
    proto->set_loss(event.loss);
    proto->mutable_posthoc()->Add(event.posthoc.begin(), event.posthoc.end());
    proto->set_model_version(event.model_version);
    TimeToProto(event.updated_at, proto->mutable_updated_at());
  }
}

void SelectToProto(const SelectResult& result, v1::SelectResponse* proto) {
  proto->set_event_id(absl::StrCat(result.event_id));
  proto->set_action(result.action);
  proto->set_action_name(result.action_name);
  proto->set_propensity(result.propensity);
  proto->set_model_version(result.model_version);
  proto->mutable_predicted_posthoc()->Add(result.predicted_posthoc.begin(),
                                          result.predicted_posthoc.end());
  EstimatesToProto(result.estimates, result.action_names,
                   proto->mutable_estimates());
}

void EstimateToProto(const EstimateResult& result,
                     v1::EstimateResponse* proto) {
  proto->set_model_version(result.model_version);
  proto->mutable_predicted_posthoc()->Add(result.predicted_posthoc.begin(),
                                          result.predicted_posthoc.end());
  EstimatesToProto(result.estimates, result.action_names,
                   proto->mutable_estimates());
}

void ModelToProto(const ModelExport& model, v1::Model* proto) {
  proto->set_user_id(model.user.user_id);
  ConfigToProto(model.user.config, proto->mutable_config());
  proto->set_model_version(model.user.model_version);
  for (const ActionModelExport& a : model.actions) {
    v1::ActionModel* out = proto->add_actions();
    out->set_action(a.action);
    out->set_action_name(a.action_name);
    out->set_count(a.count);
    out->mutable_theta()->Add(a.theta.begin(), a.theta.end());
    out->mutable_phi()->Add(a.phi.begin(), a.phi.end());
    out->set_mean_loss(a.mean_loss);
  }
}

absl::StatusOr<int64_t> ParseEventId(const std::string& event_id) {
  // Exactly what Select returns: decimal digits, no sign, spaces or leading
  // zeros (SimpleAtoi alone would take " 1" and "+5").
  int64_t id = 0;
  const bool canonical =
      !event_id.empty() && event_id.size() <= 19 && event_id[0] != '0' &&
      std::all_of(event_id.begin(), event_id.end(),
                  [](char c) { return c >= '0' && c <= '9'; });
  if (!canonical || !absl::SimpleAtoi(event_id, &id) || id <= 0) {
    return absl::InvalidArgumentError(absl::StrCat(
        "event_id: expected the decimal id returned by Select, got \"",
        event_id.substr(0, 64), "\""));
  }
  return id;
}

Page PageFromProto(int32_t page_size, const std::string& page_token) {
  Page page;
  if (page_size > 0) page.page_size = page_size;
  page.page_token = page_token;
  // Below the default 4 MiB message limit, so every page can be sent.
  page.max_bytes = int64_t{3} << 20;
  return page;
}

SelectInput SelectInputFromProto(const v1::SelectRequest& proto) {
  SelectInput input;
  input.user_id = proto.user_id();
  input.context.assign(proto.context().begin(), proto.context().end());
  input.meal_id = proto.meal_id();
  input.item_label = proto.item_label();
  return input;
}

absl::StatusOr<UpdateInput> UpdateInputFromProto(
    const v1::UpdateRequest& proto) {
  absl::StatusOr<int64_t> event_id = ParseEventId(proto.event_id());
  if (!event_id.ok()) return event_id.status();
  UpdateInput input;
  input.event_id = *event_id;
  input.loss = proto.loss();
  input.posthoc.assign(proto.posthoc().begin(), proto.posthoc().end());
  return input;
}

void UpdateToProto(const UpdateResult& result, v1::UpdateResponse* proto) {
  proto->set_model_version(result.model_version);
  proto->set_already_applied(result.already_applied);
  proto->set_user_id(result.user_id);
}

void CheckReportToProto(const StoreCheckReport& report, absl::Duration took,
                        v1::CheckStoreResponse* proto) {
  proto->set_ok(report.findings.empty());
  for (const std::string& finding : report.findings) {
    proto->add_findings(finding);
  }
  proto->set_users_checked(report.users_checked);
  proto->set_events_checked(report.events_checked);
  proto->set_seconds(absl::ToDoubleSeconds(took));
}

void AuditToProto(const AuditEntry& entry, v1::AuditRecord* proto) {
  proto->set_audit_id(entry.audit_id);
  TimeToProto(entry.time, proto->mutable_time());
  proto->set_method(entry.method);
  proto->set_target(entry.target);
  proto->set_identity(entry.identity);
  proto->set_role(entry.role);
  proto->set_peer(entry.peer);
  proto->set_result(entry.result);
}

void WithholdContexts(v1::ListEventsResponse* response) {
  for (v1::Event& event : *response->mutable_events()) {
    event.clear_context();
    event.clear_posthoc();
  }
  response->set_contexts_withheld(true);
}

}  // namespace bitewise::bandit
