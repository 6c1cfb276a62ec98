// End-to-end: the four real service binaries on free loopback ports and the
// real orchestrator running meals through them, as scripts/meal.sh does.
#include <fcntl.h>
#include <signal.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <regex>
#include <string>
#include <vector>

#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "absl/time/clock.h"
#include "absl/time/time.h"
#include "bitewise/v1/bandit.grpc.pb.h"
#include "bitewise/v1/haptic.grpc.pb.h"
#include "gtest/gtest.h"
#include "services/common/channel.h"
#include "services/common/wrench_proto.h"
#include "services/haptic/training/labelled_traces.h"
#include "tests/common/child_process.h"

namespace bitewise {
namespace {

namespace v1 = bitewise::v1;
using testing::ChildProcess;

constexpr absl::Duration kServingTimeout = absl::Seconds(90);

struct ServiceSpec {
  const char* name;     // log file stem
  const char* service;  // health name
  const char* binary;
};

const ServiceSpec kBandit = {"bandit", "bitewise.v1.BanditService",
                             BITEWISE_BANDIT_BINARY};
const ServiceSpec kPerception = {"perception", "bitewise.v1.PerceptionService",
                                 BITEWISE_PERCEPTION_BINARY};
const ServiceSpec kHaptic = {"haptic", "bitewise.v1.HapticService",
                             BITEWISE_HAPTIC_BINARY};
const ServiceSpec kRobot = {"robot", "bitewise.v1.RobotService",
                            BITEWISE_ROBOT_BINARY};

// One service binary, restartable on the same port.
struct RunningService {
  ServiceSpec spec;
  int port = 0;
  std::vector<std::string> extra_args;
  ChildProcess process;
  std::string address() const { return absl::StrCat("127.0.0.1:", port); }
};

class MealEndToEndTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = ::testing::TempDir() + "/e2e_XXXXXX";
    ASSERT_NE(mkdtemp(dir_.data()), nullptr);
    services_[0].spec = kBandit;
    services_[0].extra_args = {absl::StrCat("--db=", dir_, "/bandit.db"),
                               "--create"};
    services_[1].spec = kPerception;
    services_[2].spec = kHaptic;
    services_[3].spec = kRobot;
    services_[3].extra_args = {"--backend=sim", "--seed=3"};
    for (RunningService& s : services_) {
      ASSERT_TRUE(StartOnFreePort(s).ok()) << s.spec.name;
    }
  }

  void TearDown() override {
    for (RunningService& s : services_) s.process.Kill();
  }

  absl::Status Start(RunningService& s) {
    std::vector<std::string> argv = {s.spec.binary,
                                     absl::StrCat("--listen=", s.address()),
                                     "--drain_timeout_s=5"};
    argv.insert(argv.end(), s.extra_args.begin(), s.extra_args.end());
    absl::Status started =
        s.process.Start(argv, absl::StrCat(dir_, "/", s.spec.name, ".log"));
    if (!started.ok()) return started;
    auto channel = MakeChannel(s.address(), ChannelOptions());
    if (!channel.ok()) return channel.status();
    absl::Status serving =
        WaitForServing(*channel, s.spec.service, kServingTimeout);
    if (!serving.ok()) {
      return absl::Status(
          serving.code(),
          absl::StrCat(serving.message(), "; log:\n", s.process.log()));
    }
    return absl::OkStatus();
  }

  absl::Status StartOnFreePort(RunningService& s) {
    absl::Status last;
    for (int attempt = 0; attempt < 4; ++attempt) {
      absl::StatusOr<int> port = testing::PickFreePort();
      if (!port.ok()) return port.status();
      s.port = *port;
      last = Start(s);
      if (last.ok()) return last;
      s.process.Kill();
    }
    return last;
  }

