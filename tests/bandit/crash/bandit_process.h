// The real bitewise-bandit binary as the binary tests run it (crash,
// drain, bad input, write faults): a child process on a store, with a stub
// once it is SERVING, and one-call helpers with a deadline.
#ifndef BITEWISE_TESTS_BANDIT_CRASH_BANDIT_PROCESS_H_
#define BITEWISE_TESTS_BANDIT_CRASH_BANDIT_PROCESS_H_

#include <grpcpp/client_context.h>

#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "absl/time/time.h"
#include "bitewise/v1/bandit.grpc.pb.h"
#include "services/common/channel.h"
#include "services/common/grpc_status.h"
#include "services/common/status_macros.h"
#include "tests/common/child_process.h"

namespace bitewise {

inline constexpr char kServiceName[] = "bitewise.v1.BanditService";
// Generous: the machine is small and shared.
inline constexpr absl::Duration kCallTimeout = absl::Seconds(20);
inline constexpr absl::Duration kStartTimeout = absl::Seconds(60);
inline constexpr absl::Duration kServingTimeout = absl::Seconds(20);
inline constexpr absl::Duration kExitTimeout = absl::Seconds(20);
inline constexpr int kStartAttempts = 5;

// One run of the bitewise-bandit binary, with a stub once it is SERVING.
class ServerProcess {
 public:
  // Starts the binary on `db`, logging to `log_path` (appended), and returns
  // once the BanditService reports SERVING, with `env` (NAME=value) added to
  // its environment (without `wait_serving`: once it listens). Retries on a
  // new port if the chosen one was taken in the meantime.
  absl::Status Start(const std::string& db, const std::string& log_path,
                     std::vector<std::string> env = {},
                     bool wait_serving = true) {
    if (child_.running())
      return absl::FailedPreconditionError("already running");
    std::string last_error;
    for (int attempt = 0; attempt < kStartAttempts; ++attempt) {
      absl::StatusOr<int> port = testing::PickFreePort();
      if (!port.ok()) return port.status();
      child_.set_env(env);
      RETURN_IF_ERROR(child_.Start(
          {BITEWISE_BANDIT_BINARY, absl::StrCat("--db=", db), "--create",
           absl::StrCat("--listen=127.0.0.1:", *port), "--drain_timeout_s=5"},
          log_path));
      // The line is printed after the health status is set, so a channel
      // made now connects at once instead of backing off.
      absl::Status ready = child_.WaitForLog(
          absl::StrCat("serving on 127.0.0.1:", *port, " "), kStartTimeout);
      if (!ready.ok()) {
        last_error = std::string(ready.message());
        child_.Kill();
        // Only a lost port race is worth another try.
        if (absl::StrContains(last_error, "cannot start the server")) continue;
        return ready;
      }
      absl::StatusOr<std::shared_ptr<grpc::Channel>> channel =
          MakeChannel(absl::StrCat("127.0.0.1:", *port), ChannelOptions{});
      if (!channel.ok()) return channel.status();
      channel_ = *channel;
      address_ = absl::StrCat("127.0.0.1:", *port);
      absl::Status serving =
          wait_serving ? WaitForServing(channel_, kServiceName, kServingTimeout)
                       : absl::OkStatus();
      if (!serving.ok()) {
        Kill();
        return absl::Status(
            serving.code(),
            absl::StrCat(serving.message(), "; log:\n", child_.log()));
      }
      stub_ = v1::BanditService::NewStub(channel_);
      return absl::OkStatus();
    }
    return absl::UnavailableError(absl::StrCat(
        "no free port after ", kStartAttempts, " attempts: ", last_error));
  }

  // Sends `signal` and waits up to `timeout` for the child to exit. Returns
  // its wait status; DEADLINE_EXCEEDED leaves it running (Kill() reaps it).
  absl::StatusOr<int> SignalAndWait(int signal, absl::Duration timeout) {
    absl::StatusOr<int> status = child_.SignalAndWait(signal, timeout);
    if (status.ok()) {
      stub_.reset();
      channel_.reset();
    }
    return status;
  }

