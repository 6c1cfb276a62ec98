// bitewise-orchestrator: runs bites for one user through the four services.
//
// For each bite: capture a frame (RobotService), detect food and choose an
// item (PerceptionService), featurize it, Select an action (BanditService),
// Acquire with streamed progress (RobotService), classify the force trace
// (HapticService) and Update the bandit. An Update that cannot be delivered
// goes to a local journal and is delivered at the start of the next run.
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <map>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "absl/flags/flag.h"
#include "absl/flags/parse.h"
#include "absl/flags/usage.h"
#include "absl/strings/ascii.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_split.h"
#include "bitewise/v1/bandit.grpc.pb.h"
#include "bitewise/v1/haptic.grpc.pb.h"
#include "bitewise/v1/perception.grpc.pb.h"
#include "bitewise/v1/robot.grpc.pb.h"
#include "clients/orchestrator/update_journal.h"
#include "services/common/channel.h"
#include "services/common/grpc_status.h"
#include "services/domain/haptic_class.h"

ABSL_FLAG(std::string, user, "demo-user", "User whose model learns.");
ABSL_FLAG(std::string, meal, "meal-1", "Meal id recorded with each event.");
ABSL_FLAG(int, bites, 0,
          "Most bite attempts; 0 = until the plate is empty (at most 64).");
ABSL_FLAG(std::string, bandit, "127.0.0.1:50051", "BanditService address.");
ABSL_FLAG(std::string, perception, "127.0.0.1:50052",
          "PerceptionService address.");
ABSL_FLAG(std::string, haptic, "127.0.0.1:50053", "HapticService address.");
ABSL_FLAG(std::string, robot, "127.0.0.1:50054", "RobotService address.");
ABSL_FLAG(std::string, tls_ca, "", "CA bundle of the servers (turns on TLS).");
ABSL_FLAG(std::string, tls_cert, "", "Client certificate (mutual TLS).");
ABSL_FLAG(std::string, tls_key, "", "Client key (mutual TLS).");
ABSL_FLAG(std::string, tls_for, "all",
          "Which links use the TLS flags: all, or a comma-separated subset of "
          "bandit, perception, haptic, robot (e.g. the workstation's services "
          "while the robot computer's own stay plaintext on loopback).");
ABSL_FLAG(std::string, confirm, "robot",
          "Who decides success: robot (the RobotService reports it) or "
          "operator (answer y/n at the terminal).");
ABSL_FLAG(std::string, posthoc, "logprob",
          "Post hoc context sent to the bandit: logprob (as the original "
          "research code), prob (as the paper's text) or none (vision only; "
          "new users get the context-only learner).");
ABSL_FLAG(std::string, journal, "bitewise-orchestrator.journal",
          "File of updates not yet delivered to the BanditService.");
ABSL_FLAG(int, deadline_ms, 10000, "Deadline of every unary call.");
ABSL_FLAG(int, acquire_deadline_ms, 60000, "Deadline of one Acquire.");
ABSL_FLAG(int, retries, 4, "Retries with backoff on UNAVAILABLE.");
ABSL_FLAG(double, lambda_c, 0.0,
          "Context ridge for a NEW user, honoured exactly; 0 derives it from "
          "--rho_c and the featurizer's E||c||^2.");
ABSL_FLAG(double, rho_c, 1.0,
          "For a NEW user without --lambda_c: lambda_c = rho_c * E||c||^2 of "
          "the featurizer's contexts on seen foods (what PerceptionService "
          "reports), the number of observations the ridge is worth "
          "(docs/algorithms.md). A featurizer that does not report it keeps "
          "the BanditService's default.");
ABSL_FLAG(double, prior_rounds, 0.0,
          "For a NEW user: start from the facility's newest population pool "
          "(BuildPopulationPrior), worth this many rounds; 0: no prior.");
ABSL_FLAG(double, alpha, -1.0,
          "Exploration weight for a NEW user; negative keeps the "
          "BanditService's default.");