  std::vector<std::string> OrchestratorArgs(const std::string& user,
                                            const std::string& meal,
                                            int bites) {
    return {BITEWISE_ORCHESTRATOR_BINARY,
            absl::StrCat("--user=", user),
            absl::StrCat("--meal=", meal),
            absl::StrCat("--bites=", bites),
            absl::StrCat("--bandit=", services_[0].address()),
            absl::StrCat("--perception=", services_[1].address()),
            absl::StrCat("--haptic=", services_[2].address()),
            absl::StrCat("--robot=", services_[3].address()),
            absl::StrCat("--journal=", dir_, "/orchestrator.journal"),
            "--retries=1"};
  }

  // Runs the orchestrator to its end; returns its output and wait status.
  std::string RunOrchestrator(const std::vector<std::string>& args,
                              const std::string& log_name, int* status) {
    ChildProcess orchestrator;
    const std::string log = absl::StrCat(dir_, "/", log_name);
    EXPECT_TRUE(orchestrator.Start(args, log).ok());
    absl::StatusOr<int> waited = orchestrator.Wait(absl::Seconds(240));
    EXPECT_TRUE(waited.ok()) << waited.status();
    *status = waited.ok() ? *waited : -1;
    return orchestrator.log();
  }

  std::vector<v1::Event> Events(const std::string& user) {
    auto channel = MakeChannel(services_[0].address(), ChannelOptions());
    auto stub = v1::BanditService::NewStub(*channel);
    v1::ListEventsRequest request;
    request.set_user_id(user);
    request.set_page_size(1000);
    v1::ListEventsResponse response;
    grpc::ClientContext context;
    context.set_deadline(std::chrono::system_clock::now() +
                         std::chrono::seconds(20));
    grpc::Status status = stub->ListEvents(&context, request, &response);
    EXPECT_TRUE(status.ok()) << status.error_message();
    return {response.events().begin(), response.events().end()};
  }

  static int CountLines(const std::string& text, const std::string& needle) {
    int n = 0;
    for (absl::string_view line : absl::StrSplit(text, '\n')) {
      if (absl::StartsWith(line, "bite ") && absl::StrContains(line, needle)) {
        ++n;
      }
    }
    return n;
  }

  std::string dir_;
  std::array<RunningService, 4> services_;
};

TEST_F(MealEndToEndTest, ShortMealIsPersistedAndServicesStopCleanly) {
  int status = 0;
  const std::string out =
      RunOrchestrator(OrchestratorArgs("e2e", "m1", 3), "meal1.log", &status);
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0)
      << testing::DescribeWaitStatus(status) << "\n"
      << out;
  EXPECT_EQ(CountLines(out, "learned"), 3) << out;
  EXPECT_TRUE(absl::StrContains(out, "meal m1: 3 attempts")) << out;

  // Every bite is a completed event with the context and haptic class.
  const std::vector<v1::Event> events = Events("e2e");
  ASSERT_EQ(events.size(), 3u);
  for (const v1::Event& e : events) {
    EXPECT_TRUE(e.completed());
    EXPECT_EQ(e.meal_id(), "m1");
    EXPECT_GT(e.context_size(), 0);
    EXPECT_EQ(e.posthoc_size(), 4);
    EXPECT_TRUE(e.loss() == 0.0 || e.loss() == 1.0);
  }

  // A second meal for the same user starts from the first meal's model.
  const std::string out2 =
      RunOrchestrator(OrchestratorArgs("e2e", "m2", 2), "meal2.log", &status);
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << out2;
  EXPECT_TRUE(absl::StrContains(out2, "continues from model version 3"))
      << out2;
  EXPECT_EQ(Events("e2e").size(), 5u);

  // Every service is still healthy, then drains and exits 0 on SIGTERM.
  for (RunningService& s : services_) {
    auto channel = MakeChannel(s.address(), ChannelOptions());
    EXPECT_TRUE(
        WaitForServing(*channel, s.spec.service, absl::Seconds(10)).ok())
        << s.spec.name;
  }
  for (RunningService& s : services_) {
    absl::StatusOr<int> exited =
        s.process.SignalAndWait(SIGTERM, absl::Seconds(30));
    ASSERT_TRUE(exited.ok()) << s.spec.name << ": " << exited.status();
    EXPECT_TRUE(WIFEXITED(*exited) && WEXITSTATUS(*exited) == 0)
        << s.spec.name << ": " << testing::DescribeWaitStatus(*exited) << "\n"
        << s.process.log();
  }
}

