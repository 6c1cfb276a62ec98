// bitewise-console: the meal at the table and each person's learning, in a
// browser. Flags are parsed here; the server is ConsoleServer, the meal
// MealHost (docs/console.md).
#include <pthread.h>

#include <csignal>
#include <cstdio>
#include <iostream>
#include <memory>
#include <string>

#include "absl/flags/flag.h"
#include "absl/flags/usage.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "clients/console/access_list.h"
#include "clients/console/console_server.h"
#include "clients/console/meal_host.h"
#include "clients/meal/service_clients.h"
#include "clients/meal/trace_recording.h"
#include "services/common/channel.h"
#include "services/common/flags_usage.h"
#include "services/common/server.h"

ABSL_FLAG(std::string, listen, "127.0.0.1:8080",
          "HOST:PORT to serve on. Off loopback, --tls_cert/--tls_key and "
          "--access_file are required.");
ABSL_FLAG(std::string, tls_cert, "", "PEM certificate chain: serve HTTPS.");
ABSL_FLAG(std::string, tls_key, "", "PEM private key of --tls_cert.");
ABSL_FLAG(std::string, access_file, "",
          "Credentials and roles (caregiver, researcher), one per line: NAME "
          "ROLE HASH (docs/console.md). With it, every request needs them.");
ABSL_FLAG(bool, hash_password, false,
          "Read a password from standard input, print the HASH field for the "
          "access file, and exit.");
ABSL_FLAG(std::string, bandit, "127.0.0.1:50051", "BanditService address.");
ABSL_FLAG(std::string, perception, "127.0.0.1:50052",
          "PerceptionService address.");
ABSL_FLAG(std::string, haptic, "127.0.0.1:50053", "HapticService address.");
ABSL_FLAG(std::string, robot, "127.0.0.1:50054", "RobotService address.");
ABSL_FLAG(std::string, services_tls_ca, "",
          "CA bundle of the services (turns on TLS to them).");
ABSL_FLAG(std::string, services_tls_cert, "",
          "The console's client certificate for mutual TLS to the services "
          "(its identity there; the robot role).");
ABSL_FLAG(std::string, services_tls_key, "", "Key of --services_tls_cert.");
ABSL_FLAG(std::string, services_tls_for, "all",
          "Which service links use the TLS flags: all, or a comma-separated "
          "subset of bandit, perception, haptic, robot (say, the "
          "workstation's services while the robot computer's own stay "
          "plaintext on loopback).");
ABSL_FLAG(std::string, research_tls_cert, "",
          "A second client certificate, for the researcher view's calls to the "
          "BanditService (listing people and events, models): its identity "
          "should have the researcher role there, since the robot role may "
          "not list. Default: the calls use --services_tls_cert.");
ABSL_FLAG(std::string, research_tls_key, "", "Key of --research_tls_cert.");
ABSL_FLAG(std::string, confirm, "robot",
          "Who decides success: robot, or operator (the table view asks).");
ABSL_FLAG(std::string, learner, "",
          "Learner for NEW users: posthoc, context_only or polinucb (empty: "
          "posthoc, or context_only with --posthoc=none; "
          "docs/experiments.md, \"The learner default\").");
ABSL_FLAG(std::string, posthoc, "logprob",
          "Post hoc context sent to the bandit: logprob, prob or none.");
ABSL_FLAG(std::string, journal, "bitewise-console.journal",
          "File of updates not yet delivered (answers, failed Updates).");
ABSL_FLAG(double, rho_c, 1.0,
          "For a NEW person: lambda_c = rho_c x the featurizer's E||c||^2.");
ABSL_FLAG(std::string, record_traces, "",
          "Directory in which to record every bite's force/torque trace "
          "with the bite, for retraining HapticNet (docs/haptic.md). Empty: "
          "no recording.");
ABSL_FLAG(double, lambda_c, 0.0, "For a NEW person: the context ridge.");
ABSL_FLAG(double, alpha, -1.0,
          "For a NEW person: exploration; negative keeps the service's.");
ABSL_FLAG(double, prior_rounds, 0.0,
          "For a NEW person: start from the population pool, worth this many "
          "rounds.");
ABSL_FLAG(int, deadline_ms, 10000, "Deadline of every unary call.");
ABSL_FLAG(int, acquire_deadline_ms, 60000, "Deadline of one Acquire.");
ABSL_FLAG(int, retries, 4, "Retries of a call that ends UNAVAILABLE (0-4).");

