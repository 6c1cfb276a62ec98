// Typed clients of the four bitewise services for the meal library: each call
// carries a deadline, and each failure comes back as an absl::Status whose
// message names the service and the call ("PerceptionService.Featurize
// failed: ..."), so a person can be told which part of the system failed.
// Retries are the channels' gRPC retry policy (ChannelOptions::max_attempts).
//
// Thread-safe: gRPC stubs may be used from several threads at once.
#ifndef BITEWISE_CLIENTS_MEAL_SERVICE_CLIENTS_H_
#define BITEWISE_CLIENTS_MEAL_SERVICE_CLIENTS_H_

#include <grpcpp/channel.h>

#include <functional>
#include <memory>
#include <string>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/time/time.h"
#include "bitewise/v1/bandit.grpc.pb.h"
#include "bitewise/v1/haptic.grpc.pb.h"
#include "bitewise/v1/perception.grpc.pb.h"
#include "bitewise/v1/robot.grpc.pb.h"
#include "services/common/channel.h"

namespace bitewise::meals {

struct CallDeadlines {
  // Every unary call, retries included.
  absl::Duration unary = absl::Seconds(10);
  // One Acquire, from the request to the result.
  absl::Duration acquire = absl::Seconds(60);
};

// A channel to each service. Several may be the same channel.
struct ServiceChannels {
  std::shared_ptr<grpc::Channel> bandit;
  std::shared_ptr<grpc::Channel> perception;
  std::shared_ptr<grpc::Channel> haptic;
  std::shared_ptr<grpc::Channel> robot;
};

// Where the four services are and how to reach them, as a client's flags
// say it.
struct ServiceLinks {
  std::string bandit = "127.0.0.1:50051";
  std::string perception = "127.0.0.1:50052";
  std::string haptic = "127.0.0.1:50053";
  std::string robot = "127.0.0.1:50054";
  // TLS files (all empty: plaintext), for the links `tls_for` names: "all",
  // or a comma-separated subset of bandit, perception, haptic, robot (say,
  // the workstation's services while the robot computer's own stay
  // plaintext on loopback).
  ChannelOptions tls;
  std::string tls_for = "all";
  // With TLS: the name every BanditService replica's certificate carries.
  std::string bandit_tls_name;
  // gRPC's retry policy: attempts in all (1-5).
  int max_attempts = 1;
  // Frames and long traces.
  int max_message_bytes = 64 << 20;
};

// Opens the four channels. INVALID_ARGUMENT naming an unknown link in
// tls_for; the errors of MakeChannel, naming the address.
absl::StatusOr<ServiceChannels> OpenServiceChannels(const ServiceLinks& links);

class RobotClient {
 public:
  RobotClient(std::shared_ptr<grpc::ChannelInterface> channel,
              CallDeadlines deadlines);

  absl::StatusOr<v1::Frame> CaptureFrame();
  absl::StatusOr<v1::RobotStatus> GetStatus();
  absl::StatusOr<v1::ListActionsResponse> ListActions();
  // Runs the action; `on_progress` hears every progress report (the final
  // one carries the result). A stream that ends without a result is
  // INTERNAL.
  absl::StatusOr<v1::AcquireResult> Acquire(
      const v1::AcquireRequest& request,
      const std::function<void(const v1::AcquireProgress&)>& on_progress);
  absl::StatusOr<v1::StopResponse> Stop();

 private:
  std::unique_ptr<v1::RobotService::Stub> stub_;
  CallDeadlines deadlines_;
};

class PerceptionClient {
 public:
  PerceptionClient(std::shared_ptr<grpc::ChannelInterface> channel,
                   CallDeadlines deadlines);

  absl::StatusOr<v1::DetectFoodResponse> DetectFood(const v1::Frame& frame);
  absl::StatusOr<v1::FeaturizeResponse> Featurize(const v1::Frame& frame,
                                                  const v1::BoundingBox& bbox);

 private:
  std::unique_ptr<v1::PerceptionService::Stub> stub_;
  CallDeadlines deadlines_;
};

class HapticClient {
 public:
  HapticClient(std::shared_ptr<grpc::ChannelInterface> channel,
               CallDeadlines deadlines);

  absl::StatusOr<v1::ClassifyResponse> Classify(
      const google::protobuf::RepeatedPtrField<v1::WrenchSample>& trace);

 private:
  std::unique_ptr<v1::HapticService::Stub> stub_;
  CallDeadlines deadlines_;
};

class BanditClient {
 public:
  BanditClient(std::shared_ptr<grpc::ChannelInterface> channel,
               CallDeadlines deadlines);

  absl::StatusOr<v1::User> GetUser(const std::string& user_id);
  absl::StatusOr<v1::User> CreateUser(const v1::CreateUserRequest& request);
  absl::StatusOr<v1::ListUsersResponse> ListUsers(
      const v1::ListUsersRequest& request);
  absl::StatusOr<v1::SelectResponse> Select(const v1::SelectRequest& request);
  absl::StatusOr<v1::UpdateResponse> Update(const v1::UpdateRequest& request);
  absl::StatusOr<v1::Model> GetModel(const std::string& user_id);
  absl::StatusOr<v1::EstimateResponse> Estimate(
      const v1::EstimateRequest& request);
  absl::StatusOr<v1::ListEventsResponse> ListEvents(
      const v1::ListEventsRequest& request);

 private:
  std::unique_ptr<v1::BanditService::Stub> stub_;
  CallDeadlines deadlines_;
};

// The four clients together.
struct ServiceClients {
  ServiceClients(const ServiceChannels& channels, CallDeadlines deadlines);

  BanditClient bandit;
  PerceptionClient perception;
  HapticClient haptic;
  RobotClient robot;
};

}  // namespace bitewise::meals

#endif  // BITEWISE_CLIENTS_MEAL_SERVICE_CLIENTS_H_
