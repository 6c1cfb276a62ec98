// Conversions between the bitewise.v1 bandit protos and the engine's domain
// types. Kept apart from the handlers so that each handler reads as
// validate, call the engine, convert back.
#ifndef BITEWISE_SERVICES_BANDIT_CONVERTERS_H_
#define BITEWISE_SERVICES_BANDIT_CONVERTERS_H_

#include <cstdint>
#include <string>

#include "absl/status/statusor.h"
#include "bitewise/v1/bandit.pb.h"
#include "services/bandit/core/config.h"
#include "services/bandit/engine.h"
#include "services/bandit/store/event_store.h"

namespace bitewise::bandit {

// Applies the fields set in `proto` over `defaults`. An unset seed becomes
// a stable hash of `user_id`, so users differ but runs repeat.
// INVALID_ARGUMENT for unknown enum values or out-of-range fields.
absl::StatusOr<BanditConfig> ConfigFromProto(const v1::UserConfig& proto,
                                             const BanditConfig& defaults,
                                             const std::string& user_id);
void ConfigToProto(const BanditConfig& config, v1::UserConfig* proto);
void UserToProto(const UserRecord& user, v1::User* proto);
void PoolToProto(const PoolRecord& pool, v1::PopulationPool* proto);
void EventToProto(const EventRecord& event, v1::Event* proto);
void SelectToProto(const SelectResult& result, v1::SelectResponse* proto);
void EstimateToProto(const EstimateResult& result, v1::EstimateResponse* proto);
void ModelToProto(const ModelExport& model, v1::Model* proto);

// Event ids travel as decimal strings. INVALID_ARGUMENT if malformed.
absl::StatusOr<int64_t> ParseEventId(const std::string& event_id);
// Requests as the engine takes them. Select's fields are checked by the
// engine; Update's event id is parsed here (INVALID_ARGUMENT naming it).
SelectInput SelectInputFromProto(const v1::SelectRequest& proto);
absl::StatusOr<UpdateInput> UpdateInputFromProto(
    const v1::UpdateRequest& proto);
void UpdateToProto(const UpdateResult& result, v1::UpdateResponse* proto);
// A page of at most page_size items (default 100) and about 3 MiB.
Page PageFromProto(int32_t page_size, const std::string& page_token);

void CheckReportToProto(const StoreCheckReport& report, absl::Duration took,
                        v1::CheckStoreResponse* proto);
void AuditToProto(const AuditEntry& entry, v1::AuditRecord* proto);

// Leaves every event's raw context and post hoc vector out and says so
// (contexts_withheld), for a "researcher without_contexts" caller.
void WithholdContexts(v1::ListEventsResponse* response);

}  // namespace bitewise::bandit

#endif  // BITEWISE_SERVICES_BANDIT_CONVERTERS_H_
