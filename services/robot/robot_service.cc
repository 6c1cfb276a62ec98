#include "services/robot/robot_service.h"

#include "services/common/grpc_status.h"
#include "services/robot/converters.h"
#include "services/robot/steady_time.h"

namespace bitewise::robot {
namespace {

grpc::Status Fail(const absl::Status& status) { return ToGrpcStatus(status); }

}  // namespace

RobotServiceImpl::RobotServiceImpl(RobotBackend* backend) : backend_(backend) {}

grpc::Status RobotServiceImpl::GetStatus(grpc::ServerContext*,
                                         const v1::GetStatusRequest*,
                                         v1::RobotStatus* response) {
  StatusToProto(backend_->robot().Status(), backend_->simulated(),
                backend_->items_left(), response);
  return grpc::Status::OK;
}

grpc::Status RobotServiceImpl::CaptureFrame(grpc::ServerContext*,
                                            const v1::CaptureFrameRequest*,
                                            v1::Frame* response) {
  absl::StatusOr<sim::RenderedFrame> frame = backend_->CaptureFrame();
  if (!frame.ok()) return Fail(frame.status());
  FrameToProto(*frame, SteadyNowS(), frames_++, response);
  return grpc::Status::OK;
}

grpc::Status RobotServiceImpl::ListActions(grpc::ServerContext*,
                                           const v1::ListActionsRequest*,
                                           v1::ListActionsResponse* response) {
  for (const ActionSpec& action : SkeweringActions()) {
    ActionToProto(action, response->add_actions());
  }
  return grpc::Status::OK;
}

grpc::Status RobotServiceImpl::Acquire(
    grpc::ServerContext* context, const v1::AcquireRequest* request,
    grpc::ServerWriter<v1::AcquireProgress>* writer) {
  absl::StatusOr<AcquireTarget> target = TargetFromProto(*request);
  if (!target.ok()) return Fail(target.status());
  absl::StatusOr<ActionSpec> action = FindAction(request->action());
  if (!action.ok()) return Fail(action.status());
  absl::StatusOr<AcquireOutcome> outcome = backend_->robot().Acquire(
      *target, request->action(), [&](const AcquireProgressEvent& event) {
        if (context->IsCancelled()) return false;
        // The final message, with the result, is written below.
        if (event.phase == AcquirePhase::kDone) return true;
        v1::AcquireProgress progress;
        progress.set_phase(PhaseToProto(event.phase));
        progress.set_elapsed_s(event.elapsed_s);
        progress.set_force_n(event.force_n);
        return writer->Write(progress);
      });
  if (!outcome.ok()) return Fail(outcome.status());
  v1::AcquireProgress last;
  last.set_phase(v1::ACQUIRE_PHASE_DONE);
  last.set_elapsed_s(outcome->duration_s);
  OutcomeToProto(*outcome, *action, last.mutable_result());
  writer->Write(last);
  return grpc::Status::OK;
}

grpc::Status RobotServiceImpl::Stop(grpc::ServerContext*,
                                    const v1::StopRequest*,
                                    v1::StopResponse* response) {
  absl::StatusOr<bool> was_moving = backend_->robot().Stop();
  if (!was_moving.ok()) return Fail(was_moving.status());
  response->set_was_moving(*was_moving);
  return grpc::Status::OK;
}

grpc::Status RobotServiceImpl::Tare(grpc::ServerContext*,
                                    const v1::TareRequest*, v1::TareResponse*) {
  return Fail(backend_->robot().Tare());
}

}  // namespace bitewise::robot
