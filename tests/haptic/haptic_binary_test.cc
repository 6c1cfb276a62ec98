// End-to-end tests of the real bitewise-haptic binary, started as a child
// process: it serves the embedded model with no model flags and answers
// Classify over the wire; a missing or malformed model file, or a bad flag,
// stops the start with a clear message before anything reports SERVING.
#include <grpcpp/client_context.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "absl/time/time.h"
#include "bitewise/v1/haptic.grpc.pb.h"
#include "gmock/gmock.h"
#include "google/protobuf/util/json_util.h"
#include "gtest/gtest.h"
#include "onnx/onnx_pb.h"
#include "services/common/channel.h"
#include "services/haptic/converters.h"
#include "services/haptic/core/haptic_net.h"
#include "tests/common/child_process.h"
#include "tests/haptic/haptic_test_traces.h"

namespace bitewise::haptic {
namespace {

using ::bitewise::testing::DescribeWaitStatus;
using ::bitewise::testing::ReadFile;
using ::testing::HasSubstr;
using ::testing::Not;

constexpr char kBinary[] = BITEWISE_HAPTIC_BINARY;
constexpr char kServiceName[] = "bitewise.v1.HapticService";
// Generous: the machine is small and shared.
constexpr absl::Duration kTimeout = absl::Seconds(60);

// One run of the binary on a port that was free a moment ago, with its
// output in a fresh log file; killed with the test if the test dies.
class HapticProcess {
 public:
  explicit HapticProcess(const std::string& name)
      : log_path_(::testing::TempDir() + "/" + name + ".log") {}

  void Spawn(std::vector<std::string> args) {
    absl::StatusOr<int> port = bitewise::testing::PickFreePort();
    ASSERT_TRUE(port.ok()) << port.status();
    port_ = *port;
    args.insert(args.begin(), kBinary);
    args.push_back(absl::StrCat("--listen=127.0.0.1:", port_));
    // ChildProcess appends; each run starts with an empty log.
    unlink(log_path_.c_str());
    const absl::Status started = child_.Start(args, log_path_);
    ASSERT_TRUE(started.ok()) << started;
  }

  // Waits for the "serving on" line; an error with the log if the process
  // exits first or the timeout passes.
  absl::Status WaitServingLine() {
    return child_.WaitForLog("serving on", kTimeout);
  }

  // Waits for the process to exit; its wait status, or an error on timeout.
  absl::StatusOr<int> WaitExit() { return child_.Wait(kTimeout); }

  absl::StatusOr<int> SignalAndWaitExit(int signal) {
    return child_.SignalAndWait(signal, kTimeout);
  }

  std::string address() const { return absl::StrCat("127.0.0.1:", port_); }
  std::string log() const { return child_.log(); }

 private:
  const std::string log_path_;
  int port_ = 0;
  bitewise::testing::ChildProcess child_;
};

v1::ClassifyRequest SimulatedRequest(HapticClass haptic_class, uint64_t seed) {
  std::mt19937_64 rng(seed);
  v1::ClassifyRequest request;
  TraceToProto(SimulatedTrace(haptic_class, rng), &request);
  return request;
}

void ExpectServesAndStops(HapticProcess& process) {
  const absl::Status serving_line = process.WaitServingLine();
  ASSERT_TRUE(serving_line.ok()) << serving_line;
  auto channel = MakeChannel(process.address(), ChannelOptions());
  ASSERT_TRUE(channel.ok());
  ASSERT_TRUE(WaitForServing(*channel, kServiceName, absl::Seconds(20)).ok());
  auto stub = v1::HapticService::NewStub(*channel);
  const v1::ClassifyRequest request =
      SimulatedRequest(HapticClass::kHardSkin, 8);
  v1::ClassifyResponse response;
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() +
                       std::chrono::seconds(20));
  grpc::Status status = stub->Classify(&context, request, &response);
  ASSERT_TRUE(status.ok()) << status.error_message();
  EXPECT_EQ(response.category(), v1::HAPTIC_CATEGORY_HARD_SKIN);
  EXPECT_THAT(process.log(), HasSubstr(response.model_fingerprint()));
  // The response as grpcurl prints it (docs/haptic.md quotes this).
  std::string json;
  google::protobuf::util::JsonPrintOptions options;
  options.add_whitespace = true;
  ASSERT_TRUE(
      google::protobuf::util::MessageToJsonString(response, &json, options)
          .ok());
  std::cout << "Classify response from the real binary:\n" << json;