TEST_F(MealEndToEndTest, KilledBanditMidMealLosesNoAcknowledgedUpdate) {
  ChildProcess orchestrator;
  ASSERT_TRUE(orchestrator
                  .Start(OrchestratorArgs("crash", "m1", 8),
                         absl::StrCat(dir_, "/crash1.log"))
                  .ok());
  // Let two bites finish, then kill the BanditService while the third is
  // being acquired, so its Update has nowhere to go.
  ASSERT_TRUE(orchestrator.WaitForLog("bite  2", absl::Seconds(180)).ok())
      << orchestrator.log();
  absl::SleepFor(absl::Milliseconds(1500));
  services_[0].process.Kill();
  absl::StatusOr<int> ended = orchestrator.Wait(absl::Seconds(120));
  ASSERT_TRUE(ended.ok()) << ended.status();
  const std::string out = orchestrator.log();
  // The orchestrator says what failed and stops the meal.
  EXPECT_TRUE(WIFEXITED(*ended) && WEXITSTATUS(*ended) == 1) << out;
  EXPECT_TRUE(absl::StrContains(out, "stopping the meal: BanditService."))
      << out;
  EXPECT_TRUE(absl::StrContains(out, "UNAVAILABLE")) << out;
  const int learned = CountLines(out, "learned");
  const int journaled = CountLines(out, "journaled");
  EXPECT_GE(learned, 2) << out;

  // Restart on the same database and port; the next run delivers the
  // journal first and the meal goes on.
  ASSERT_TRUE(Start(services_[0]).ok());
  int status = 0;
  const std::string out2 = RunOrchestrator(OrchestratorArgs("crash", "m1", 2),
                                           "crash2.log", &status);
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << out2;
  if (journaled > 0) {
    EXPECT_TRUE(absl::StrContains(
        out2, absl::StrCat("journal: delivered ", journaled, " update(s)")))
        << out2;
  }
  const int learned2 = CountLines(out2, "learned");
  EXPECT_EQ(learned2, 2) << out2;

  int completed = 0;
  for (const v1::Event& e : Events("crash")) completed += e.completed();
  EXPECT_EQ(completed, learned + journaled + learned2)
      << "first run:\n"
      << out << "\nsecond run:\n"
      << out2;
}