namespace {

namespace v1 = bitewise::v1;
using bitewise::orchestrator::JournaledUpdate;
using bitewise::orchestrator::UpdateJournal;

// The API's haptic category (0 is unspecified) for people.
const char* HapticLabel(v1::HapticCategory category) {
  const int index = static_cast<int>(category) - 1;
  if (index < 0 || index >= bitewise::domain::kHapticClasses) return "unknown";
  return bitewise::domain::HapticClassLabel(
      static_cast<bitewise::domain::HapticClass>(index));
}

std::unique_ptr<grpc::ClientContext> Context(int deadline_ms) {
  auto context = std::make_unique<grpc::ClientContext>();
  context->set_deadline(std::chrono::system_clock::now() +
                        std::chrono::milliseconds(deadline_ms));
  return context;
}

// Retries `call` with exponential backoff while the server is UNAVAILABLE.
template <typename Call>
grpc::Status WithRetries(Call call) {
  grpc::Status status;
  const int retries = absl::GetFlag(FLAGS_retries);
  for (int attempt = 0; attempt <= retries; ++attempt) {
    status = call();
    if (status.error_code() != grpc::StatusCode::UNAVAILABLE) return status;
    if (attempt < retries) {
      std::this_thread::sleep_for(std::chrono::milliseconds(250 << attempt));
    }
  }
  return status;
}

std::string Describe(const char* service, const char* call,
                     const grpc::Status& status) {
  return absl::StrCat(service, ".", call,
                      " failed: ", bitewise::FromGrpcStatus(status).ToString());
}

struct Stubs {
  std::unique_ptr<v1::BanditService::Stub> bandit;
  std::unique_ptr<v1::PerceptionService::Stub> perception;
  std::unique_ptr<v1::HapticService::Stub> haptic;
  std::unique_ptr<v1::RobotService::Stub> robot;
};

struct Tally {
  int attempts = 0;
  int failures = 0;
};

class MealRunner {
 public:
  MealRunner(Stubs stubs, UpdateJournal* journal, std::string user_id,
             bool vision_only)
      : stubs_(std::move(stubs)),
        journal_(journal),
        user_id_(std::move(user_id)),
        vision_only_(vision_only) {}

  // Delivers updates left over from an earlier run.
  void DrainJournal() {
    absl::StatusOr<int> delivered =
        journal_->Drain([&](const JournaledUpdate& update) -> absl::Status {
          const grpc::Status status = SendUpdate(update, nullptr);
          if (status.ok()) return absl::OkStatus();
          if (status.error_code() == grpc::StatusCode::UNAVAILABLE ||
              status.error_code() == grpc::StatusCode::DEADLINE_EXCEEDED) {
            return bitewise::FromGrpcStatus(status);  // keep for next run
          }
          std::fprintf(stderr, "journal: dropping update for event %s: %s\n",
                       update.event_id.c_str(),
                       bitewise::FromGrpcStatus(status).ToString().c_str());
          return absl::OkStatus();
        });
    if (!delivered.ok()) {
      std::fprintf(stderr, "journal: %s\n",
                   delivered.status().ToString().c_str());
    } else if (*delivered > 0) {
      std::printf("journal: delivered %d update(s) left from an earlier run\n",
                  *delivered);
    }
  }

