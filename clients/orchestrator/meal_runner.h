// MealRunner: the orchestrator's meal logic, apart from its flags. For each
// bite: capture a frame (RobotService), detect food and choose the most
// confident item (PerceptionService), featurize it, find or create the user
// at the first bite (BanditService; a new user's context ridge follows the
// featurizer's scale), Select an action, Acquire with streamed progress
// (RobotService), classify the force trace (HapticService) and Update the
// bandit. An Update that cannot be delivered goes to the journal and is
// delivered by DrainJournal at the start of the next run.
//
// Thread-compatible. Prints one line per bite and a summary to stdout.
#ifndef BITEWISE_CLIENTS_ORCHESTRATOR_MEAL_RUNNER_H_
#define BITEWISE_CLIENTS_ORCHESTRATOR_MEAL_RUNNER_H_

#include <map>
#include <memory>
#include <string>

#include "bitewise/v1/bandit.grpc.pb.h"
#include "bitewise/v1/haptic.grpc.pb.h"
#include "bitewise/v1/perception.grpc.pb.h"
#include "bitewise/v1/robot.grpc.pb.h"
#include "clients/orchestrator/update_journal.h"

namespace bitewise::orchestrator {

// What the bandit learns from the haptic class.
enum class PosthocMode {
  kLogProbabilities,  // the default: best in every measured cell
  kProbabilities,
  kNone,  // vision only; new users get the context-only learner
};

// Who decides whether the food came up.
enum class ConfirmBy { kRobot, kOperator };

struct MealRunnerOptions {
  std::string user_id = "demo-user";
  PosthocMode posthoc = PosthocMode::kLogProbabilities;
  ConfirmBy confirm = ConfirmBy::kRobot;
  // For a NEW user: lambda_c > 0 is used exactly; otherwise lambda_c =
  // rho_c * the featurizer's E||c||^2 when it reports one.
  double lambda_c = 0.0;
  double rho_c = 1.0;
  // For a NEW user: alpha < 0 keeps the BanditService's default;
  // prior_rounds > 0 starts from the facility's population pool.
  double alpha = -1.0;
  double prior_rounds = 0.0;
  // Deadline of every unary call and of one Acquire (each covering the
  // call's retries, which are the channels' gRPC retry policy:
  // ChannelOptions::max_attempts).
  int deadline_ms = 10000;
  int acquire_deadline_ms = 60000;
};

struct MealStubs {
  std::unique_ptr<v1::BanditService::Stub> bandit;
  std::unique_ptr<v1::PerceptionService::Stub> perception;
  std::unique_ptr<v1::HapticService::Stub> haptic;
  std::unique_ptr<v1::RobotService::Stub> robot;
};

enum class BiteEnd {
  kDone,        // the bite ran and the bandit learned (or it was journaled)
  kPlateEmpty,  // nothing left to eat: the meal is over
  kFailed,      // a service failed; `error` says which and why
};

struct BiteResult {
  BiteEnd end = BiteEnd::kDone;
  std::string error;
};

class MealRunner {
 public:
  // `journal` must outlive the runner.
  MealRunner(MealStubs stubs, UpdateJournal* journal,
             MealRunnerOptions options);

  // Delivers updates left over from an earlier run.
  void DrainJournal();
  // Runs bite `number` of meal `meal_id`.
  BiteResult Bite(const std::string& meal_id, int number);
  void PrintSummary(const std::string& meal_id) const;

 private:
  struct Tally {
    int attempts = 0;
    int failures = 0;
  };

  // Finds or creates the user for contexts of `context_dim` values;
  // returns false with a message on failure.
  bool EnsureUser(const std::string& user_id, bool vision_only, int context_dim,
                  double context_mean_squared_norm, std::string* error);
  grpc::Status SendUpdate(const JournaledUpdate& update,
                          v1::UpdateResponse* response);
  grpc::Status RunAcquire(const v1::AcquireRequest& request,
                          v1::AcquireResult* result);
  static bool AskOperator();

  MealStubs stubs_;
  UpdateJournal* journal_;
  const MealRunnerOptions options_;
  bool user_ready_ = false;  // loaded or created at the first Featurize
  v1::User user_;
  std::map<std::string, Tally> per_food_;
  int attempts_ = 0;
  int failures_ = 0;
};

}  // namespace bitewise::orchestrator

#endif  // BITEWISE_CLIENTS_ORCHESTRATOR_MEAL_RUNNER_H_
