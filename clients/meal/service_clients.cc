#include "clients/meal/service_clients.h"

#include <grpcpp/client_context.h>

#include <algorithm>
#include <chrono>
#include <utility>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "services/common/grpc_status.h"
#include "services/common/status_macros.h"

namespace bitewise::meals {
namespace {

std::unique_ptr<grpc::ClientContext> ContextWithin(absl::Duration deadline) {
  auto context = std::make_unique<grpc::ClientContext>();
  context->set_deadline(absl::ToChronoTime(absl::Now() + deadline));
  return context;
}

// The call's status as an absl::Status whose message names the call.
absl::Status Named(const char* call, const grpc::Status& status) {
  if (status.ok()) return absl::OkStatus();
  const absl::Status converted = FromGrpcStatus(status);
  return absl::Status(converted.code(),
                      absl::StrCat(call, " failed: ",
                                   absl::StatusCodeToString(converted.code()),
                                   ": ", converted.message()));
}

// One unary call: `method` of `stub` with a deadline.
template <typename Stub, typename Request, typename Response>
absl::StatusOr<Response> Unary(
    Stub* stub,
    grpc::Status (Stub::*method)(grpc::ClientContext*, const Request&,
                                 Response*),
    const char* name, const Request& request, absl::Duration deadline) {
  auto context = ContextWithin(deadline);
  Response response;
  const grpc::Status status =
      (stub->*method)(context.get(), request, &response);
  if (!status.ok()) return Named(name, status);
  return response;
}

}  // namespace

RobotClient::RobotClient(std::shared_ptr<grpc::ChannelInterface> channel,
                         CallDeadlines deadlines)
    : stub_(v1::RobotService::NewStub(std::move(channel))),
      deadlines_(deadlines) {}

absl::StatusOr<v1::Frame> RobotClient::CaptureFrame() {
  return Unary(stub_.get(), &v1::RobotService::Stub::CaptureFrame,
               "RobotService.CaptureFrame", v1::CaptureFrameRequest(),
               deadlines_.unary);
}

absl::StatusOr<v1::RobotStatus> RobotClient::GetStatus() {
  return Unary(stub_.get(), &v1::RobotService::Stub::GetStatus,
               "RobotService.GetStatus", v1::GetStatusRequest(),
               deadlines_.unary);
}

absl::StatusOr<v1::ListActionsResponse> RobotClient::ListActions() {
  return Unary(stub_.get(), &v1::RobotService::Stub::ListActions,
               "RobotService.ListActions", v1::ListActionsRequest(),
               deadlines_.unary);
}

absl::StatusOr<v1::StopResponse> RobotClient::Stop() {
  return Unary(stub_.get(), &v1::RobotService::Stub::Stop, "RobotService.Stop",
               v1::StopRequest(), deadlines_.unary);
}

absl::StatusOr<v1::AcquireResult> RobotClient::Acquire(
    const v1::AcquireRequest& request,
    const std::function<void(const v1::AcquireProgress&)>& on_progress) {
  auto context = ContextWithin(deadlines_.acquire);
  std::unique_ptr<grpc::ClientReader<v1::AcquireProgress>> reader =
      stub_->Acquire(context.get(), request);
  v1::AcquireProgress progress;
  bool have_result = false;
  v1::AcquireResult result;
  while (reader->Read(&progress)) {
    if (on_progress) on_progress(progress);
    if (progress.has_result()) {
      result = progress.result();
      have_result = true;
    }
  }
  const grpc::Status status = reader->Finish();
  if (!status.ok()) return Named("RobotService.Acquire", status);
  if (!have_result) {
    return absl::InternalError(
        "RobotService.Acquire failed: the stream ended without a result");
  }
  return result;
}

PerceptionClient::PerceptionClient(
    std::shared_ptr<grpc::ChannelInterface> channel, CallDeadlines deadlines)
    : stub_(v1::PerceptionService::NewStub(std::move(channel))),
      deadlines_(deadlines) {}

absl::StatusOr<v1::DetectFoodResponse> PerceptionClient::DetectFood(
    const v1::Frame& frame) {
  v1::DetectFoodRequest request;
  *request.mutable_frame() = frame;
  return Unary(stub_.get(), &v1::PerceptionService::Stub::DetectFood,
               "PerceptionService.DetectFood", request, deadlines_.unary);
}

absl::StatusOr<v1::FeaturizeResponse> PerceptionClient::Featurize(
    const v1::Frame& frame, const v1::BoundingBox& bbox) {
  v1::FeaturizeRequest request;
  *request.mutable_frame() = frame;
  *request.mutable_bbox() = bbox;
  return Unary(stub_.get(), &v1::PerceptionService::Stub::Featurize,
               "PerceptionService.Featurize", request, deadlines_.unary);
}

HapticClient::HapticClient(std::shared_ptr<grpc::ChannelInterface> channel,
                           CallDeadlines deadlines)
    : stub_(v1::HapticService::NewStub(std::move(channel))),
      deadlines_(deadlines) {}

absl::StatusOr<v1::ClassifyResponse> HapticClient::Classify(
    const google::protobuf::RepeatedPtrField<v1::WrenchSample>& trace) {
  v1::ClassifyRequest request;
  *request.mutable_samples() = trace;
  return Unary(stub_.get(), &v1::HapticService::Stub::Classify,
               "HapticService.Classify", request, deadlines_.unary);
}

BanditClient::BanditClient(std::shared_ptr<grpc::ChannelInterface> channel,
                           CallDeadlines deadlines)
    : stub_(v1::BanditService::NewStub(std::move(channel))),
      deadlines_(deadlines) {}

absl::StatusOr<v1::User> BanditClient::GetUser(const std::string& user_id) {
  v1::GetUserRequest request;
  request.set_user_id(user_id);
  return Unary(stub_.get(), &v1::BanditService::Stub::GetUser,
               "BanditService.GetUser", request, deadlines_.unary);
}

absl::StatusOr<v1::User> BanditClient::CreateUser(
    const v1::CreateUserRequest& request) {
  return Unary(stub_.get(), &v1::BanditService::Stub::CreateUser,
               "BanditService.CreateUser", request, deadlines_.unary);
}

absl::StatusOr<v1::ListUsersResponse> BanditClient::ListUsers(
    const v1::ListUsersRequest& request) {
  return Unary(stub_.get(), &v1::BanditService::Stub::ListUsers,
               "BanditService.ListUsers", request, deadlines_.unary);
}

absl::StatusOr<v1::SelectResponse> BanditClient::Select(
    const v1::SelectRequest& request) {
  return Unary(stub_.get(), &v1::BanditService::Stub::Select,
               "BanditService.Select", request, deadlines_.unary);
}

absl::StatusOr<v1::UpdateResponse> BanditClient::Update(
    const v1::UpdateRequest& request) {
  return Unary(stub_.get(), &v1::BanditService::Stub::Update,
               "BanditService.Update", request, deadlines_.unary);
}

absl::StatusOr<v1::Model> BanditClient::GetModel(const std::string& user_id) {
  v1::GetModelRequest request;
  request.set_user_id(user_id);
  return Unary(stub_.get(), &v1::BanditService::Stub::GetModel,
               "BanditService.GetModel", request, deadlines_.unary);
}

absl::StatusOr<v1::EstimateResponse> BanditClient::Estimate(
    const v1::EstimateRequest& request) {
  return Unary(stub_.get(), &v1::BanditService::Stub::Estimate,
               "BanditService.Estimate", request, deadlines_.unary);
}

absl::StatusOr<v1::ListEventsResponse> BanditClient::ListEvents(
    const v1::ListEventsRequest& request) {
  return Unary(stub_.get(), &v1::BanditService::Stub::ListEvents,
               "BanditService.ListEvents", request, deadlines_.unary);
}

absl::StatusOr<ServiceChannels> OpenServiceChannels(const ServiceLinks& links) {
  const std::vector<std::string> tls_links = absl::StrSplit(links.tls_for, ',');
  for (const std::string& link : tls_links) {
    if (link != "all" && link != "bandit" && link != "perception" &&
        link != "haptic" && link != "robot") {
      return absl::InvalidArgumentError(absl::StrCat(
          "unknown link \"", link,
          "\" in the TLS links (all, or some of bandit, perception, haptic, "
          "robot)"));
    }
  }
  // Flags that would be dropped silently: links named for TLS without a
  // CA (all would stay plaintext), a name for the BanditService's
  // certificate on a link without TLS.
  const bool any_tls = !links.tls.tls_ca_file.empty();
  if (!any_tls && links.tls_for != "all") {
    return absl::InvalidArgumentError(absl::StrCat(
        "the TLS links \"", links.tls_for,
        "\" are named, but no CA file is given: every link would be "
        "plaintext"));
  }
  const auto tls_on = [&](const std::string& link) {
    return any_tls && (links.tls_for == "all" ||
                       std::find(tls_links.begin(), tls_links.end(), link) !=
                           tls_links.end());
  };
  if (!links.bandit_tls_name.empty() && !tls_on("bandit")) {
    return absl::InvalidArgumentError(absl::StrCat(
        "a name for the BanditService's certificate (\"", links.bandit_tls_name,
        "\") is given, but the bandit link is plaintext (no CA file, or not "
        "among the TLS links)"));
  }
  auto open = [&](const std::string& link, const std::string& address)
      -> absl::StatusOr<std::shared_ptr<grpc::Channel>> {
    const bool use_tls =
        links.tls_for == "all" ||
        std::find(tls_links.begin(), tls_links.end(), link) != tls_links.end();
    ChannelOptions options = use_tls ? links.tls : ChannelOptions{};
    options.max_message_bytes = links.max_message_bytes;
    options.max_attempts = links.max_attempts;
    if (link == "bandit" && use_tls) {
      options.tls_server_name_override = links.bandit_tls_name;
    }
    absl::StatusOr<std::shared_ptr<grpc::Channel>> channel =
        MakeChannel(address, options);
    if (!channel.ok()) {
      return absl::Status(
          channel.status().code(),
          absl::StrCat(address, ": ", channel.status().message()));
    }
    return channel;
  };
  ServiceChannels channels;
  ASSIGN_OR_RETURN(channels.bandit, open("bandit", links.bandit));
  ASSIGN_OR_RETURN(channels.perception, open("perception", links.perception));
  ASSIGN_OR_RETURN(channels.haptic, open("haptic", links.haptic));
  ASSIGN_OR_RETURN(channels.robot, open("robot", links.robot));
  return channels;
}

ServiceClients::ServiceClients(const ServiceChannels& channels,
                               CallDeadlines deadlines)
    : bandit(channels.bandit, deadlines),
      perception(channels.perception, deadlines),
      haptic(channels.haptic, deadlines),
      robot(channels.robot, deadlines) {}

}  // namespace bitewise::meals