  // Finds or creates the user for contexts of `context_dim` values;
  // returns false with a message on failure.
  bool EnsureUser(const std::string& user_id, bool vision_only, int context_dim,
                  double context_mean_squared_norm, std::string* error) {
    v1::GetUserRequest get;
    get.set_user_id(user_id);
    grpc::Status status = WithRetries([&] {
      return stubs_.bandit->GetUser(Context(Deadline()).get(), get, &user_);
    });
    if (status.ok()) {
      if (static_cast<int>(user_.config().context_dim()) != context_dim) {
        *error = absl::StrFormat(
            "user %s learns from %u context values but the featurizer gives "
            "%d; use another --user or the featurizer the user started with",
            user_id, user_.config().context_dim(), context_dim);
        return false;
      }
      std::printf("user %s continues from model version %lld (%s)\n",
                  user_id.c_str(),
                  static_cast<long long>(user_.model_version()),
                  v1::Learner_Name(user_.config().learner()).c_str());
      return true;
    }
    if (status.error_code() != grpc::StatusCode::NOT_FOUND) {
      *error = Describe("BanditService", "GetUser", status);
      return false;
    }
    v1::CreateUserRequest create;
    create.set_user_id(user_id);
    create.mutable_config()->set_context_dim(context_dim);
    create.mutable_config()->set_learner(vision_only ? v1::LEARNER_CONTEXT_ONLY
                                                     : v1::LEARNER_POSTHOC);
    if (absl::GetFlag(FLAGS_lambda_c) > 0.0) {
      create.mutable_config()->set_lambda_c(absl::GetFlag(FLAGS_lambda_c));
    } else if (context_mean_squared_norm > 0.0) {
      const double rho_c = absl::GetFlag(FLAGS_rho_c);
      create.mutable_config()->set_lambda_c(rho_c * context_mean_squared_norm);
      std::printf(
          "context ridge lambda_c = %.4g (rho_c %.3g x E||c||^2 %.4g "
          "of the featurizer on seen foods)\n",
          rho_c * context_mean_squared_norm, rho_c, context_mean_squared_norm);
    } else {
      std::printf(
          "the featurizer reports no E||c||^2: the BanditService's "
          "default lambda_c applies (--lambda_c sets it)\n");
    }
    if (absl::GetFlag(FLAGS_alpha) >= 0.0) {
      create.mutable_config()->set_alpha(absl::GetFlag(FLAGS_alpha));
    }
    if (absl::GetFlag(FLAGS_prior_rounds) > 0.0) {
      create.mutable_config()->set_prior_rounds(
          absl::GetFlag(FLAGS_prior_rounds));
    }
    status = WithRetries([&] {
      return stubs_.bandit->CreateUser(Context(Deadline()).get(), create,
                                       &user_);
    });
    if (!status.ok()) {
      *error = Describe("BanditService", "CreateUser", status);
      return false;
    }
    std::printf("new user %s (%s, context dim %u%s)\n", user_id.c_str(),
                v1::Learner_Name(user_.config().learner()).c_str(),
                user_.config().context_dim(),
                user_.config().prior_pool_version() > 0
                    ? absl::StrFormat(", population prior from pool %d "
                                      "worth %g rounds",
                                      user_.config().prior_pool_version(),
                                      user_.config().prior_rounds())
                          .c_str()
                    : "");
    return true;
  }