  const absl::StatusOr<int> exit_status = process.SignalAndWaitExit(SIGTERM);
  ASSERT_TRUE(exit_status.ok()) << exit_status.status() << "\n"
                                << process.log();
  EXPECT_TRUE(WIFEXITED(*exit_status) && WEXITSTATUS(*exit_status) == 0)
      << DescribeWaitStatus(*exit_status) << "\n"
      << process.log();
}

TEST(HapticBinaryTest, ServesTheEmbeddedModelWithNoModelFlags) {
  HapticProcess process("embedded");
  ASSERT_NO_FATAL_FAILURE(process.Spawn({}));
  ExpectServesAndStops(process);
  EXPECT_THAT(process.log(),
              HasSubstr("familiarity <embedded "
                        "models/hapticnet/hapticnet.onnx.familiarity>, "
                        "threshold 0.05"));
}

// The service asks for the trace's first 50 ms to be free motion: a trace
// whose force rises from 20 ms on is INVALID_ARGUMENT, saying so.
TEST(HapticBinaryTest, AContactInsideTheTareWindowIsRefused) {
  HapticProcess process("early_contact");
  ASSERT_NO_FATAL_FAILURE(process.Spawn({}));
  ASSERT_TRUE(process.WaitServingLine().ok()) << process.log();
  auto channel = MakeChannel(process.address(), ChannelOptions());
  ASSERT_TRUE(channel.ok());
  ASSERT_TRUE(WaitForServing(*channel, kServiceName, absl::Seconds(20)).ok());
  std::vector<TimedWrench> trace;
  for (int i = 0; i < 300; ++i) {
    TimedWrench s;
    s.t_s = i * 1e-3;
    Channel(s.wrench, 2) = std::min(30.0, std::max(0.0, s.t_s - 0.02) * 1000);
    trace.push_back(s);
  }
  v1::ClassifyRequest request;
  TraceToProto(trace, &request);
  v1::ClassifyResponse response;
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() +
                       std::chrono::seconds(20));
  const grpc::Status status = v1::HapticService::NewStub(*channel)->Classify(
      &context, request, &response);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(status.error_message(),
              HasSubstr("must begin with 50 ms of free motion"));
}

TEST(HapticBinaryTest, ServesAModelFileGivenByFlag) {
  HapticProcess process("model_flag");
  ASSERT_NO_FATAL_FAILURE(
      process.Spawn({absl::StrCat("--model=", BITEWISE_HAPTIC_MODEL_FILE)}));
  ExpectServesAndStops(process);
  EXPECT_THAT(process.log(), HasSubstr(BITEWISE_HAPTIC_MODEL_FILE));
}

// The start must fail, non-zero, naming the problem, before the server
// exists: nothing ever reports SERVING.
void ExpectStartFails(HapticProcess& process, const std::string& message) {
  const absl::StatusOr<int> exit_status = process.WaitExit();
  ASSERT_TRUE(exit_status.ok()) << exit_status.status() << "; still running:\n"
                                << process.log();
  EXPECT_TRUE(WIFEXITED(*exit_status)) << DescribeWaitStatus(*exit_status);
  EXPECT_NE(WEXITSTATUS(*exit_status), 0);
  EXPECT_THAT(process.log(), HasSubstr(message));
  EXPECT_THAT(process.log(), Not(HasSubstr("serving on")));
  auto channel = MakeChannel(process.address(), ChannelOptions());
  ASSERT_TRUE(channel.ok());
  EXPECT_FALSE(CheckHealth(*channel, kServiceName, absl::Seconds(1)).ok());
}

TEST(HapticBinaryTest, MalformedModelFileStopsTheStart) {
  const std::string path = ::testing::TempDir() + "/haptic_malformed.onnx";
  std::ofstream(path) << "\x08\x06 definitely not an ONNX graph";
  HapticProcess process("malformed");
  ASSERT_NO_FATAL_FAILURE(process.Spawn({"--model=" + path}));
  ExpectStartFails(process, "cannot load the HapticNet model");
  EXPECT_THAT(process.log(), HasSubstr(path));
}

