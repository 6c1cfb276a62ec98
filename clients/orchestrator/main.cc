// bitewise-orchestrator: runs bites for one user through the four services.
// Flags are parsed here into MealOptions; the meal logic is the meal
// library (clients/meal/meal.h).
#include <poll.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <tuple>

#include "absl/flags/flag.h"
#include "absl/flags/usage.h"
#include "absl/strings/ascii.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/synchronization/mutex.h"
#include "clients/meal/meal.h"
#include "clients/meal/service_clients.h"
#include "clients/meal/trace_recording.h"
#include "clients/meal/update_journal.h"
#include "services/common/channel.h"
#include "services/common/flags_usage.h"
#include "services/common/server.h"

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
ABSL_FLAG(std::string, learner, "",
          "Learner for NEW users: posthoc, context_only or polinucb (empty: "
          "posthoc, or context_only with --posthoc=none; "
          "docs/experiments.md, \"The learner default\").");
ABSL_FLAG(std::string, posthoc, "logprob",
          "Post hoc context sent to the bandit: logprob (as the original "
          "research code), prob (as the paper's text) or none (vision only; "
          "new users get the context-only learner).");
ABSL_FLAG(std::string, unfamiliar_posthoc,
          bitewise::domain::UnfamiliarPosthocName(
              bitewise::domain::kDefaultUnfamiliarPosthoc),
          "Post hoc context of a bite whose trace the HapticService calls "
          "unfamiliar: uniform (flattened), zero (none) or asis (HapticNet's "
          "answer); docs/experiments.md, \"Unfamiliar traces\".");
ABSL_FLAG(std::string, limit_reached_posthoc, "",
          "Post hoc context of a bite whose descent the action's force "
          "limit stopped, cutting its trace short: zero (none; a poLinUCB "
          "person's own prediction), uniform or asis (HapticNet's answer on "
          "the cut trace); empty: what was measured for the person's "
          "learner, asis for post hoc LinUCB and zero for poLinUCB "
          "(docs/experiments.md, \"A trace the robot cut short\").");
ABSL_FLAG(std::string, journal, "bitewise-orchestrator.journal",
          "File of updates not yet delivered to the BanditService.");
ABSL_FLAG(int, deadline_ms, 10000, "Deadline of every unary call.");
ABSL_FLAG(int, acquire_deadline_ms, 60000, "Deadline of one Acquire.");
ABSL_FLAG(int, retries, 4,
          "Retries of a call that ends UNAVAILABLE (0-4; gRPC's retry policy, "
          "random backoff below 0.5 s * 2^n, at most 4 s, within the call's "
          "deadline).");
ABSL_FLAG(std::string, record_traces, "",
          "Directory in which to record every bite's force/torque trace with "
          "the bite (traces.csv in bitewise-haptic-train's format, bites.csv "
          "one row per bite), for retraining HapticNet on the lab's own data "
          "(docs/haptic.md). Empty: no recording.");
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
namespace meals = bitewise::meals;
namespace mealpb = bitewise::meal::v1;

// Prints notes, and on a terminal one line that follows the Acquire's
// phases as they stream in.
class TerminalListener : public meals::MealListener {
 public:
  TerminalListener() : show_progress_(isatty(STDOUT_FILENO) != 0) {}

  void OnEvent(const mealpb::BiteEvent& event,
               const mealpb::MealState& state) override {
    if (!show_progress_ || event.step() != mealpb::STEP_ACQUIRE) return;
    if (event.state() == mealpb::STEP_STATE_PROGRESS) {
      std::string phase = v1::AcquirePhase_Name(event.phase());
      phase = absl::AsciiStrToLower(phase.substr(phase.rfind('_') + 1));
      std::printf("\r  acquiring: %-9s %5.2f s %5.1f N", phase.c_str(),
                  event.elapsed_s(), event.force_n());
      std::fflush(stdout);
    } else if (event.state() != mealpb::STEP_STATE_STARTED) {
      std::printf("\r%60s\r", "");
    }
  }

  void OnNote(const std::string& note) override {
    std::printf("%s\n", note.c_str());
    std::fflush(stdout);
  }

 private:
  const bool show_progress_;
};

