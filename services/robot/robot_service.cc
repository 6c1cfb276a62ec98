#include "services/robot/robot_service.h"

#include "absl/strings/str_cat.h"
#include "services/camera/frame_proto.h"
#include "services/common/rpc_handler.h"
#include "services/common/rpc_methods.h"
#include "services/common/status_macros.h"
#include "services/domain/steady_time.h"
#include "services/robot/converters.h"

namespace bitewise::robot {

RobotServiceImpl::RobotServiceImpl(const RpcEnvironment* env,
                                   RobotBackend* backend)
    : env_(env), backend_(backend) {}

grpc::Status RobotServiceImpl::GetStatus(grpc::ServerContext* context,
                                         const v1::GetStatusRequest*,
                                         v1::RobotStatus* response) {
  return RunRpc(*env_, BITEWISE_RPC_METHOD(v1::RobotService), context, [&] {
    StatusToProto(backend_->robot().Status(), backend_->simulated(),
                  backend_->items_left(), response);
    return absl::OkStatus();
  });
}

grpc::Status RobotServiceImpl::CaptureFrame(grpc::ServerContext* context,
                                            const v1::CaptureFrameRequest*,
                                            v1::Frame* response) {
  return RunRpc(*env_, BITEWISE_RPC_METHOD(v1::RobotService), context,
                [&]() -> absl::Status {
                  ASSIGN_OR_RETURN(const domain::RgbdFrame frame,
                                   backend_->CaptureFrame());
                  camera::FrameToProto(
                      frame, frame.capture_s,
                      absl::StrCat(backend_->simulated() ? "sim-" : "camera-",
                                   frame.sequence),
                      response);
                  return absl::OkStatus();
                });
}

grpc::Status RobotServiceImpl::ListActions(grpc::ServerContext* context,
                                           const v1::ListActionsRequest*,
                                           v1::ListActionsResponse* response) {
  return RunRpc(*env_, BITEWISE_RPC_METHOD(v1::RobotService), context, [&] {
    for (const ActionSpec& action : SkeweringActions()) {
      ActionToProto(action, response->add_actions());
    }
    return absl::OkStatus();
  });
}

grpc::Status RobotServiceImpl::Acquire(
    grpc::ServerContext* context, const v1::AcquireRequest* request,
    grpc::ServerWriter<v1::AcquireProgress>* writer) {
  return RunRpc(
      *env_, BITEWISE_RPC_METHOD(v1::RobotService), context,
      [&]() -> absl::Status {
        ASSIGN_OR_RETURN(const AcquireTarget target, TargetFromProto(*request));
        ASSIGN_OR_RETURN(const ActionSpec action,
                         ActionFromWire(request->action()));
        AcquireOptions options;
        options.dry_run = request->dry_run();
        ASSIGN_OR_RETURN(const AcquireOutcome outcome,
                         backend_->robot().Acquire(
                             target, action.name,
                             [&](const AcquireProgressEvent& event) {
                               if (context->IsCancelled()) return false;
                               // The final message, with the result, is written
                               // below.
                               if (event.phase == AcquirePhase::kDone)
                                 return true;
                               v1::AcquireProgress progress;
                               progress.set_phase(PhaseToProto(event.phase));
                               progress.set_elapsed_s(event.elapsed_s);
                               progress.set_force_n(event.force_n);
                               return writer->Write(progress);
                             },
                             options));
        v1::AcquireProgress last;
        last.set_phase(v1::ACQUIRE_PHASE_DONE);
        last.set_elapsed_s(outcome.duration_s);
        OutcomeToProto(outcome, action, last.mutable_result());
        writer->Write(last);
        return absl::OkStatus();
      });
}

// Stop runs even for a caller that has gone or timed out: halting the arm
// matters more than the reply.
grpc::Status RobotServiceImpl::Stop(grpc::ServerContext* context,
                                    const v1::StopRequest*,
                                    v1::StopResponse* response) {
  return RunRpc(
      *env_, BITEWISE_RPC_METHOD(v1::RobotService), context,
      [&]() -> absl::Status {
        ASSIGN_OR_RETURN(const bool was_moving, backend_->robot().Stop());
        response->set_was_moving(was_moving);
        return absl::OkStatus();
      },
      RpcPolicy::kAlwaysRun);
}

grpc::Status RobotServiceImpl::Tare(grpc::ServerContext* context,
                                    const v1::TareRequest*, v1::TareResponse*) {
  return RunRpc(*env_, BITEWISE_RPC_METHOD(v1::RobotService), context,
                [&] { return backend_->robot().Tare(); });
}

}  // namespace bitewise::robot