// The store's disk fills while the operator judges a bite: the update is
// refused (RESOURCE_EXHAUSTED naming the cause), kept in the orchestrator's
// journal, the BanditService's health drops at once and returns once the
// disk takes writes again, with no restart, and the next run delivers the
// journal before its first bite. Nothing is lost. The full disk is the
// write-fault injector's (tests/common) beneath the bandit's real store.
TEST_F(MealEndToEndTest, AFullDiskMidMealIsJournaledAndDeliveredAfterward) {
  RunningService& bandit = services_[0];
  const std::string control = dir_ + "/fault";
  bandit.process.Kill();
  bandit.process.set_env(
      {absl::StrCat("LD_PRELOAD=", BITEWISE_WRITE_FAULT_INJECTOR),
       absl::StrCat("BITEWISE_WRITE_FAULT_FILE=", control),
       // As the kernel names the open file (TempDir() may end in '/').
       absl::StrCat("BITEWISE_WRITE_FAULT_PREFIX=",
                    std::filesystem::canonical(dir_).string(), "/bandit.db"),
       "ASAN_OPTIONS=verify_asan_link_order=0"});
  ASSERT_TRUE(Start(bandit).ok());
  auto channel = MakeChannel(bandit.address(), ChannelOptions());
  ASSERT_TRUE(channel.ok());

  // The operator answers at the terminal (a FIFO here).
  const std::string answers = dir_ + "/answers";
  ASSERT_EQ(mkfifo(answers.c_str(), 0600), 0);
  const int answer_fd = open(answers.c_str(), O_RDWR | O_CLOEXEC);
  ASSERT_GE(answer_fd, 0);
  auto answer = [&](const char* text) {
    ASSERT_EQ(write(answer_fd, text, 2), 2);
  };
  std::vector<std::string> args = OrchestratorArgs("full", "m1", 2);
  args.push_back("--confirm=operator");
  ChildProcess orchestrator;
  orchestrator.set_stdin(answers);
  ASSERT_TRUE(orchestrator.Start(args, dir_ + "/full1.log").ok());
  ASSERT_TRUE(orchestrator.WaitForLog("[y/n]", absl::Seconds(180)).ok())
      << orchestrator.log();
  answer("y\n");
  ASSERT_TRUE(orchestrator.WaitForLog("bite  2", absl::Seconds(180)).ok())
      << orchestrator.log();
  // The second question: bite 2's line, then its question.
  for (int i = 0; i < 600; ++i) {
    const std::string log = orchestrator.log();
    if (log.find("[y/n]", log.find("bite  2")) != std::string::npos) break;
    absl::SleepFor(absl::Milliseconds(100));
  }
  std::ofstream(control) << "ENOSPC";
  answer("n\n");
  absl::StatusOr<int> ended = orchestrator.Wait(absl::Seconds(120));
  close(answer_fd);
  ASSERT_TRUE(ended.ok()) << ended.status();
  const std::string out = orchestrator.log();
  EXPECT_TRUE(WIFEXITED(*ended) && WEXITSTATUS(*ended) == 1) << out;
  EXPECT_TRUE(absl::StrContains(out, "answered no: journaled")) << out;
  EXPECT_TRUE(absl::StrContains(out, "the disk is full")) << out;

  // Health is NOT_SERVING while the disk is full (how soon it drops:
  // tests/bandit/crash/store_faults_test.cc).
  absl::StatusOr<ServingStatus> health =
      CheckHealth(*channel, bandit.spec.service, absl::Seconds(5));
  ASSERT_TRUE(health.ok()) << health.status();
  EXPECT_EQ(*health, ServingStatus::kNotServing) << bandit.process.log();

  // Space again: SERVING within a second, no restart.
  std::filesystem::remove(control);
  const absl::Time freed = absl::Now();
  ASSERT_TRUE(
      WaitForServing(*channel, bandit.spec.service, absl::Seconds(10)).ok());
  EXPECT_LT(absl::Now() - freed, absl::Seconds(1));
  EXPECT_TRUE(bandit.process.running());

  // The next run delivers the journaled answer, then bites.
  int status = 0;
  const std::string out2 =
      RunOrchestrator(OrchestratorArgs("full", "m1", 1), "full2.log", &status);
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << out2;
  EXPECT_TRUE(absl::StrContains(out2, "journal: delivered 1 update(s)"))
      << out2;
  const std::vector<v1::Event> events = Events("full");
  ASSERT_EQ(events.size(), 3u);
  for (const v1::Event& e : events) EXPECT_TRUE(e.completed());
  EXPECT_EQ(events[1].loss(), 1.0);  // the operator's "no"
}

// --confirm=operator with nobody at the terminal (stdin at its end, as
// from a launcher): the meal stops at the first question and nothing is
// learned. It went on, learning a "no" for every bite.
TEST_F(MealEndToEndTest, NoOperatorAtTheTerminalStopsTheMealUnlearned) {
  std::vector<std::string> args = OrchestratorArgs("alone", "m1", 3);
  args.push_back("--confirm=operator");
  int status = 0;
  const std::string out = RunOrchestrator(args, "alone.log", &status);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 1)
      << testing::DescribeWaitStatus(status) << "\n"
      << out;
  EXPECT_TRUE(absl::StrContains(
      out, "stopping the meal: no answer from the operator (end of input)"))
      << out;
  const std::vector<v1::Event> events = Events("alone");
  ASSERT_EQ(events.size(), 1u) << out;
  EXPECT_FALSE(events[0].completed());
}