// The familiarity model beside a --model file: a malformed one stops the
// start naming it; without one the service runs and says it has no score.
TEST(HapticBinaryTest, MalformedFamiliarityFileStopsTheStart) {
  const std::string model = ::testing::TempDir() + "/with_bad_familiarity.onnx";
  std::ofstream(model, std::ios::binary)
      << ReadFile(BITEWISE_HAPTIC_MODEL_FILE);
  std::ofstream(model + ".familiarity") << "bitewise-haptic-familiarity 1\n";
  HapticProcess process("bad_familiarity");
  ASSERT_NO_FATAL_FAILURE(process.Spawn({"--model=" + model}));
  ExpectStartFails(process, "cannot load the familiarity model");
  EXPECT_THAT(process.log(), HasSubstr(model + ".familiarity"));
}

TEST(HapticBinaryTest, AModelWithoutAFamiliarityFileServesWithoutTheScore) {
  const std::string model = ::testing::TempDir() + "/no_familiarity.onnx";
  std::ofstream(model, std::ios::binary)
      << ReadFile(BITEWISE_HAPTIC_MODEL_FILE);
  std::remove((model + ".familiarity").c_str());
  HapticProcess process("no_familiarity");
  ASSERT_NO_FATAL_FAILURE(process.Spawn({"--model=" + model}));
  ExpectServesAndStops(process);
  EXPECT_THAT(process.log(),
              HasSubstr(absl::StrCat("no familiarity score: ", model,
                                     ".familiarity does not exist")));
}

// bitewise-haptic-eval loads the familiarity file as the service does and
// reports it per trace and per row; a malformed one stops it naming the
// file, and --familiarity=none leaves the columns empty.
class HapticEvalTest : public ::testing::Test {
 protected:
  // Runs the evaluator on a few mechanics traces; its exit status.
  int RunEval(const std::string& name, std::vector<std::string> args) {
    args.insert(args.begin(),
                {BITEWISE_HAPTIC_EVAL_BINARY, "--traces_per_class=10",
                 "--stories=mechanics", "--confusion=false"});
    log_ = ::testing::TempDir() + "/" + name + ".log";
    unlink(log_.c_str());
    bitewise::testing::ChildProcess child;
    const absl::Status started = child.Start(args, log_);
    EXPECT_TRUE(started.ok()) << started;
    absl::StatusOr<int> status = child.Wait(kTimeout);
    EXPECT_TRUE(status.ok()) << status.status();
    return status.ok() ? *status : -1;
  }
  std::string log() const { return ReadFile(log_); }
  std::string log_;
};

TEST_F(HapticEvalTest, ReportsTheFamiliarityOfEveryTrace) {
  const std::string csv = ::testing::TempDir() + "/eval_probabilities.csv";
  const int status = RunEval("eval", {"--probabilities_csv=" + csv});
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0)
      << DescribeWaitStatus(status) << "\n"
      << log();
  EXPECT_THAT(log(), HasSubstr("familiarity <embedded "
                               "models/hapticnet/hapticnet.onnx.familiarity>"));
  std::ifstream in(csv);
  std::string line;
  ASSERT_TRUE(std::getline(in, line));
  EXPECT_EQ(line,
            "condition,label,p_hard,p_medium,p_soft,p_hard_skin,familiarity,"
            "distance,d_hard,d_medium,d_soft,d_hard_skin");
  int rows = 0;
  while (std::getline(in, line)) {
    ++rows;
    const std::vector<std::string> fields = absl::StrSplit(line, ',');
    ASSERT_EQ(fields.size(), 12u) << line;
    double familiarity = -1.0, distance = -1.0;
    ASSERT_TRUE(absl::SimpleAtod(fields[6], &familiarity)) << line;
    ASSERT_TRUE(absl::SimpleAtod(fields[7], &distance)) << line;
    EXPECT_GE(familiarity, 0.0);
    EXPECT_LE(familiarity, 1.0);
    EXPECT_GT(distance, 0.0);
    // The distance is the nearest class's (printed to six digits).
    double nearest = std::numeric_limits<double>::infinity();
    for (int c = 8; c < 12; ++c) {
      double d = -1.0;
      ASSERT_TRUE(absl::SimpleAtod(fields[c], &d)) << line;
      EXPECT_GE(d, distance * (1 - 1e-5)) << line;
      nearest = std::min(nearest, d);
    }
    EXPECT_NEAR(nearest, distance, 1e-5 * distance) << line;
  }
  EXPECT_GE(rows, 36);  // 40 traces; a weak soft item may be rejected
}

