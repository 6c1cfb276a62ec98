// BanditServiceImpl: the gRPC face of the BanditEngine. Each handler
// validates the request, calls the engine and converts the result; errors
// become gRPC statuses through the one mapping in services/common.
// Thread-safe (the engine is).
#ifndef BITEWISE_SERVICES_BANDIT_BANDIT_SERVICE_H_
#define BITEWISE_SERVICES_BANDIT_BANDIT_SERVICE_H_

#include "bitewise/v1/bandit.grpc.pb.h"
#include "services/bandit/core/config.h"
#include "services/bandit/engine.h"
#include "services/common/audit.h"
#include "services/common/rpc_environment.h"

namespace bitewise::bandit {

class BanditServiceImpl final : public v1::BanditService::Service {
 public:
  // `env` (what every call runs with: rpc_environment.h) and `engine` must
  // outlive the service. `defaults` fill the fields that a CreateUser
  // request leaves unset.
  BanditServiceImpl(const RpcEnvironment* env, BanditEngine* engine,
                    const BanditConfig& defaults);

  grpc::Status Select(grpc::ServerContext* context,
                      const v1::SelectRequest* request,
                      v1::SelectResponse* response) override;
  grpc::Status Update(grpc::ServerContext* context,
                      const v1::UpdateRequest* request,
                      v1::UpdateResponse* response) override;
  grpc::Status CreateUser(grpc::ServerContext* context,
                          const v1::CreateUserRequest* request,
                          v1::User* response) override;
  grpc::Status GetUser(grpc::ServerContext* context,
                       const v1::GetUserRequest* request,
                       v1::User* response) override;
  grpc::Status ListUsers(grpc::ServerContext* context,
                         const v1::ListUsersRequest* request,
                         v1::ListUsersResponse* response) override;
  grpc::Status ResetUser(grpc::ServerContext* context,
                         const v1::ResetUserRequest* request,
                         v1::User* response) override;
  grpc::Status SetLearner(grpc::ServerContext* context,
                          const v1::SetLearnerRequest* request,
                          v1::User* response) override;
  grpc::Status DeleteUser(grpc::ServerContext* context,
                          const v1::DeleteUserRequest* request,
                          v1::DeleteUserResponse* response) override;
  grpc::Status Estimate(grpc::ServerContext* context,
                        const v1::EstimateRequest* request,
                        v1::EstimateResponse* response) override;
  grpc::Status GetModel(grpc::ServerContext* context,
                        const v1::GetModelRequest* request,
                        v1::Model* response) override;
  grpc::Status ListEvents(grpc::ServerContext* context,
                          const v1::ListEventsRequest* request,
                          v1::ListEventsResponse* response) override;
  grpc::Status BuildPopulationPrior(
      grpc::ServerContext* context,
      const v1::BuildPopulationPriorRequest* request,
      v1::PopulationPool* response) override;
  grpc::Status CheckStore(grpc::ServerContext* context,
                          const v1::CheckStoreRequest* request,
                          v1::CheckStoreResponse* response) override;
  grpc::Status ListAudit(grpc::ServerContext* context,
                         const v1::ListAuditRequest* request,
                         v1::ListAuditResponse* response) override;

 private:
  const RpcEnvironment* const env_;
  BanditEngine* const engine_;
  const BanditConfig defaults_;
};

// Keeps the audit trail (services/common/audit.h) in the event store, where
// ListAudit reads it. `store` must outlive the sink.
class StoreAuditSink final : public AuditSink {
 public:
  explicit StoreAuditSink(AuditLog* store) : store_(store) {}
  absl::Status Record(const AuditEvent& event) override;

 private:
  AuditLog* const store_;
};

}  // namespace bitewise::bandit

#endif  // BITEWISE_SERVICES_BANDIT_BANDIT_SERVICE_H_