  // Runs one bite. Returns false when the meal must stop (plate empty or a
  // service failed); `error` says which.
  bool Bite(const std::string& meal_id, int number, std::string* error) {
    v1::CaptureFrameRequest capture;
    v1::Frame frame;
    grpc::Status status = WithRetries([&] {
      return stubs_.robot->CaptureFrame(Context(Deadline()).get(), capture,
                                        &frame);
    });
    if (!status.ok()) {
      *error = Describe("RobotService", "CaptureFrame", status);
      return false;
    }
    v1::DetectFoodRequest detect;
    *detect.mutable_frame() = frame;
    v1::DetectFoodResponse detected;
    status = WithRetries([&] {
      return stubs_.perception->DetectFood(Context(Deadline()).get(), detect,
                                           &detected);
    });
    if (!status.ok()) {
      *error = Describe("PerceptionService", "DetectFood", status);
      return false;
    }
    if (detected.items_size() == 0) {
      *error = "the plate is empty";
      return false;
    }
    // The most confident item first.
    const v1::FoodItem& item =
        *std::max_element(detected.items().begin(), detected.items().end(),
                          [](const v1::FoodItem& a, const v1::FoodItem& b) {
                            return a.score() < b.score();
                          });

    v1::FeaturizeRequest featurize;
    *featurize.mutable_frame() = frame;
    *featurize.mutable_bbox() = item.bbox();
    v1::FeaturizeResponse features;
    status = WithRetries([&] {
      return stubs_.perception->Featurize(Context(Deadline()).get(), featurize,
                                          &features);
    });
    if (!status.ok()) {
      *error = Describe("PerceptionService", "Featurize", status);
      return false;
    }

    if (!user_ready_) {
      if (!EnsureUser(user_id_, vision_only_, features.context_size(),
                      features.context_mean_squared_norm(), error)) {
        return false;
      }
      user_ready_ = true;
    }
    v1::SelectRequest select;
    select.set_user_id(user_.user_id());
    select.set_meal_id(meal_id);
    select.set_item_label(absl::StrFormat(
        "item@%.0f,%.0f", item.center_px().u(), item.center_px().v()));
    *select.mutable_context() = features.context();
    v1::SelectResponse chosen;
    status = WithRetries([&] {
      return stubs_.bandit->Select(Context(Deadline()).get(), select, &chosen);
    });
    if (!status.ok()) {
      *error = Describe("BanditService", "Select", status);
      return false;
    }

    v1::AcquireRequest acquire;
    acquire.mutable_target()->mutable_center_camera_m()->CopyFrom(
        item.center_camera_m());
    acquire.mutable_target()->set_major_axis_angle_rad(
        item.major_axis_angle_rad());
    *acquire.mutable_target()->mutable_bbox() = item.bbox();
    acquire.set_action(chosen.action());
    v1::AcquireResult result;
    status = RunAcquire(acquire, &result);
    if (!status.ok()) {
      // The action did not complete: the bandit learns nothing from it,
      // and the pending event stays pending.
      *error = Describe("RobotService", "Acquire", status);
      return false;
    }
    bool success = result.success();
    if (absl::GetFlag(FLAGS_confirm) == "operator" ||
        result.success_decided_by_operator()) {
      success = AskOperator();
    }

    v1::ClassifyRequest classify;
    *classify.mutable_samples() = result.trace();
    v1::ClassifyResponse haptic;
    status = WithRetries([&] {
      return stubs_.haptic->Classify(Context(Deadline()).get(), classify,
                                     &haptic);
    });
    std::string haptic_text;
    JournaledUpdate update;
    update.event_id = chosen.event_id();
    update.loss = success ? 0.0 : 1.0;
    const std::string mode = absl::GetFlag(FLAGS_posthoc);
    if (status.ok()) {
      const int category = static_cast<int>(haptic.category());
      const double p = haptic.probabilities_size() >= category && category > 0
                           ? haptic.probabilities(category - 1)
                           : 0.0;
      haptic_text =
          absl::StrFormat("%s %.2f", HapticLabel(haptic.category()), p);
      if (mode == "logprob") {
        update.posthoc.assign(haptic.log_probabilities().begin(),
                              haptic.log_probabilities().end());
      } else if (mode == "prob") {
        update.posthoc.assign(haptic.probabilities().begin(),
                              haptic.probabilities().end());
      }
    } else if (mode != "none") {
      // Without a haptic class the post hoc learner cannot use this bite.
      *error = Describe("HapticService", "Classify", status);
      return false;
    } else {
      haptic_text = "n/a";
    }

    grpc::Status sent = SendUpdate(update, nullptr);
    std::string update_text = "learned";
    if (!sent.ok()) {
      absl::Status journaled = journal_->Append(update);
      update_text =
          journaled.ok()
              ? absl::StrCat("journaled (",
                             Describe("BanditService", "Update", sent), ")")
              : absl::StrCat("LOST: ", journaled.ToString());
    }

    const std::string food =
        result.true_food_type().empty() ? "?" : result.true_food_type();
    Tally& tally = per_food_[food];
    ++tally.attempts;
    ++attempts_;
    if (!success) {
      ++tally.failures;
      ++failures_;
    }
    std::string lcbs;
    for (const v1::ActionEstimate& e : chosen.estimates()) {
      absl::StrAppend(&lcbs,
                      absl::StrFormat(" %s %+.3f", e.action_name(), e.lcb()));
    }
    std::printf("bite %2d  %-14s %-5s lcb[%s ]  %-7s  haptic %-14s %s\n",
                number, food.c_str(), chosen.action_name().c_str(),
                lcbs.c_str(), success ? "success" : "FAILED",
                haptic_text.c_str(), update_text.c_str());
    std::fflush(stdout);
    if (!sent.ok()) {
      *error = Describe("BanditService", "Update", sent);
      return false;
    }
    return true;
  }