TEST_F(HapticEvalTest, NoneLeavesTheColumnsEmpty) {
  const std::string csv = ::testing::TempDir() + "/eval_none.csv";
  const int status = RunEval(
      "eval_none", {"--familiarity=none", "--probabilities_csv=" + csv});
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0)
      << DescribeWaitStatus(status) << "\n"
      << log();
  std::ifstream in(csv);
  std::string line;
  ASSERT_TRUE(std::getline(in, line));
  ASSERT_TRUE(std::getline(in, line));
  EXPECT_THAT(line, ::testing::EndsWith(",,"));
  EXPECT_THAT(log(), HasSubstr("| - | - | - |"));
}

TEST_F(HapticEvalTest, AMalformedFamiliarityFileStopsIt) {
  const std::string model = ::testing::TempDir() + "/eval_bad.onnx";
  std::ofstream(model, std::ios::binary)
      << ReadFile(BITEWISE_HAPTIC_MODEL_FILE);
  std::ofstream(model + ".familiarity") << "bitewise-haptic-familiarity 1\n";
  const int status = RunEval("eval_bad", {"--model=" + model});
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 1)
      << DescribeWaitStatus(status);
  EXPECT_THAT(log(), HasSubstr(model + ".familiarity"));
}

// --force_limit_n adds the world's nominal traces cut at that limit as a
// condition of its own; its name holds a comma, so the CSV quotes it and
// keeps twelve columns.
TEST_F(HapticEvalTest, AForceLimitAddsTheCutTracesAsAQuotedCondition) {
  const std::string csv = ::testing::TempDir() + "/eval_limit.csv";
  const int status = RunEval(
      "eval_limit", {"--stories=", "--traces_per_class=5", "--force_limit_n=10",
                     "--familiarity=none", "--probabilities_csv=" + csv});
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0)
      << DescribeWaitStatus(status) << "\n"
      << log();
  EXPECT_THAT(
      log(),
      HasSubstr("| world: nominal, the fork halted at the force limit |"));
  std::ifstream in(csv);
  std::string line;
  int cut = 0;
  while (std::getline(in, line)) {
    if (!absl::StartsWith(line, "\"world: nominal, the fork halted")) continue;
    ++cut;
    const std::string rest = line.substr(line.find("\",") + 2);
    EXPECT_EQ(std::vector<std::string>(absl::StrSplit(rest, ',')).size(), 11u)
        << line;
  }
  EXPECT_EQ(cut, 20);  // 5 per class
}

TEST_F(HapticEvalTest, ANegativeForceLimitIsRefusedNamingTheFlag) {
  const int status = RunEval("eval_negative_limit", {"--force_limit_n=-1"});
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 2)
      << DescribeWaitStatus(status);
  EXPECT_THAT(log(), HasSubstr("--force_limit_n must be 0 (none) or a force"));
}

// A small, quick run of bitewise-haptic-train with extra `flags`,
// writing <TempDir>/<name>.onnx; its exit status (-1 if it never ended) and
// its log in `log`.
int TrainSmall(const std::string& name, const std::vector<std::string>& flags,
               std::string* log) {
  const std::string log_path = ::testing::TempDir() + "/" + name + ".log";
  std::vector<std::string> args = {
      BITEWISE_HAPTIC_TRAIN_BINARY,
      "--stories=world",
      "--traces_per_class=20",
      "--familiarity=false",
      "--max_epochs=1",
      "--held_out_per_class=0",
      "--out=" + ::testing::TempDir() + "/" + name + ".onnx"};
  // Last, so that they win over the defaults above.
  args.insert(args.end(), flags.begin(), flags.end());
  bitewise::testing::ChildProcess child;
  const absl::Status started = child.Start(args, log_path);
  EXPECT_TRUE(started.ok()) << started;
  absl::StatusOr<int> status = child.Wait(kTimeout);
  EXPECT_TRUE(status.ok()) << status.status();
  *log = ReadFile(log_path);
  return status.ok() ? *status : -1;
}