namespace {

namespace console = bitewise::console;
namespace meals = bitewise::meals;

int Fail(const std::string& message) {
  std::fprintf(stderr, "bitewise-console: %s\n", message.c_str());
  return 1;
}

}  // namespace

int main(int argc, char** argv) {
  // SIGTERM and SIGINT are taken by sigwait at the end.
  bitewise::BlockTerminationSignals();
  absl::SetProgramUsageMessage(
      "Serves the table view and the researcher view of bitewise meals.");
  bitewise::ShowOwnFlagsInHelp();
  bitewise::ParseFlagsOnly(argc, argv);

  if (absl::GetFlag(FLAGS_hash_password)) {
    std::string password;
    if (!std::getline(std::cin, password) || password.empty()) {
      return Fail("--hash_password: no password on standard input");
    }
    absl::StatusOr<std::string> hash = console::HashPassword(password);
    if (!hash.ok()) return Fail(hash.status().ToString());
    std::printf("%s\n", hash->c_str());
    return 0;
  }

  const std::string confirm = absl::GetFlag(FLAGS_confirm);
  const std::string posthoc = absl::GetFlag(FLAGS_posthoc);
  if (confirm != "robot" && confirm != "operator") {
    return Fail("--confirm: expected robot or operator, got " + confirm);
  }
  if (posthoc != "logprob" && posthoc != "prob" && posthoc != "none") {
    return Fail("--posthoc: expected logprob, prob or none, got " + posthoc);
  }
  if (!(absl::GetFlag(FLAGS_rho_c) > 0.0)) {
    return Fail("--rho_c must be positive");
  }

  console::ConsoleServerOptions server_options;
  const std::string listen = absl::GetFlag(FLAGS_listen);
  const size_t colon = listen.rfind(':');
  if (colon == std::string::npos ||
      !absl::SimpleAtoi(listen.substr(colon + 1), &server_options.port) ||
      server_options.port < 0 || server_options.port > 65535) {
    return Fail("--listen: expected HOST:PORT, got " + listen);
  }
  server_options.host = listen.substr(0, colon);
  if (server_options.host.size() > 2 && server_options.host.front() == '[') {
    server_options.host =
        server_options.host.substr(1, server_options.host.size() - 2);
  }
  server_options.tls_cert_file = absl::GetFlag(FLAGS_tls_cert);
  server_options.tls_key_file = absl::GetFlag(FLAGS_tls_key);
  if (!absl::GetFlag(FLAGS_access_file).empty()) {
    absl::StatusOr<console::AccessList> access =
        console::AccessList::Load(absl::GetFlag(FLAGS_access_file));
    if (!access.ok()) return Fail(access.status().ToString());
    server_options.access =
        std::make_shared<const console::AccessList>(*access);
  }

  meals::ServiceLinks links;
  links.bandit = absl::GetFlag(FLAGS_bandit);
  links.perception = absl::GetFlag(FLAGS_perception);
  links.haptic = absl::GetFlag(FLAGS_haptic);
  links.robot = absl::GetFlag(FLAGS_robot);
  links.tls.tls_ca_file = absl::GetFlag(FLAGS_services_tls_ca);
  links.tls.tls_cert_file = absl::GetFlag(FLAGS_services_tls_cert);
  links.tls.tls_key_file = absl::GetFlag(FLAGS_services_tls_key);
  links.tls_for = absl::GetFlag(FLAGS_services_tls_for);
  links.max_attempts = absl::GetFlag(FLAGS_retries) + 1;
  absl::StatusOr<meals::ServiceChannels> channels =
      meals::OpenServiceChannels(links);
  if (!channels.ok()) return Fail(channels.status().ToString());
  server_options.services = {
      {"bitewise.v1.BanditService", links.bandit, channels->bandit},
      {"bitewise.v1.PerceptionService", links.perception, channels->perception},
      {"bitewise.v1.HapticService", links.haptic, channels->haptic},
      {"bitewise.v1.RobotService", links.robot, channels->robot}};
  meals::CallDeadlines deadlines;
  deadlines.unary = absl::Milliseconds(absl::GetFlag(FLAGS_deadline_ms));
  deadlines.acquire =
      absl::Milliseconds(absl::GetFlag(FLAGS_acquire_deadline_ms));
  meals::ServiceClients clients(*channels, deadlines);
  std::unique_ptr<meals::BanditClient> research_bandit;
  if (!absl::GetFlag(FLAGS_research_tls_cert).empty()) {
    bitewise::ChannelOptions research = links.tls;
    research.max_message_bytes = links.max_message_bytes;
    research.max_attempts = links.max_attempts;
    research.tls_cert_file = absl::GetFlag(FLAGS_research_tls_cert);
    research.tls_key_file = absl::GetFlag(FLAGS_research_tls_key);
    absl::StatusOr<std::shared_ptr<grpc::Channel>> channel =
        bitewise::MakeChannel(absl::GetFlag(FLAGS_bandit), research);
    if (!channel.ok()) return Fail(channel.status().ToString());
    research_bandit =
        std::make_unique<meals::BanditClient>(*channel, deadlines);
    server_options.research_bandit = research_bandit.get();
  }

  console::MealHostOptions host_options;
  host_options.journal_path = absl::GetFlag(FLAGS_journal);
  // The claim first: the writability check may create and remove the
  // file, which must not happen under another holder's appends.
  absl::StatusOr<std::unique_ptr<meals::JournalClaim>> claim =
      meals::JournalClaim::Take(host_options.journal_path);
  if (!claim.ok()) {
    return Fail(absl::StrCat("--journal: ", claim.status().ToString()));
  }
  if (absl::Status writable =
          meals::UpdateJournal(host_options.journal_path).CheckWritable();
      !writable.ok()) {
    return Fail(absl::StrCat("--journal: ", writable.ToString()));
  }
  meals::MealOptions& defaults = host_options.defaults;
  defaults.posthoc = posthoc == "logprob"
                         ? meals::PosthocMode::kLogProbabilities
                     : posthoc == "prob" ? meals::PosthocMode::kProbabilities
                                         : meals::PosthocMode::kNone;
  defaults.confirm = confirm == "operator" ? meals::ConfirmBy::kOperator
                                           : meals::ConfirmBy::kRobot;
  absl::StatusOr<bitewise::v1::Learner> learner =
      meals::ParseLearner(absl::GetFlag(FLAGS_learner), defaults.posthoc);
  if (!learner.ok()) return Fail(std::string(learner.status().message()));
  defaults.learner = *learner;
  defaults.lambda_c = absl::GetFlag(FLAGS_lambda_c);
  defaults.rho_c = absl::GetFlag(FLAGS_rho_c);
  defaults.alpha = absl::GetFlag(FLAGS_alpha);
  defaults.prior_rounds = absl::GetFlag(FLAGS_prior_rounds);
  std::unique_ptr<meals::TraceRecording> recording;
  if (!absl::GetFlag(FLAGS_record_traces).empty()) {
    absl::StatusOr<std::unique_ptr<meals::TraceRecording>> opened =
        meals::TraceRecording::Open(absl::GetFlag(FLAGS_record_traces));
    if (!opened.ok()) {
      return Fail(
          absl::StrCat("--record_traces: ", opened.status().ToString()));
    }
    recording = std::move(opened).value();
    defaults.recording = recording.get();
    if (!recording->note().empty()) {
      std::fprintf(stderr, "--record_traces: %s\n", recording->note().c_str());
    }
  }
  console::MealHost host(&clients, host_options);
  // What a killed console left undelivered goes first.
  const absl::StatusOr<int> delivered = host.DeliverJournal();
  if (!delivered.ok()) {
    std::fprintf(stderr, "journal: %s (kept for the next meal)\n",
                 delivered.status().ToString().c_str());
  } else if (*delivered > 0) {
    std::fprintf(stderr, "journal: delivered %d update(s) left from before\n",
                 *delivered);
  }

  const bool access = server_options.access != nullptr;
  const bool tls = !server_options.tls_cert_file.empty();
  absl::StatusOr<std::unique_ptr<console::ConsoleServer>> server =
      console::ConsoleServer::Start(std::move(server_options), &host, &clients);
  if (!server.ok()) return Fail(server.status().ToString());
  std::printf("bitewise-console: open %s (%s%s)\n", (*server)->url().c_str(),
              tls ? "HTTPS" : "HTTP",
              access ? ", credentials from the access file"
                     : ", loopback only, no credentials");
  std::fflush(stdout);

  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGTERM);
  sigaddset(&signals, SIGINT);
  int signal = 0;
  sigwait(&signals, &signal);
  std::fprintf(stderr, "bitewise-console: stopping\n");
  (*server)->Shutdown();
  return 0;
}