  void PrintSummary(const std::string& meal_id) const {
    std::printf("\nmeal %s: %d attempts, %d failures\n", meal_id.c_str(),
                attempts_, failures_);
    std::printf("  %-14s %8s %8s\n", "food", "attempts", "failures");
    for (const auto& [food, tally] : per_food_) {
      std::printf("  %-14s %8d %8d\n", food.c_str(), tally.attempts,
                  tally.failures);
    }
  }

 private:
  static int Deadline() { return absl::GetFlag(FLAGS_deadline_ms); }

  grpc::Status SendUpdate(const JournaledUpdate& update,
                          v1::UpdateResponse* response) {
    v1::UpdateRequest request;
    request.set_event_id(update.event_id);
    request.set_loss(update.loss);
    request.mutable_posthoc()->Add(update.posthoc.begin(),
                                   update.posthoc.end());
    v1::UpdateResponse ignored;
    return WithRetries([&] {
      return stubs_.bandit->Update(Context(Deadline()).get(), request,
                                   response != nullptr ? response : &ignored);
    });
  }

  grpc::Status RunAcquire(const v1::AcquireRequest& request,
                          v1::AcquireResult* result) {
    auto context = Context(absl::GetFlag(FLAGS_acquire_deadline_ms));
    std::unique_ptr<grpc::ClientReader<v1::AcquireProgress>> reader =
        stubs_.robot->Acquire(context.get(), request);
    v1::AcquireProgress progress;
    bool have_result = false;
    int last_phase = -1;
    // On a terminal, one line that follows the phases as they stream in.
    const bool show = isatty(STDOUT_FILENO) != 0;
    while (reader->Read(&progress)) {
      if (show && (progress.phase() != last_phase || progress.has_result())) {
        last_phase = progress.phase();
        std::string phase = v1::AcquirePhase_Name(progress.phase());
        phase = absl::AsciiStrToLower(phase.substr(phase.rfind('_') + 1));
        std::printf("\r  acquiring: %-9s %5.2f s %5.1f N", phase.c_str(),
                    progress.elapsed_s(), progress.force_n());
        std::fflush(stdout);
      }
      if (progress.has_result()) {
        *result = progress.result();
        have_result = true;
      }
    }
    if (show) std::printf("\r%60s\r", "");
    grpc::Status status = reader->Finish();
    if (status.ok() && !have_result) {
      return grpc::Status(grpc::StatusCode::INTERNAL,
                          "Acquire ended without a result");
    }
    return status;
  }

  static bool AskOperator() {
    while (true) {
      std::printf("did the food come up on the fork? [y/n] ");
      std::fflush(stdout);
      std::string answer;
      if (!std::getline(std::cin, answer)) return false;
      if (answer == "y" || answer == "Y") return true;
      if (answer == "n" || answer == "N") return false;
    }
  }

  Stubs stubs_;
  UpdateJournal* journal_;
  const std::string user_id_;
  const bool vision_only_;
  bool user_ready_ = false;  // loaded or created at the first Featurize
  v1::User user_;
  std::map<std::string, Tally> per_food_;
  int attempts_ = 0;
  int failures_ = 0;
};

}  // namespace