// Ctrl-C mid-meal: the arm is told to stop, the meal ends after the call
// in flight with its summary, and the exit code is 128 + SIGINT.
TEST_F(MealEndToEndTest, CtrlCStopsTheArmAndEndsTheMeal) {
  ChildProcess orchestrator;
  ASSERT_TRUE(orchestrator
                  .Start(OrchestratorArgs("interrupted", "m1", 20),
                         dir_ + "/interrupted.log")
                  .ok());
  ASSERT_TRUE(orchestrator.WaitForLog("bite  1", absl::Seconds(180)).ok())
      << orchestrator.log();
  absl::StatusOr<int> ended =
      orchestrator.SignalAndWait(SIGINT, absl::Seconds(120));
  ASSERT_TRUE(ended.ok()) << ended.status();
  const std::string out = orchestrator.log();
  EXPECT_TRUE(WIFEXITED(*ended) && WEXITSTATUS(*ended) == 130)
      << testing::DescribeWaitStatus(*ended) << "\n"
      << out;
  EXPECT_TRUE(absl::StrContains(out, "SIGINT: stopping the arm")) << out;
  EXPECT_TRUE(absl::StrContains(out, "stopping the meal: interrupted (SIGINT)"))
      << out;
  EXPECT_TRUE(absl::StrContains(out, "meal m1: ")) << out;  // the summary
  // Bite 1, and at most the look or bite the signal met.
  EXPECT_LE(Events("interrupted").size(), 2u) << out;
  EXPECT_TRUE(absl::StrContains(out, "bitewise-orchestrator: SIGINT")) << out;
}