// One line per bite: food, action, the lower confidence bounds, the
// outcome, the haptic class and what was learned.
void PrintBite(const mealpb::Bite& bite) {
  std::string lcbs;
  for (const v1::ActionEstimate& e : bite.estimates()) {
    absl::StrAppend(&lcbs,
                    absl::StrFormat(" %s %+.3f", e.action_name(), e.lcb()));
  }
  const std::string outcome = bite.outcome() == "success"   ? "success"
                              : bite.outcome() == "failure" ? "FAILED"
                              : bite.outcome() == "pending" ? "?"
                                                            : bite.outcome();
  const std::string haptic =
      bite.haptic().label().empty() ? std::string("n/a")
      : bite.haptic().probabilities().empty()
          ? bite.haptic().label()
          : absl::StrFormat("%s %.2f", bite.haptic().label(),
                            bite.haptic().probability());
  // A trace cut short by the force limit (docs/haptic.md, "A trace the
  // robot cut short"): its haptic class is shown with the limit.
  const std::string limit = bite.force_limit_reached()
                                ? absl::StrFormat("  (stopped at %.0f N)",
                                                  bite.action().max_force_n())
                                : std::string();
  std::string learned = bite.learned();
  if (learned == "journaled") {
    learned = absl::StrCat("journaled (", bite.error(), ")");
  }
  std::printf("bite %2d  %-14s %-5s lcb[%s ]  %-7s  haptic %-14s %s%s\n",
              bite.number(), bite.food().empty() ? "?" : bite.food().c_str(),
              bite.action().name().c_str(), lcbs.c_str(), outcome.c_str(),
              haptic.c_str(), learned.c_str(), limit.c_str());
  std::fflush(stdout);
}

// The termination signal received (0: none); set by the signal thread.
std::atomic<int> interrupted{0};

// The meal a signal stops (null before it exists and after its end). The
// Stop call runs under the lock, so main waits for one in flight before
// the meal and its channels go.
absl::Mutex stop_mu;
meals::Meal* stop_target ABSL_GUARDED_BY(stop_mu) = nullptr;

// SIGINT and SIGTERM, blocked in every thread, are taken here: the first
// tells the arm to stop (a running Acquire ends as "stopped"; before the
// meal exists there is nothing to stop, and the program exits), the meal
// loop ends after the call in flight; a second ends the program at once.
void StartSignalThread() {
  std::thread([] {
    sigset_t signals;
    sigemptyset(&signals);
    sigaddset(&signals, SIGINT);
    sigaddset(&signals, SIGTERM);
    int signal_number = 0;
    if (sigwait(&signals, &signal_number) != 0) return;
    interrupted = signal_number;
    const char* name = signal_number == SIGINT ? "SIGINT" : "SIGTERM";
    {
      absl::MutexLock lock(&stop_mu);
      if (stop_target == nullptr) {
        std::fprintf(stderr, "bitewise-orchestrator: %s: exiting\n", name);
        std::_Exit(128 + signal_number);
      }
    }
    std::fprintf(stderr, "bitewise-orchestrator: %s: stopping the arm\n", name);
    std::thread([] {
      absl::MutexLock lock(&stop_mu);
      if (stop_target == nullptr) return;
      if (absl::StatusOr<bitewise::v1::StopResponse> stopped =
              stop_target->Stop();
          !stopped.ok()) {
        std::fprintf(stderr, "bitewise-orchestrator: Stop failed: %s\n",
                     stopped.status().ToString().c_str());
      }
    }).detach();
    if (sigwait(&signals, &signal_number) == 0) {
      std::fprintf(stderr, "bitewise-orchestrator: second signal: exiting\n");
      std::_Exit(128 + signal_number);
    }
  }).detach();
}

