// RobotServiceImpl: the gRPC face of the RobotBackend. Each handler
// validates, calls the Robot (or the backend's camera) and converts; errors
// become gRPC statuses through the one mapping in services/common. Acquire
// streams a progress message per phase and at 10 Hz, then one message with
// the result; a caller that goes away cancels the motion and halts the arm.
//
// Thread-safe (the Robot is).
#ifndef BITEWISE_SERVICES_ROBOT_ROBOT_SERVICE_H_
#define BITEWISE_SERVICES_ROBOT_ROBOT_SERVICE_H_

#include <atomic>
#include <cstdint>

#include "bitewise/v1/robot.grpc.pb.h"
#include "services/common/rpc_environment.h"
#include "services/robot/backend.h"

namespace bitewise::robot {

class RobotServiceImpl final : public v1::RobotService::Service {
 public:
  // `env` (what every call runs with: rpc_environment.h) and `backend` must
  // outlive the service.
  RobotServiceImpl(const RpcEnvironment* env, RobotBackend* backend);

  grpc::Status GetStatus(grpc::ServerContext* context,
                         const v1::GetStatusRequest* request,
                         v1::RobotStatus* response) override;
  grpc::Status CaptureFrame(grpc::ServerContext* context,
                            const v1::CaptureFrameRequest* request,
                            v1::Frame* response) override;
  grpc::Status ListActions(grpc::ServerContext* context,
                           const v1::ListActionsRequest* request,
                           v1::ListActionsResponse* response) override;
  grpc::Status Acquire(
      grpc::ServerContext* context, const v1::AcquireRequest* request,
      grpc::ServerWriter<v1::AcquireProgress>* writer) override;
  grpc::Status Stop(grpc::ServerContext* context,
                    const v1::StopRequest* request,
                    v1::StopResponse* response) override;
  grpc::Status Tare(grpc::ServerContext* context,
                    const v1::TareRequest* request,
                    v1::TareResponse* response) override;

 private:
  const RpcEnvironment* const env_;
  RobotBackend* const backend_;
};

}  // namespace bitewise::robot

#endif  // BITEWISE_SERVICES_ROBOT_ROBOT_SERVICE_H_