// The lab's retraining path, end to end: meals record their traces, the
// trainer learns from the recording (with a story), the HapticService
// serves the new model, and it answers for a recorded trace.
TEST_F(MealEndToEndTest, RecordedMealsRetrainHapticNetAndTheServiceServesIt) {
  const std::string recording = absl::StrCat(dir_, "/recording");
  int status = 0;
  std::vector<std::string> args = OrchestratorArgs("lab", "m1", 6);
  args.push_back(absl::StrCat("--record_traces=", recording));
  std::string out = RunOrchestrator(args, "rec1.log", &status);
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << out;
  EXPECT_TRUE(absl::StrContains(out, "recorded 6 trace(s) in")) << out;
  // A second meal continues the same recording.
  args = OrchestratorArgs("lab", "m2", 4);
  args.push_back(absl::StrCat("--record_traces=", recording));
  out = RunOrchestrator(args, "rec2.log", &status);
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << out;

  // Ten bites: ids 0-9, each labelled with the simulated food's class,
  // HapticNet's answer and the familiarity of its trace, the trace readable
  // by the trainer's reader.
  absl::StatusOr<std::vector<haptic::RecordedTrace>> traces =
      haptic::ReadRecordedTraces(absl::StrCat(recording, "/traces.csv"));
  ASSERT_TRUE(traces.ok()) << traces.status();
  ASSERT_EQ(traces->size(), 10u);
  for (size_t i = 0; i < traces->size(); ++i) {
    EXPECT_EQ((*traces)[i].id, absl::StrCat(i));
    EXPECT_TRUE((*traces)[i].label.has_value());
    EXPECT_GT((*traces)[i].samples.size(), 100u);
  }
  std::ifstream bites_file(absl::StrCat(recording, "/bites.csv"));
  std::vector<std::string> bites;
  for (std::string line; std::getline(bites_file, line);) bites.push_back(line);
  ASSERT_EQ(bites.size(), 11u);
  EXPECT_TRUE(absl::StartsWith(bites[0], "trace,time_utc,user,meal,event_id"));
  EXPECT_TRUE(absl::EndsWith(
      bites[0], ",p_hard_skin,familiarity,unfamiliar,force_limit_reached"))
      << bites[0];
  const std::vector<std::string> row = absl::StrSplit(bites[7], ',');
  ASSERT_EQ(row.size(), 17u) << bites[7];
  EXPECT_EQ(row[0], "6");
  EXPECT_EQ(row[2], "lab");
  EXPECT_EQ(row[3], "m2");
  EXPECT_NE(row[9], "none");  // HapticNet answered
  // The shipped model has a familiarity model: every bite has its score
  // (in [0, 1]) and the verdict, unfamiliar exactly below the threshold.
  for (size_t i = 1; i < bites.size(); ++i) {
    const std::vector<std::string> fields = absl::StrSplit(bites[i], ',');
    ASSERT_EQ(fields.size(), 17u) << bites[i];
    EXPECT_TRUE(fields[16] == "0" || fields[16] == "1") << bites[i];
    double familiarity = -1.0;
    EXPECT_TRUE(absl::SimpleAtod(fields[14], &familiarity)) << bites[i];
    EXPECT_GE(familiarity, 0.0) << bites[i];
    EXPECT_LE(familiarity, 1.0) << bites[i];
    EXPECT_EQ(fields[15], familiarity < 0.05 ? "1" : "0") << bites[i];
  }

  // Retrain on the recording mixed with one story; the trainer reports the
  // held-out recorded traces and every story it did not train on.
  ChildProcess trainer;
  const std::string model = absl::StrCat(dir_, "/retrained.onnx");
  ASSERT_TRUE(
      trainer
          .Start({BITEWISE_HAPTIC_TRAIN_BINARY,
                  absl::StrCat("--traces=", recording, "/traces.csv"),
                  absl::StrCat("--labels=", recording, "/bites.csv"),
                  "--traces_repeat=5", "--stories=world",
                  "--traces_per_class=60", "--max_epochs=4",
                  "--held_out_per_class=10", absl::StrCat("--out=", model)},
                 absl::StrCat(dir_, "/train.log"))
          .ok());
  absl::StatusOr<int> trained = trainer.Wait(absl::Seconds(240));
  ASSERT_TRUE(trained.ok()) << trained.status();
  const std::string train_log = trainer.log();
  ASSERT_TRUE(WIFEXITED(*trained) && WEXITSTATUS(*trained) == 0) << train_log;
  std::printf("%s", train_log.c_str());  // the new model's numbers
  EXPECT_TRUE(absl::StrContains(train_log, "recorded traces: 10 labelled"))
      << train_log;
  EXPECT_TRUE(absl::StrContains(train_log, "held-out recorded traces ("))
      << train_log;
  EXPECT_TRUE(absl::StrContains(train_log, "held-out story piecewise"))
      << train_log;
  EXPECT_TRUE(absl::StrContains(train_log, "held-out story mechanics"))
      << train_log;

  // The HapticService restarted on the new model serves it.
  RunningService& haptic_service = services_[2];
  haptic_service.process.Kill();
  haptic_service.extra_args = {absl::StrCat("--model=", model)};
  ASSERT_TRUE(Start(haptic_service).ok());
  auto channel = MakeChannel(haptic_service.address(), ChannelOptions());
  ASSERT_TRUE(channel.ok());
  auto stub = v1::HapticService::NewStub(*channel);
  v1::ClassifyRequest request;
  AppendTraceToProto((*traces)[0].samples, request.mutable_samples());
  v1::ClassifyResponse response;
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() +
                       std::chrono::seconds(20));
  const grpc::Status classified = stub->Classify(&context, request, &response);
  ASSERT_TRUE(classified.ok()) << classified.error_message();
  EXPECT_EQ(response.probabilities_size(), 4);
  const std::regex fingerprint("bytes, (fnv1a64:[0-9a-f]+)\\)");
  std::smatch match;
  ASSERT_TRUE(std::regex_search(train_log, match, fingerprint)) << train_log;
  EXPECT_EQ(response.model_fingerprint(), match[1].str());
}

}  // namespace
}  // namespace bitewise