// Asks at the terminal until the answer is y or n. No answer (end of
// input: no terminal, a launcher's closed stdin; or a termination signal
// while waiting) is nullopt, never "no": a "no" nobody gave would teach
// the person's model a failure, bite after bite, while the arm goes on.
// Reads stdin itself (not through std::cin's buffer, which poll cannot
// see), a fifth of a second at a time, so that a signal ends the wait.
std::optional<bool> AskOperator(const std::string& question) {
  static std::string pending;  // read, not yet a whole line
  while (interrupted.load() == 0) {
    std::printf("%s [y/n] ", question.c_str());
    std::fflush(stdout);
    std::string answer;
    while (true) {
      if (const size_t end = pending.find('\n'); end != std::string::npos) {
        answer = pending.substr(0, end);
        pending.erase(0, end + 1);
        break;
      }
      if (interrupted.load() != 0) return std::nullopt;
      pollfd in{STDIN_FILENO, POLLIN, 0};
      const int ready = poll(&in, 1, 200);
      if (ready < 0 && errno == EINTR) continue;
      if (ready < 0) return std::nullopt;
      if (ready == 0) continue;
      char buffer[256];
      const ssize_t n = read(STDIN_FILENO, buffer, sizeof(buffer));
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) return std::nullopt;  // end of input
      pending.append(buffer, static_cast<size_t>(n));
    }
    if (!answer.empty() && answer.back() == '\r') answer.pop_back();
    if (answer == "y" || answer == "Y") return true;
    if (answer == "n" || answer == "N") return false;
  }
  return std::nullopt;
}

void PrintSummary(const mealpb::MealState& state) {
  std::printf("\nmeal %s: %s\n", state.meal_id().c_str(),
              state.summary().text().c_str());
  std::printf("  %-14s %8s %8s\n", "food", "attempts", "failures");
  for (const mealpb::FoodTally& tally : state.summary().foods()) {
    std::printf("  %-14s %8d %8d\n", tally.food().c_str(), tally.attempts(),
                tally.failures());
  }
}

}  // namespace