int main(int argc, char** argv) {
  absl::SetProgramUsageMessage(
      "Runs bites for one user through the bitewise services.");
  absl::ParseCommandLine(argc, argv);
  const std::string confirm = absl::GetFlag(FLAGS_confirm);
  const std::string posthoc = absl::GetFlag(FLAGS_posthoc);
  if (confirm != "robot" && confirm != "operator") {
    std::fprintf(stderr, "--confirm: expected robot or operator, got %s\n",
                 confirm.c_str());
    return 2;
  }
  if (!(absl::GetFlag(FLAGS_rho_c) > 0.0)) {
    std::fprintf(stderr, "--rho_c must be positive, got %g\n",
                 absl::GetFlag(FLAGS_rho_c));
    return 2;
  }
  if (posthoc != "logprob" && posthoc != "prob" && posthoc != "none") {
    std::fprintf(stderr, "--posthoc: expected logprob, prob or none, got %s\n",
                 posthoc.c_str());
    return 2;
  }

  bitewise::ChannelOptions tls;
  tls.tls_ca_file = absl::GetFlag(FLAGS_tls_ca);
  tls.tls_cert_file = absl::GetFlag(FLAGS_tls_cert);
  tls.tls_key_file = absl::GetFlag(FLAGS_tls_key);
  tls.max_message_bytes = 64 << 20;  // frames and long traces
  const std::string tls_for = absl::GetFlag(FLAGS_tls_for);
  const std::vector<std::string> tls_links = absl::StrSplit(tls_for, ',');
  for (const std::string& link : tls_links) {
    if (link != "all" && link != "bandit" && link != "perception" &&
        link != "haptic" && link != "robot") {
      std::fprintf(stderr, "--tls_for: unknown link \"%s\"\n", link.c_str());
      return 2;
    }
  }
  auto channel = [&](const std::string& link) {
    const std::string address = link == "bandit" ? absl::GetFlag(FLAGS_bandit)
                                : link == "perception"
                                    ? absl::GetFlag(FLAGS_perception)
                                : link == "haptic" ? absl::GetFlag(FLAGS_haptic)
                                                   : absl::GetFlag(FLAGS_robot);
    const bool use_tls =
        tls_for == "all" ||
        std::find(tls_links.begin(), tls_links.end(), link) != tls_links.end();
    bitewise::ChannelOptions options = tls;
    if (!use_tls) options = bitewise::ChannelOptions{};
    options.max_message_bytes = tls.max_message_bytes;
    auto made = bitewise::MakeChannel(address, options);
    if (!made.ok()) {
      std::fprintf(stderr, "%s: %s\n", address.c_str(),
                   made.status().ToString().c_str());
      std::exit(1);
    }
    return *made;
  };
  Stubs stubs;
  stubs.bandit = v1::BanditService::NewStub(channel("bandit"));
  stubs.perception = v1::PerceptionService::NewStub(channel("perception"));
  stubs.haptic = v1::HapticService::NewStub(channel("haptic"));
  stubs.robot = v1::RobotService::NewStub(channel("robot"));

  UpdateJournal journal(absl::GetFlag(FLAGS_journal));
  const std::string user_id = absl::GetFlag(FLAGS_user);
  const std::string meal_id = absl::GetFlag(FLAGS_meal);
  // A new user's context dimension follows the featurizer in use, so the
  // user is found or created at the first Featurize.
  MealRunner runner(std::move(stubs), &journal, user_id, posthoc == "none");
  runner.DrainJournal();

  int limit = absl::GetFlag(FLAGS_bites);
  if (limit <= 0) limit = 64;
  std::printf("meal %s for %s\n", meal_id.c_str(), user_id.c_str());
  int exit_code = 0;
  for (int bite = 1; bite <= limit; ++bite) {
    std::string error;
    if (!runner.Bite(meal_id, bite, &error)) {
      if (error != "the plate is empty") {
        std::fprintf(stderr, "stopping the meal: %s\n", error.c_str());
        exit_code = 1;
      } else {
        std::printf("the plate is empty\n");
      }
      break;
    }
  }
  runner.PrintSummary(meal_id);
  return exit_code;
}
