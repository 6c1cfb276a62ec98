#include "clients/orchestrator/meal_runner.h"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <iostream>
#include <utility>

#include "absl/strings/ascii.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "services/common/grpc_status.h"
#include "services/domain/haptic_class.h"

namespace bitewise::orchestrator {
namespace {

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

std::string Describe(const char* service, const char* call,
                     const grpc::Status& status) {
  return absl::StrCat(service, ".", call,
                      " failed: ", bitewise::FromGrpcStatus(status).ToString());
}

}  // namespace

MealRunner::MealRunner(MealStubs stubs, UpdateJournal* journal,
                       MealRunnerOptions options)
    : stubs_(std::move(stubs)),
      journal_(journal),
      options_(std::move(options)) {}

void MealRunner::DrainJournal() {
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
bool MealRunner::EnsureUser(const std::string& user_id, bool vision_only,
                            int context_dim, double context_mean_squared_norm,
                            std::string* error) {
  v1::GetUserRequest get;
  get.set_user_id(user_id);
  grpc::Status status =
      stubs_.bandit->GetUser(Context(options_.deadline_ms).get(), get, &user_);
  if (status.ok()) {
    if (static_cast<int>(user_.config().context_dim()) != context_dim) {
      *error = absl::StrFormat(
          "user %s learns from %u context values but the featurizer gives "
          "%d; use another --user or the featurizer the user started with",
          user_id, user_.config().context_dim(), context_dim);
      return false;
    }
    std::printf("user %s continues from model version %lld (%s)\n",
                user_id.c_str(), static_cast<long long>(user_.model_version()),
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
  if (options_.lambda_c > 0.0) {
    create.mutable_config()->set_lambda_c(options_.lambda_c);
  } else if (context_mean_squared_norm > 0.0) {
    const double rho_c = options_.rho_c;
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
  if (options_.alpha >= 0.0) {
    create.mutable_config()->set_alpha(options_.alpha);
  }
  if (options_.prior_rounds > 0.0) {
    create.mutable_config()->set_prior_rounds(options_.prior_rounds);
  }
  status = stubs_.bandit->CreateUser(Context(options_.deadline_ms).get(),
                                     create, &user_);
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
BiteResult MealRunner::Bite(const std::string& meal_id, int number) {
  std::string error_text;
  std::string* error = &error_text;
  auto failed = [&] { return BiteResult{BiteEnd::kFailed, error_text}; };
  v1::CaptureFrameRequest capture;
  v1::Frame frame;
  grpc::Status status = stubs_.robot->CaptureFrame(
      Context(options_.deadline_ms).get(), capture, &frame);
  if (!status.ok()) {
    *error = Describe("RobotService", "CaptureFrame", status);
    return failed();
  }
  v1::DetectFoodRequest detect;
  *detect.mutable_frame() = frame;
  v1::DetectFoodResponse detected;
  status = stubs_.perception->DetectFood(Context(options_.deadline_ms).get(),
                                         detect, &detected);
  if (!status.ok()) {
    *error = Describe("PerceptionService", "DetectFood", status);
    return failed();
  }
  if (detected.items_size() == 0) return BiteResult{BiteEnd::kPlateEmpty, ""};
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
  status = stubs_.perception->Featurize(Context(options_.deadline_ms).get(),
                                        featurize, &features);
  if (!status.ok()) {
    *error = Describe("PerceptionService", "Featurize", status);
    return failed();
  }

  if (!user_ready_) {
    if (!EnsureUser(options_.user_id, options_.posthoc == PosthocMode::kNone,
                    features.context_size(),
                    features.context_mean_squared_norm(), error)) {
      return failed();
    }
    user_ready_ = true;
  }
  v1::SelectRequest select;
  select.set_user_id(user_.user_id());
  select.set_meal_id(meal_id);
  select.set_item_label(absl::StrFormat("item@%.0f,%.0f", item.center_px().u(),
                                        item.center_px().v()));
  *select.mutable_context() = features.context();
  v1::SelectResponse chosen;
  status = stubs_.bandit->Select(Context(options_.deadline_ms).get(), select,
                                 &chosen);
  if (!status.ok()) {
    *error = Describe("BanditService", "Select", status);
    return failed();
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
    return failed();
  }
  bool success = result.success();
  if (options_.confirm == ConfirmBy::kOperator ||
      result.success_decided_by_operator()) {
    success = AskOperator();
  }

  v1::ClassifyRequest classify;
  *classify.mutable_samples() = result.trace();
  v1::ClassifyResponse haptic;
  status = stubs_.haptic->Classify(Context(options_.deadline_ms).get(),
                                   classify, &haptic);
  std::string haptic_text;
  JournaledUpdate update;
  update.event_id = chosen.event_id();
  update.loss = success ? 0.0 : 1.0;
  const PosthocMode mode = options_.posthoc;
  if (status.ok()) {
    const int category = static_cast<int>(haptic.category());
    const double p = haptic.probabilities_size() >= category && category > 0
                         ? haptic.probabilities(category - 1)
                         : 0.0;
    haptic_text = absl::StrFormat("%s %.2f", HapticLabel(haptic.category()), p);
    if (mode == PosthocMode::kLogProbabilities) {
      update.posthoc.assign(haptic.log_probabilities().begin(),
                            haptic.log_probabilities().end());
    } else if (mode == PosthocMode::kProbabilities) {
      update.posthoc.assign(haptic.probabilities().begin(),
                            haptic.probabilities().end());
    }
  } else if (mode != PosthocMode::kNone) {
    // Without a haptic class the post hoc learner cannot use this bite.
    *error = Describe("HapticService", "Classify", status);
    return failed();
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
  std::printf("bite %2d  %-14s %-5s lcb[%s ]  %-7s  haptic %-14s %s\n", number,
              food.c_str(), chosen.action_name().c_str(), lcbs.c_str(),
              success ? "success" : "FAILED", haptic_text.c_str(),
              update_text.c_str());
  std::fflush(stdout);
  if (!sent.ok()) {
    *error = Describe("BanditService", "Update", sent);
    return failed();
  }
  return BiteResult{BiteEnd::kDone, ""};
}

void MealRunner::PrintSummary(const std::string& meal_id) const {
  std::printf("\nmeal %s: %d attempts, %d failures\n", meal_id.c_str(),
              attempts_, failures_);
  std::printf("  %-14s %8s %8s\n", "food", "attempts", "failures");
  for (const auto& [food, tally] : per_food_) {
    std::printf("  %-14s %8d %8d\n", food.c_str(), tally.attempts,
                tally.failures);
  }
}

grpc::Status MealRunner::SendUpdate(const JournaledUpdate& update,
                                    v1::UpdateResponse* response) {
  v1::UpdateRequest request;
  request.set_event_id(update.event_id);
  request.set_loss(update.loss);
  request.mutable_posthoc()->Add(update.posthoc.begin(), update.posthoc.end());
  v1::UpdateResponse ignored;
  return stubs_.bandit->Update(Context(options_.deadline_ms).get(), request,
                               response != nullptr ? response : &ignored);
}

grpc::Status MealRunner::RunAcquire(const v1::AcquireRequest& request,
                                    v1::AcquireResult* result) {
  auto context = Context(options_.acquire_deadline_ms);
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

bool MealRunner::AskOperator() {
  while (true) {
    std::printf("did the food come up on the fork? [y/n] ");
    std::fflush(stdout);
    std::string answer;
    if (!std::getline(std::cin, answer)) return false;
    if (answer == "y" || answer == "Y") return true;
    if (answer == "n" || answer == "N") return false;
  }
}

}  // namespace bitewise::orchestrator