int main(int argc, char** argv) {
  absl::SetProgramUsageMessage(
      "Runs bites for one user through the bitewise services.");
  bitewise::ShowOwnFlagsInHelp();
  bitewise::ParseFlagsOnly(argc, argv);
  // SIGINT and SIGTERM go to the signal thread (blocked here, before any
  // other thread starts, so every thread inherits the mask).
  bitewise::BlockTerminationSignals();
  StartSignalThread();
  const std::string confirm = absl::GetFlag(FLAGS_confirm);
  const std::string posthoc = absl::GetFlag(FLAGS_posthoc);
  if (confirm != "robot" && confirm != "operator") {
    std::fprintf(stderr, "--confirm: expected robot or operator, got %s\n",
                 confirm.c_str());
    return 2;
  }
  if (const double rho_c = absl::GetFlag(FLAGS_rho_c);
      !(rho_c > 0.0 && std::isfinite(rho_c))) {
    std::fprintf(stderr, "--rho_c must be a positive number, got %g\n", rho_c);
    return 2;
  }
  // Numbers that would otherwise fail later, in a service's words (a
  // deadline of 0 as DEADLINE_EXCEEDED of the first call, an Acquire
  // deadline after Select recorded a pending bite) or be dropped silently
  // (a negative count of bites, a ridge or prior that is not a number).
  for (const auto& [flag, value, low, high] :
       {std::tuple<const char*, double, double, double>{
            "--bites", absl::GetFlag(FLAGS_bites), 0, 1e6},
        {"--deadline_ms", absl::GetFlag(FLAGS_deadline_ms), 1, 3.6e6},
        {"--acquire_deadline_ms", absl::GetFlag(FLAGS_acquire_deadline_ms), 1,
         3.6e6},
        {"--retries", absl::GetFlag(FLAGS_retries), 0, 4},
        {"--lambda_c", absl::GetFlag(FLAGS_lambda_c), 0, 1e12},
        {"--prior_rounds", absl::GetFlag(FLAGS_prior_rounds), 0, 1e9}}) {
    if (!(value >= low && value <= high)) {
      std::fprintf(stderr, "%s must be from %g to %g, got %g\n", flag, low,
                   high, value);
      return 2;
    }
  }
  if (const double alpha = absl::GetFlag(FLAGS_alpha);
      !std::isfinite(alpha) || alpha > 1e6) {
    std::fprintf(stderr,
                 "--alpha must be a number (negative: the BanditService's "
                 "default), got %g\n",
                 alpha);
    return 2;
  }
  if (posthoc != "logprob" && posthoc != "prob" && posthoc != "none") {
    std::fprintf(stderr, "--posthoc: expected logprob, prob or none, got %s\n",
                 posthoc.c_str());
    return 2;
  }

  meals::ServiceLinks links;
  links.bandit = absl::GetFlag(FLAGS_bandit);
  links.perception = absl::GetFlag(FLAGS_perception);
  links.haptic = absl::GetFlag(FLAGS_haptic);
  links.robot = absl::GetFlag(FLAGS_robot);
  links.tls.tls_ca_file = absl::GetFlag(FLAGS_tls_ca);
  links.tls.tls_cert_file = absl::GetFlag(FLAGS_tls_cert);
  links.tls.tls_key_file = absl::GetFlag(FLAGS_tls_key);
  links.tls_for = absl::GetFlag(FLAGS_tls_for);
  links.bandit_tls_name = absl::GetFlag(FLAGS_bandit_tls_name);
  links.max_attempts = absl::GetFlag(FLAGS_retries) + 1;
  absl::StatusOr<meals::ServiceChannels> channels =
      meals::OpenServiceChannels(links);
  if (!channels.ok()) {
    std::fprintf(stderr, "%s\n", channels.status().ToString().c_str());
    return absl::IsInvalidArgument(channels.status()) ? 2 : 1;
  }
  meals::CallDeadlines deadlines;
  deadlines.unary = absl::Milliseconds(absl::GetFlag(FLAGS_deadline_ms));
  deadlines.acquire =
      absl::Milliseconds(absl::GetFlag(FLAGS_acquire_deadline_ms));
  meals::ServiceClients clients(*channels, deadlines);

  meals::MealOptions options;
  options.user_id = absl::GetFlag(FLAGS_user);
  options.meal_id = absl::GetFlag(FLAGS_meal);
  options.posthoc = posthoc == "logprob" ? meals::PosthocMode::kLogProbabilities
                    : posthoc == "prob"  ? meals::PosthocMode::kProbabilities
                                         : meals::PosthocMode::kNone;
  options.confirm = confirm == "operator" ? meals::ConfirmBy::kOperator
                                          : meals::ConfirmBy::kRobot;
  // Each rule by name (nullopt, said on stderr: not a rule);
  // --limit_reached_posthoc may be empty, the rule of the person's learner.
  const auto parse_rule = [](const char* flag, const std::string& value)
      -> std::optional<bitewise::domain::UnfamiliarPosthoc> {
    absl::StatusOr<bitewise::domain::UnfamiliarPosthoc> parsed =
        bitewise::domain::ParseUnfamiliarPosthoc(value);
    if (parsed.ok()) return *parsed;
    std::fprintf(stderr, "--%s: %s\n", flag,
                 std::string(parsed.status().message()).c_str());
    return std::nullopt;
  };
  const std::optional<bitewise::domain::UnfamiliarPosthoc> unfamiliar =
      parse_rule("unfamiliar_posthoc", absl::GetFlag(FLAGS_unfamiliar_posthoc));
  if (!unfamiliar.has_value()) return 2;
  options.unfamiliar_posthoc = *unfamiliar;
  if (const std::string limit = absl::GetFlag(FLAGS_limit_reached_posthoc);
      !limit.empty()) {
    options.limit_reached_posthoc = parse_rule("limit_reached_posthoc", limit);
    if (!options.limit_reached_posthoc.has_value()) return 2;
  }
  absl::StatusOr<bitewise::v1::Learner> learner =
      meals::ParseLearner(absl::GetFlag(FLAGS_learner), options.posthoc);
  if (!learner.ok()) {
    std::fprintf(stderr, "%s\n",
                 std::string(learner.status().message()).c_str());
    return 2;
  }
  options.learner = *learner;
  options.lambda_c = absl::GetFlag(FLAGS_lambda_c);
  options.rho_c = absl::GetFlag(FLAGS_rho_c);
  options.alpha = absl::GetFlag(FLAGS_alpha);
  options.prior_rounds = absl::GetFlag(FLAGS_prior_rounds);
  std::unique_ptr<meals::TraceRecording> recording;
  if (!absl::GetFlag(FLAGS_record_traces).empty()) {
    absl::StatusOr<std::unique_ptr<meals::TraceRecording>> opened =
        meals::TraceRecording::Open(absl::GetFlag(FLAGS_record_traces));
    if (!opened.ok()) {
      std::fprintf(stderr, "--record_traces: %s\n",
                   opened.status().ToString().c_str());
      return 2;
    }
    recording = std::move(opened).value();
    options.recording = recording.get();
    if (!recording->note().empty()) {
      std::printf("--record_traces: %s\n", recording->note().c_str());
    }
  }

  meals::UpdateJournal journal(absl::GetFlag(FLAGS_journal));
  // The claim first: the writability check may create and remove the
  // file, which must not happen under another holder's appends.
  absl::StatusOr<std::unique_ptr<meals::JournalClaim>> claim =
      meals::JournalClaim::Take(journal.path());
  if (!claim.ok()) {
    std::fprintf(stderr, "--journal: %s\n", claim.status().ToString().c_str());
    return 2;
  }
  if (absl::Status writable = journal.CheckWritable(); !writable.ok()) {
    std::fprintf(stderr, "--journal: %s\n", writable.ToString().c_str());
    return 2;
  }
  TerminalListener listener;
  // A new user's context dimension follows the featurizer in use, so the
  // user is found or created at the first bite.
  meals::Meal meal(&clients, &journal, options, &listener);
  const absl::StatusOr<int> delivered = meal.DeliverJournal();
  if (!delivered.ok()) {
    std::fprintf(stderr, "journal: %s\n",
                 delivered.status().ToString().c_str());
  } else if (*delivered > 0) {
    std::printf("journal: delivered %d update(s) left from an earlier run\n",
                *delivered);
  }

  {
    absl::MutexLock lock(&stop_mu);
    stop_target = &meal;  // from here a signal stops the meal
  }

  int limit = absl::GetFlag(FLAGS_bites);
  if (limit <= 0) limit = 64;
  std::printf("meal %s for %s\n", options.meal_id.c_str(),
              options.user_id.c_str());
  int exit_code = 0;
  auto stop = [&](const std::string& why) {
    std::fflush(stdout);  // the bite's lines first
    std::fprintf(stderr, "stopping the meal: %s\n", why.c_str());
    exit_code = 1;
  };
  bool reported = false;
  const auto signalled = [&] {
    if (interrupted.load() == 0) return false;
    if (!reported) {
      stop(interrupted.load() == SIGINT ? "interrupted (SIGINT)"
                                        : "interrupted (SIGTERM)");
      exit_code = 128 + interrupted.load();
      reported = true;
    }
    return true;
  };
  for (int bite = 1; bite <= limit; ++bite) {
    // A signal after this count is taken (meal.stops()) refuses the look
    // or the bite even if it lands before the call begins.
    uint64_t stops = meal.stops();
    if (signalled()) break;
    absl::Status looked = meal.LookAtPlate(stops);
    if (!looked.ok()) {
      if (!signalled()) stop(std::string(looked.message()));
      break;
    }
    if (!meal.state().running()) {
      std::printf("the plate is empty\n");
      break;
    }
    stops = meal.stops();
    if (signalled()) break;
    absl::Status bitten = meal.Bite(std::nullopt, stops);
    mealpb::Bite current = meal.state().current();
    if (!bitten.ok()) {
      if (current.number() == bite) PrintBite(current);
      if (!signalled()) stop(std::string(bitten.message()));
      break;
    }
    if (!current.question().empty()) {
      // The bite's line first, so the question is read knowing which food
      // and which action it is about.
      PrintBite(current);
      const std::optional<bool> success = AskOperator(current.question());
      if (!success.has_value()) {
        std::printf("\n");
        if (!signalled()) {
          stop(
              "no answer from the operator (end of input): this bite is not "
              "learned (its event stays pending); --confirm=operator needs "
              "someone at the terminal");
        }
        break;
      }
      absl::Status answered = meal.Answer(current.event_id(), *success);
      if (!answered.ok()) {
        stop(std::string(answered.message()));
        break;
      }
      meal.ConfirmAnswer();
      current = meal.state().current();
      std::printf("  answered %s: %s\n", current.answer().c_str(),
                  current.learned().c_str());
    } else {
      PrintBite(current);
    }
    if (current.learned() != "learned") {
      stop(current.error().empty() ? current.learned() : current.error());
      break;
    }
  }
  signalled();  // a signal during the last bite still sets the exit code
  const absl::Status finished = meal.Finish();
  if (!finished.ok()) {
    std::fprintf(stderr, "%s\n", finished.ToString().c_str());
  }
  PrintSummary(meal.state());
  if (recording != nullptr) {
    std::printf("recorded %lld trace(s) in %s\n",
                static_cast<long long>(recording->recorded()),
                recording->dir().c_str());
  }
  {
    absl::MutexLock lock(&stop_mu);  // waits for a Stop in flight
    stop_target = nullptr;
  }
  signalled();
  return exit_code;
}