// bitewise-haptic-train's --slow_approach: a factor below 1 (a faster
// approach is not what it means) stops it naming the flag; a valid one is
// said in the trainer's account of its data.
TEST(HapticTrainerBinaryTest, SlowApproachIsCheckedAndReported) {
  std::string log;
  int status = TrainSmall("slow_bad", {"--slow_approach=0.5"}, &log);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 1)
      << DescribeWaitStatus(status) << "\n"
      << log;
  EXPECT_THAT(log, HasSubstr("--slow_approach must be in [1, 10]; got 0.5"));
  status = TrainSmall("slow_good", {"--slow_approach=2"}, &log);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0)
      << DescribeWaitStatus(status) << "\n"
      << log;
  EXPECT_THAT(log, HasSubstr("slow approach up to x2 (--slow_approach)"));
}

// bitewise-haptic-train's --compliant_arm: a share outside [0, 1] stops it
// naming the flag; a valid one is said in the trainer's account of its data.
TEST(HapticTrainerBinaryTest, CompliantArmIsCheckedAndReported) {
  std::string log;
  int status = TrainSmall("arm_bad", {"--compliant_arm=1.5"}, &log);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 1)
      << DescribeWaitStatus(status) << "\n"
      << log;
  EXPECT_THAT(log, HasSubstr("--compliant_arm must be in [0, 1]; got 1.5"));
  status = TrainSmall("arm_good", {"--compliant_arm=0.5"}, &log);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0)
      << DescribeWaitStatus(status) << "\n"
      << log;
  EXPECT_THAT(
      log, HasSubstr("0.5 of them through a compliant arm (--compliant_arm)"));
}

// The trainer's familiarity: a density it does not know stops it before any
// trace is drawn, naming the flag; too few distinct windows of a class (20
// items per class, 14 of them in training) to fit one is said, the network
// is still trained, and no familiarity file is left beside it, not even one
// from an earlier run at that path.
TEST(HapticTrainerBinaryTest, AFamiliarityThatCannotBeFittedLeavesNoFile) {
  std::string log;
  int status =
      TrainSmall("fam_bad", {"--familiarity_gaussians=per_moon"}, &log);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 1)
      << DescribeWaitStatus(status) << "\n"
      << log;
  EXPECT_THAT(log, HasSubstr("--familiarity_gaussians must be class or "
                             "class_and_story; got \"per_moon\""));
  const std::string model = ::testing::TempDir() + "/fam_few.onnx";
  {
    std::ofstream stale(model + ".familiarity");
    stale << "left from an earlier run\n";
  }
  status = TrainSmall("fam_few", {"--familiarity=true"}, &log);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0)
      << DescribeWaitStatus(status) << "\n"
      << log;
  EXPECT_THAT(log, HasSubstr("familiarity: not fitted (familiarity fit: class "
                             "0 has"));
  EXPECT_THAT(log, HasSubstr("need at least 20 distinct"));
  EXPECT_TRUE(std::ifstream(model).good());
  EXPECT_FALSE(std::ifstream(model + ".familiarity").good());
}

// A run that fails after its familiarity was fitted (here: a batch size of
// 0, refused by the trainer) leaves the model at --out and its familiarity
// file as they were, and no staged file. Before, the familiarity file was
// replaced (or removed) before the network was trained, so the old model
// was served with a score that was not its own. A run without a score of
// its own (--familiarity=false) removes the old model's.
TEST(HapticTrainerBinaryTest,
     AFailedRunChangesNothingAndAModelNeverKeepsAnotherOnesScore) {
  std::string log;
  const std::string model = ::testing::TempDir() + "/keep.onnx";
  int status = TrainSmall("keep", {}, &log);
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << log;
  const std::string before = ReadFile(model);
  ASSERT_FALSE(before.empty());
  {
    std::ofstream own(model + ".familiarity");
    own << "the score fitted with keep.onnx\n";
  }
  status = TrainSmall("keep", {"--familiarity=true", "--batch_size=0"}, &log);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 1)
      << DescribeWaitStatus(status) << "\n"
      << log;
  EXPECT_EQ(ReadFile(model), before);
  EXPECT_EQ(ReadFile(model + ".familiarity"),
            "the score fitted with keep.onnx\n");
  EXPECT_FALSE(std::ifstream(model + ".tmp").good());
  EXPECT_FALSE(std::ifstream(model + ".familiarity.tmp").good());

  status = TrainSmall("keep", {"--seed=2"}, &log);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << log;
  EXPECT_NE(ReadFile(model), before);
  EXPECT_FALSE(std::ifstream(model + ".familiarity").good());
  EXPECT_THAT(log, HasSubstr("removed " + model + ".familiarity"));
  EXPECT_FALSE(std::ifstream(model + ".tmp").good());
}

