// bitewise-orchestrator: runs bites for one user through the four services.
// Flags are parsed here into MealRunnerOptions; the meal logic is
// MealRunner (meal_runner.h).
#include <algorithm>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "absl/flags/flag.h"
#include "absl/flags/parse.h"
#include "absl/flags/usage.h"
#include "absl/strings/str_split.h"
#include "bitewise/v1/bandit.grpc.pb.h"
#include "bitewise/v1/haptic.grpc.pb.h"
#include "bitewise/v1/perception.grpc.pb.h"
#include "bitewise/v1/robot.grpc.pb.h"
#include "clients/orchestrator/meal_runner.h"
#include "services/common/channel.h"
#include "services/common/flags_usage.h"

ABSL_FLAG(std::string, user, "demo-user", "User whose model learns.");
ABSL_FLAG(std::string, meal, "meal-1", "Meal id recorded with each event.");
ABSL_FLAG(int, bites, 0,
          "Most bite attempts; 0 = until the plate is empty (at most 64).");
ABSL_FLAG(std::string, bandit, "127.0.0.1:50051",
          "BanditService address; replicas on one PostgreSQL database: "
          "IP:PORT,IP:PORT or dns:///NAME:PORT (calls spread round robin "
          "over those that are up; deploy/README.md).");
ABSL_FLAG(std::string, bandit_tls_name, "",
          "The name to check the BanditService certificates against (every "
          "replica's certificate must carry it); default: the address.");
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
ABSL_FLAG(int, retries, 4,
          "Retries of a call that ends UNAVAILABLE (0-4; gRPC's retry policy, "
          "random backoff below 0.5 s * 2^n, at most 4 s, within the call's "
          "deadline).");
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
namespace orchestrator = bitewise::orchestrator;

}  // namespace

int main(int argc, char** argv) {
  absl::SetProgramUsageMessage(
      "Runs bites for one user through the bitewise services.");
  bitewise::ShowOwnFlagsInHelp();
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
    options.max_attempts = absl::GetFlag(FLAGS_retries) + 1;
    if (link == "bandit" && use_tls) {
      options.tls_server_name_override = absl::GetFlag(FLAGS_bandit_tls_name);
    }
    auto made = bitewise::MakeChannel(address, options);
    if (!made.ok()) {
      std::fprintf(stderr, "%s: %s\n", address.c_str(),
                   made.status().ToString().c_str());
      std::exit(1);
    }
    return *made;
  };
  orchestrator::MealStubs stubs;
  stubs.bandit = v1::BanditService::NewStub(channel("bandit"));
  stubs.perception = v1::PerceptionService::NewStub(channel("perception"));
  stubs.haptic = v1::HapticService::NewStub(channel("haptic"));
  stubs.robot = v1::RobotService::NewStub(channel("robot"));

  orchestrator::MealRunnerOptions options;
  options.user_id = absl::GetFlag(FLAGS_user);
  options.posthoc =
      posthoc == "logprob" ? orchestrator::PosthocMode::kLogProbabilities
      : posthoc == "prob"  ? orchestrator::PosthocMode::kProbabilities
                           : orchestrator::PosthocMode::kNone;
  options.confirm = confirm == "operator" ? orchestrator::ConfirmBy::kOperator
                                          : orchestrator::ConfirmBy::kRobot;
  options.lambda_c = absl::GetFlag(FLAGS_lambda_c);
  options.rho_c = absl::GetFlag(FLAGS_rho_c);
  options.alpha = absl::GetFlag(FLAGS_alpha);
  options.prior_rounds = absl::GetFlag(FLAGS_prior_rounds);
  options.deadline_ms = absl::GetFlag(FLAGS_deadline_ms);
  options.acquire_deadline_ms = absl::GetFlag(FLAGS_acquire_deadline_ms);

  orchestrator::UpdateJournal journal(absl::GetFlag(FLAGS_journal));
  const std::string meal_id = absl::GetFlag(FLAGS_meal);
  // A new user's context dimension follows the featurizer in use, so the
  // user is found or created at the first Featurize.
  orchestrator::MealRunner runner(std::move(stubs), &journal, options);
  runner.DrainJournal();

  int limit = absl::GetFlag(FLAGS_bites);
  if (limit <= 0) limit = 64;
  std::printf("meal %s for %s\n", meal_id.c_str(), options.user_id.c_str());
  int exit_code = 0;
  for (int bite = 1; bite <= limit; ++bite) {
    const orchestrator::BiteResult result = runner.Bite(meal_id, bite);
    if (result.end == orchestrator::BiteEnd::kPlateEmpty) {
      std::printf("the plate is empty\n");
      break;
    }
    if (result.end == orchestrator::BiteEnd::kFailed) {
      std::fprintf(stderr, "stopping the meal: %s\n", result.error.c_str());
      exit_code = 1;
      break;
    }
  }
  runner.PrintSummary(meal_id);
  return exit_code;
}
