#include "services/bandit/bandit_service.h"

#include <string>
#include <vector>

#include "services/bandit/converters.h"
#include "services/common/rpc_handler.h"
#include "services/common/rpc_methods.h"
#include "services/common/status_macros.h"

namespace bitewise::bandit {

BanditServiceImpl::BanditServiceImpl(const RpcEnvironment* env,
                                     BanditEngine* engine,
                                     const BanditConfig& defaults)
    : env_(env), engine_(engine), defaults_(defaults) {}

grpc::Status BanditServiceImpl::Select(grpc::ServerContext* context,
                                       const v1::SelectRequest* request,
                                       v1::SelectResponse* response) {
  return RunRpc(*env_, BITEWISE_RPC_METHOD(v1::BanditService), context,
                [&]() -> absl::Status {
                  ASSIGN_OR_RETURN(
                      const SelectResult result,
                      engine_->Select(SelectInputFromProto(*request)));
                  SelectToProto(result, response);
                  return absl::OkStatus();
                });
}

grpc::Status BanditServiceImpl::Update(grpc::ServerContext* context,
                                       const v1::UpdateRequest* request,
                                       v1::UpdateResponse* response) {
  return RunRpc(*env_, BITEWISE_RPC_METHOD(v1::BanditService), context,
                [&]() -> absl::Status {
                  ASSIGN_OR_RETURN(const UpdateInput input,
                                   UpdateInputFromProto(*request));
                  ASSIGN_OR_RETURN(const UpdateResult result,
                                   engine_->Update(input));
                  UpdateToProto(result, response);
                  return absl::OkStatus();
                });
}

grpc::Status BanditServiceImpl::CreateUser(grpc::ServerContext* context,
                                           const v1::CreateUserRequest* request,
                                           v1::User* response) {
  return RunRpc(
      *env_, BITEWISE_RPC_METHOD(v1::BanditService), context,
      [&]() -> absl::Status {
        RETURN_IF_ERROR(ValidateUserId(request->user_id()));
        ASSIGN_OR_RETURN(
            const BanditConfig config,
            ConfigFromProto(request->config(), defaults_, request->user_id()));
        ASSIGN_OR_RETURN(const UserRecord user,
                         engine_->CreateUser(request->user_id(), config,
                                             request->config().prior_rounds()));
        UserToProto(user, response);
        return absl::OkStatus();
      },
      RpcPolicy::kNormal, request->user_id());
}

grpc::Status BanditServiceImpl::GetUser(grpc::ServerContext* context,
                                        const v1::GetUserRequest* request,
                                        v1::User* response) {
  return RunRpc(*env_, BITEWISE_RPC_METHOD(v1::BanditService), context,
                [&]() -> absl::Status {
                  ASSIGN_OR_RETURN(const UserRecord user,
                                   engine_->GetUser(request->user_id()));
                  UserToProto(user, response);
                  return absl::OkStatus();
                });
}

grpc::Status BanditServiceImpl::ListUsers(grpc::ServerContext* context,
                                          const v1::ListUsersRequest* request,
                                          v1::ListUsersResponse* response) {
  return RunRpc(*env_, BITEWISE_RPC_METHOD(v1::BanditService), context,
                [&]() -> absl::Status {
                  ASSIGN_OR_RETURN(
                      const PageResult<UserRecord> page,
                      engine_->ListUsers(PageFromProto(request->page_size(),
                                                       request->page_token())));
                  for (const UserRecord& user : page.items) {
                    UserToProto(user, response->add_users());
                  }
                  response->set_next_page_token(page.next_page_token);
                  return absl::OkStatus();
                });
}

grpc::Status BanditServiceImpl::ResetUser(grpc::ServerContext* context,
                                          const v1::ResetUserRequest* request,
                                          v1::User* response) {
  return RunRpc(
      *env_, BITEWISE_RPC_METHOD(v1::BanditService), context,
      [&]() -> absl::Status {
        ASSIGN_OR_RETURN(const UserRecord user,
                         engine_->ResetUser(request->user_id()));
        UserToProto(user, response);
        return absl::OkStatus();
      },
      RpcPolicy::kNormal, request->user_id());
}

grpc::Status BanditServiceImpl::SetLearner(grpc::ServerContext* context,
                                           const v1::SetLearnerRequest* request,
                                           v1::User* response) {
  return RunRpc(
      *env_, BITEWISE_RPC_METHOD(v1::BanditService), context,
      [&]() -> absl::Status {
        if (request->learner() == v1::LEARNER_UNSPECIFIED) {
          return absl::InvalidArgumentError(
              "learner: unset (LEARNER_UNSPECIFIED); name the learner to "
              "move the user to");
        }
        ASSIGN_OR_RETURN(
            const UserRecord user,
            engine_->SetLearner(request->user_id(),
                                static_cast<Learner>(request->learner())));
        UserToProto(user, response);
        return absl::OkStatus();
      },
      RpcPolicy::kNormal, request->user_id());
}

grpc::Status BanditServiceImpl::DeleteUser(grpc::ServerContext* context,
                                           const v1::DeleteUserRequest* request,
                                           v1::DeleteUserResponse*) {
  return RunRpc(
      *env_, BITEWISE_RPC_METHOD(v1::BanditService), context,
      [&] { return engine_->DeleteUser(request->user_id()); },
      RpcPolicy::kNormal, request->user_id());
}

grpc::Status BanditServiceImpl::GetModel(grpc::ServerContext* context,
                                         const v1::GetModelRequest* request,
                                         v1::Model* response) {
  return RunRpc(*env_, BITEWISE_RPC_METHOD(v1::BanditService), context,
                [&]() -> absl::Status {
                  ASSIGN_OR_RETURN(const ModelExport model,
                                   engine_->GetModel(request->user_id()));
                  ModelToProto(model, response);
                  return absl::OkStatus();
                });
}

grpc::Status BanditServiceImpl::Estimate(grpc::ServerContext* context,
                                         const v1::EstimateRequest* request,
                                         v1::EstimateResponse* response) {
  return RunRpc(*env_, BITEWISE_RPC_METHOD(v1::BanditService), context,
                [&]() -> absl::Status {
                  // Widths at contexts of the caller's choosing would give
                  // away each action's sum of c c^T, the contexts withheld.
                  if (!CallerMayReadContexts()) {
                    return absl::PermissionDeniedError(
                        "Estimate: this identity's role withholds contexts "
                        "(without_contexts), and an estimate's width at a "
                        "chosen context reveals what the model learned of "
                        "them");
                  }
                  ASSIGN_OR_RETURN(const EstimateResult result,
                                   engine_->Estimate(request->user_id(),
                                                     request->context()));
                  EstimateToProto(result, response);
                  return absl::OkStatus();
                });
}

grpc::Status BanditServiceImpl::ListEvents(grpc::ServerContext* context,
                                           const v1::ListEventsRequest* request,
                                           v1::ListEventsResponse* response) {
  return RunRpc(*env_, BITEWISE_RPC_METHOD(v1::BanditService), context,
                [&]() -> absl::Status {
                  ASSIGN_OR_RETURN(const PageResult<EventRecord> page,
                                   engine_->ListEvents(
                                       request->user_id(), request->meal_id(),
                                       PageFromProto(request->page_size(),
                                                     request->page_token())));
                  for (const EventRecord& event : page.items) {
                    EventToProto(event, response->add_events());
                  }
                  response->set_next_page_token(page.next_page_token);
                  if (!CallerMayReadContexts()) WithholdContexts(response);
                  return absl::OkStatus();
                });
}

grpc::Status BanditServiceImpl::BuildPopulationPrior(
    grpc::ServerContext* context,
    const v1::BuildPopulationPriorRequest* request,
    v1::PopulationPool* response) {
  return RunRpc(*env_, BITEWISE_RPC_METHOD(v1::BanditService), context,
                [&]() -> absl::Status {
                  ASSIGN_OR_RETURN(const BanditConfig like,
                                   ConfigFromProto(request->like(), defaults_,
                                                   "population pool"));
                  ASSIGN_OR_RETURN(const PoolRecord pool,
                                   engine_->BuildPopulationPool(like));
                  PoolToProto(pool, response);
                  return absl::OkStatus();
                });
}

grpc::Status BanditServiceImpl::CheckStore(grpc::ServerContext* context,
                                           const v1::CheckStoreRequest*,
                                           v1::CheckStoreResponse* response) {
  return RunRpc(*env_, BITEWISE_RPC_METHOD(v1::BanditService), context,
                [&]() -> absl::Status {
                  const absl::Time start = absl::Now();
                  ASSIGN_OR_RETURN(const StoreCheckReport report,
                                   engine_->CheckStore());
                  CheckReportToProto(report, absl::Now() - start, response);
                  return absl::OkStatus();
                });
}

grpc::Status BanditServiceImpl::ListAudit(grpc::ServerContext* context,
                                          const v1::ListAuditRequest* request,
                                          v1::ListAuditResponse* response) {
  return RunRpc(*env_, BITEWISE_RPC_METHOD(v1::BanditService), context,
                [&]() -> absl::Status {
                  ASSIGN_OR_RETURN(
                      const PageResult<AuditEntry> page,
                      engine_->ListAudit(PageFromProto(request->page_size(),
                                                       request->page_token())));
                  for (const AuditEntry& entry : page.items) {
                    AuditToProto(entry, response->add_records());
                  }
                  response->set_next_page_token(page.next_page_token);
                  return absl::OkStatus();
                });
}

absl::Status StoreAuditSink::Record(const AuditEvent& event) {
  AuditEntry entry;
  static_cast<AuditEvent&>(entry) = event;
  return store_->AppendAudit(entry).status();
}

}  // namespace bitewise::bandit