// The trainer's --window_s: out of range stops it naming the flag; a valid
// one is recorded in the model, which then loads with that window.
TEST(HapticTrainerBinaryTest, WindowIsCheckedAndRecordedInTheModel) {
  std::string log;
  int status = TrainSmall("window_bad", {"--window_s=0"}, &log);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 1)
      << DescribeWaitStatus(status) << "\n"
      << log;
  EXPECT_THAT(log, HasSubstr("--window_s must be in (0, 1] s; got 0"));

  status = TrainSmall("window_100ms", {"--window_s=0.1"}, &log);
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0)
      << DescribeWaitStatus(status) << "\n"
      << log;
  absl::StatusOr<std::unique_ptr<HapticNet>> net =
      HapticNet::FromOnnxFile(::testing::TempDir() + "/window_100ms.onnx");
  ASSERT_TRUE(net.ok()) << net.status();
  EXPECT_EQ((*net)->window_s(), std::optional<double>(0.1));
}

// --ensemble_of: two members become one model of the same graph contract,
// which loads with their window and agrees with the trainer's reference;
// a member trained on another window stops it, naming that member.
TEST(HapticTrainerBinaryTest, EnsembleOfMembersOnOneWindow) {
  std::string log;
  for (const char* name : {"member_a", "member_b"}) {
    const int status = TrainSmall(
        name, {absl::StrCat("--seed=", name[7] == 'a' ? 1 : 2)}, &log);
    ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0)
        << DescribeWaitStatus(status) << "\n"
        << log;
  }
  const std::string dir = ::testing::TempDir();
  const std::string members = dir + "/member_a.onnx," + dir + "/member_b.onnx";
  int status = TrainSmall(
      "ensemble", {"--ensemble_of=" + members, "--held_out_per_class=5"}, &log);
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0)
      << DescribeWaitStatus(status) << "\n"
      << log;
  EXPECT_THAT(log, HasSubstr("ensemble of 2 members"));
  // Scored on fresh items of every story, where OpenCV's run of the file
  // is checked against the trainer's reference (the run fails otherwise).
  EXPECT_THAT(log, HasSubstr("story mechanics (fresh items: 5 per class"));
  absl::StatusOr<std::unique_ptr<HapticNet>> net =
      HapticNet::FromOnnxFile(dir + "/ensemble.onnx");
  ASSERT_TRUE(net.ok()) << net.status();
  EXPECT_EQ((*net)->window_s(), std::optional<double>(0.05));

  status = TrainSmall("member_100ms", {"--window_s=0.1"}, &log);
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0)
      << DescribeWaitStatus(status) << "\n"
      << log;
  status = TrainSmall(
      "ensemble_mixed",
      {"--ensemble_of=" + members + "," + dir + "/member_100ms.onnx"}, &log);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 1)
      << DescribeWaitStatus(status) << "\n"
      << log;
  EXPECT_THAT(log, HasSubstr(dir + "/member_100ms.onnx was trained on a 0.1 "
                                   "s window, but --window_s=0.05"));
  EXPECT_FALSE(std::ifstream(dir + "/ensemble_mixed.onnx").good());
}

TEST(HapticBinaryTest, TruncatedModelFileStopsTheStart) {
  const std::string bytes = ReadFile(BITEWISE_HAPTIC_MODEL_FILE);
  ASSERT_GT(bytes.size(), 1000u);
  const std::string path = ::testing::TempDir() + "/truncated.onnx";
  std::ofstream(path, std::ios::binary) << bytes.substr(0, bytes.size() / 2);
  HapticProcess process("truncated");
  ASSERT_NO_FATAL_FAILURE(process.Spawn({"--model=" + path}));
  ExpectStartFails(process, "cannot load the HapticNet model");
}

