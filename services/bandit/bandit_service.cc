#include "services/bandit/bandit_service.h"

#include <string>
#include <vector>

#include "services/bandit/converters.h"
#include "services/common/grpc_status.h"

namespace bitewise::bandit {
namespace {

grpc::Status Fail(const absl::Status& status) { return ToGrpcStatus(status); }

}  // namespace

BanditServiceImpl::BanditServiceImpl(BanditEngine* engine,
                                     const BanditConfig& defaults)
    : engine_(engine), defaults_(defaults) {}

grpc::Status BanditServiceImpl::Select(grpc::ServerContext*,
                                       const v1::SelectRequest* request,
                                       v1::SelectResponse* response) {
  SelectInput input;
  input.user_id = request->user_id();
  input.context.assign(request->context().begin(), request->context().end());
  input.meal_id = request->meal_id();
  input.item_label = request->item_label();
  absl::StatusOr<SelectResult> result = engine_->Select(input);
  if (!result.ok()) return Fail(result.status());
  SelectToProto(*result, response);
  return grpc::Status::OK;
}

grpc::Status BanditServiceImpl::Update(grpc::ServerContext*,
                                       const v1::UpdateRequest* request,
                                       v1::UpdateResponse* response) {
  absl::StatusOr<int64_t> event_id = ParseEventId(request->event_id());
  if (!event_id.ok()) return Fail(event_id.status());
  UpdateInput input;
  input.event_id = *event_id;
  input.loss = request->loss();
  input.posthoc.assign(request->posthoc().begin(), request->posthoc().end());
  absl::StatusOr<UpdateResult> result = engine_->Update(input);
  if (!result.ok()) return Fail(result.status());
  response->set_model_version(result->model_version);
  response->set_already_applied(result->already_applied);
  response->set_user_id(result->user_id);
  return grpc::Status::OK;
}

grpc::Status BanditServiceImpl::CreateUser(grpc::ServerContext*,
                                           const v1::CreateUserRequest* request,
                                           v1::User* response) {
  absl::Status valid = ValidateUserId(request->user_id());
  if (!valid.ok()) return Fail(valid);
  absl::StatusOr<BanditConfig> config =
      ConfigFromProto(request->config(), defaults_, request->user_id());
  if (!config.ok()) return Fail(config.status());
  absl::StatusOr<UserRecord> user = engine_->CreateUser(
      request->user_id(), *config, request->config().prior_rounds());
  if (!user.ok()) return Fail(user.status());
  UserToProto(*user, response);
  return grpc::Status::OK;
}

grpc::Status BanditServiceImpl::GetUser(grpc::ServerContext*,
                                        const v1::GetUserRequest* request,
                                        v1::User* response) {
  absl::StatusOr<UserRecord> user = engine_->GetUser(request->user_id());
  if (!user.ok()) return Fail(user.status());
  UserToProto(*user, response);
  return grpc::Status::OK;
}

grpc::Status BanditServiceImpl::ListUsers(grpc::ServerContext*,
                                          const v1::ListUsersRequest* request,
                                          v1::ListUsersResponse* response) {
  absl::StatusOr<PageResult<UserRecord>> page = engine_->ListUsers(
      PageFromProto(request->page_size(), request->page_token()));
  if (!page.ok()) return Fail(page.status());
  for (const UserRecord& user : page->items) {
    UserToProto(user, response->add_users());
  }
  response->set_next_page_token(page->next_page_token);
  return grpc::Status::OK;
}

grpc::Status BanditServiceImpl::ResetUser(grpc::ServerContext*,
                                          const v1::ResetUserRequest* request,
                                          v1::User* response) {
  absl::StatusOr<UserRecord> user = engine_->ResetUser(request->user_id());
  if (!user.ok()) return Fail(user.status());
  UserToProto(*user, response);
  return grpc::Status::OK;
}

grpc::Status BanditServiceImpl::DeleteUser(grpc::ServerContext*,
                                           const v1::DeleteUserRequest* request,
                                           v1::DeleteUserResponse*) {
  return Fail(engine_->DeleteUser(request->user_id()));
}

grpc::Status BanditServiceImpl::GetModel(grpc::ServerContext*,
                                         const v1::GetModelRequest* request,
                                         v1::Model* response) {
  absl::StatusOr<ModelExport> model = engine_->GetModel(request->user_id());
  if (!model.ok()) return Fail(model.status());
  ModelToProto(*model, response);
  return grpc::Status::OK;
}

grpc::Status BanditServiceImpl::ListEvents(grpc::ServerContext*,
                                           const v1::ListEventsRequest* request,
                                           v1::ListEventsResponse* response) {
  absl::StatusOr<PageResult<EventRecord>> page = engine_->ListEvents(
      request->user_id(), request->meal_id(),
      PageFromProto(request->page_size(), request->page_token()));
  if (!page.ok()) return Fail(page.status());
  for (const EventRecord& event : page->items) {
    EventToProto(event, response->add_events());
  }
  response->set_next_page_token(page->next_page_token);
  return grpc::Status::OK;
}

grpc::Status BanditServiceImpl::BuildPopulationPrior(
    grpc::ServerContext*, const v1::BuildPopulationPriorRequest* request,
    v1::PopulationPool* response) {
  absl::StatusOr<BanditConfig> like =
      ConfigFromProto(request->like(), defaults_, "population pool");
  if (!like.ok()) return Fail(like.status());
  absl::StatusOr<PoolRecord> pool = engine_->BuildPopulationPool(*like);
  if (!pool.ok()) return Fail(pool.status());
  PoolToProto(*pool, response);
  return grpc::Status::OK;
}

}  // namespace bitewise::bandit