  void Kill() {
    stub_.reset();
    channel_.reset();
    child_.Kill();
  }

  // Waits until the log has a line containing `text`.
  absl::Status WaitForLog(const std::string& text, absl::Duration timeout) {
    return child_.WaitForLog(text, timeout);
  }

  bool running() const { return child_.running(); }
  pid_t pid() const { return child_.pid(); }
  const std::shared_ptr<grpc::Channel>& channel() const { return channel_; }
  const std::string& address() const { return address_; }
  v1::BanditService::Stub& stub() { return *stub_; }
  const std::string& log_path() const { return child_.log_path(); }

 private:
  testing::ChildProcess child_;
  std::shared_ptr<grpc::Channel> channel_;
  std::string address_;
  std::unique_ptr<v1::BanditService::Stub> stub_;
};

// One unary call with a deadline; the gRPC status comes back as absl::Status.
template <typename Request, typename Response>
absl::StatusOr<Response> Call(
    v1::BanditService::Stub& stub,
    grpc::Status (v1::BanditService::Stub::*method)(grpc::ClientContext*,
                                                    const Request&, Response*),
    const Request& request) {
  grpc::ClientContext context;
  context.set_deadline(absl::ToChronoTime(absl::Now() + kCallTimeout));
  Response response;
  const grpc::Status status = (stub.*method)(&context, request, &response);
  if (!status.ok()) return FromGrpcStatus(status);
  return response;
}

inline absl::StatusOr<v1::SelectResponse> Select(
    v1::BanditService::Stub& stub, const std::string& user_id,
    const std::vector<double>& context) {
  v1::SelectRequest request;
  request.set_user_id(user_id);
  request.mutable_context()->Add(context.begin(), context.end());
  request.set_meal_id("meal-1");
  request.set_item_label("banana");
  return Call(stub, &v1::BanditService::Stub::Select, request);
}

inline absl::StatusOr<v1::UpdateResponse> Update(
    v1::BanditService::Stub& stub, const std::string& event_id, double loss,
    const std::vector<double>& posthoc) {
  v1::UpdateRequest request;
  request.set_event_id(event_id);
  request.set_loss(loss);
  request.mutable_posthoc()->Add(posthoc.begin(), posthoc.end());
  return Call(stub, &v1::BanditService::Stub::Update, request);
}

inline absl::StatusOr<v1::User> GetUser(v1::BanditService::Stub& stub,
                                        const std::string& user_id) {
  v1::GetUserRequest request;
  request.set_user_id(user_id);
  return Call(stub, &v1::BanditService::Stub::GetUser, request);
}

inline absl::StatusOr<v1::Model> GetModel(v1::BanditService::Stub& stub,
                                          const std::string& user_id) {
  v1::GetModelRequest request;
  request.set_user_id(user_id);
  return Call(stub, &v1::BanditService::Stub::GetModel, request);
}

// Every event of the user, following page tokens.
inline absl::StatusOr<std::vector<v1::Event>> ListAllEvents(
    v1::BanditService::Stub& stub, const std::string& user_id) {
  std::vector<v1::Event> events;
  std::string token;
  for (int page = 0; page < 1000; ++page) {
    v1::ListEventsRequest request;
    request.set_user_id(user_id);
    request.set_page_size(16);
    request.set_page_token(token);
    absl::StatusOr<v1::ListEventsResponse> response =
        Call(stub, &v1::BanditService::Stub::ListEvents, request);
    if (!response.ok()) return response.status();
    events.insert(events.end(), response->events().begin(),
                  response->events().end());
    token = response->next_page_token();
    if (token.empty()) return events;
  }
  return absl::InternalError("ListEvents: more than 1000 pages");
}

}  // namespace bitewise

#endif  // BITEWISE_TESTS_BANDIT_CRASH_BANDIT_PROCESS_H_