TEST(HapticBinaryTest, MissingModelFileStopsTheStart) {
  const std::string path = ::testing::TempDir() + "/absent/hapticnet.onnx";
  HapticProcess process("missing");
  ASSERT_NO_FATAL_FAILURE(process.Spawn({"--model=" + path}));
  ExpectStartFails(process, "cannot open HapticNet model file " + path);
}

// A model records the window it was trained on; the service runs it on
// that window, and a --window_s that contradicts it stops the start.
std::string ModelFileWithWindow(const std::string& name,
                                const std::string& window_s) {
  onnx::ModelProto model;
  EXPECT_TRUE(model.ParseFromString(ReadFile(BITEWISE_HAPTIC_MODEL_FILE)));
  for (auto& entry : *model.mutable_metadata_props()) {
    if (entry.key() == kHapticNetWindowKey) entry.set_value(window_s);
  }
  const std::string path = ::testing::TempDir() + "/" + name;
  std::ofstream(path, std::ios::binary) << model.SerializeAsString();
  return path;
}

TEST(HapticBinaryTest, ServesAModelOnItsOwnWindow) {
  // Not TrainsOnAWindow's "window_100ms.onnx": tests run two at a time in
  // one TEST_TMPDIR, and one would read the other's file half-written.
  const std::string path =
      ModelFileWithWindow("served_window_100ms.onnx", "0.1");
  HapticProcess process("own_window");
  ASSERT_NO_FATAL_FAILURE(process.Spawn({"--model=" + path}));
  ExpectServesAndStops(process);
  EXPECT_THAT(process.log(), HasSubstr("window 0.1 s"));
}

TEST(HapticBinaryTest, AWindowFlagThatContradictsTheModelStopsTheStart) {
  const std::string path = ModelFileWithWindow("window_100ms_flag.onnx", "0.1");
  HapticProcess process("window_mismatch");
  ASSERT_NO_FATAL_FAILURE(
      process.Spawn({"--model=" + path, "--window_s=0.05"}));
  ExpectStartFails(process, "was trained on a 0.1 s window");
  EXPECT_THAT(process.log(), HasSubstr(path));
}

// The trainer's --conv_channels: a layer of no channels stops it naming the
// flag; a front end trains, is recorded in the model, and the service loads
// and serves that file like any other.
TEST(HapticTrainerBinaryTest, ConvolutionalFrontEndIsCheckedAndServed) {
  std::string log;
  int status = TrainSmall("conv_bad", {"--conv_channels=16,0"}, &log);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 1)
      << DescribeWaitStatus(status) << "\n"
      << log;
  EXPECT_THAT(log, HasSubstr("--conv_channels: a convolutional layer of 0 "
                             "channels: need >= 1"));
  status = TrainSmall(
      "conv_good",
      {"--conv_channels=4,8", "--traces_per_class=100", "--max_epochs=10"},
      &log);
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0)
      << DescribeWaitStatus(status) << "\n"
      << log;
  // The trainer checks OpenCV's run of the file against its own pass.
  EXPECT_THAT(log, HasSubstr("OpenCV DNN vs reference"));
  const std::string path = ::testing::TempDir() + "/conv_good.onnx";
  onnx::ModelProto model;
  ASSERT_TRUE(model.ParseFromString(ReadFile(path)));
  bool recorded = false;
  for (const auto& entry : model.metadata_props()) {
    recorded |=
        entry.key() == "bitewise.conv_channels" && entry.value() == "4,8";
  }
  EXPECT_TRUE(recorded);
  // Trained enough to call the test trace right, which the check expects.
  HapticProcess process("conv_served");
  ASSERT_NO_FATAL_FAILURE(process.Spawn({"--model=" + path}));
  ExpectServesAndStops(process);
}

TEST(HapticBinaryTest, BadPipelineFlagStopsTheStart) {
  HapticProcess process("bad_flag");
  ASSERT_NO_FATAL_FAILURE(
      process.Spawn({"--contact_release_n=3", "--contact_threshold_n=1"}));
  ExpectStartFails(process, "release_n");
}

}  // namespace
}  // namespace bitewise::haptic
