// End-to-end tests of the real bitewise-haptic binary, started as a child
// process: it serves the embedded model with no model flags and answers
// Classify over the wire; a missing or malformed model file, or a bad flag,
// stops the start with a clear message before anything reports SERVING.
#include <arpa/inet.h>
#include <fcntl.h>
#include <grpcpp/client_context.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <fstream>
#include <iostream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "absl/time/time.h"
#include "bitewise/v1/haptic.grpc.pb.h"
#include "gmock/gmock.h"
#include "google/protobuf/util/json_util.h"
#include "gtest/gtest.h"
#include "services/common/channel.h"
#include "tests/haptic/haptic_test_traces.h"

namespace bitewise::haptic {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;

constexpr char kBinary[] = BITEWISE_HAPTIC_BINARY;
constexpr char kServiceName[] = "bitewise.v1.HapticService";
// Generous: the machine is small and shared.
constexpr absl::Duration kTimeout = absl::Seconds(60);

std::string ReadFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream contents;
  contents << in.rdbuf();
  return contents.str();
}

// A port that was free a moment ago (bound to 127.0.0.1:0 and released).
int PickFreePort() {
  const int fd = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t len = sizeof(addr);
  bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr));
  getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len);
  close(fd);
  return ntohs(addr.sin_port);
}

// One run of the binary with its output in a log file; killed with the
// test if the test dies.
class HapticProcess {
 public:
  explicit HapticProcess(const std::string& name)
      : log_path_(::testing::TempDir() + "/" + name + ".log") {}
  ~HapticProcess() {
    if (pid_ > 0) {
      kill(pid_, SIGKILL);
      waitpid(pid_, nullptr, 0);
    }
  }

  void Spawn(std::vector<std::string> args) {
    port_ = PickFreePort();
    args.insert(args.begin(), kBinary);
    args.push_back(absl::StrCat("--listen=127.0.0.1:", port_));
    const pid_t parent = getpid();
    pid_ = fork();
    ASSERT_GE(pid_, 0) << std::strerror(errno);
    if (pid_ == 0) {
      prctl(PR_SET_PDEATHSIG, SIGKILL);
      if (getppid() != parent) _exit(127);
      const int fd =
          open(log_path_.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      dup2(fd, STDOUT_FILENO);
      dup2(fd, STDERR_FILENO);
      std::vector<char*> argv;
      for (std::string& a : args) argv.push_back(a.data());
      argv.push_back(nullptr);
      execv(kBinary, argv.data());
      _exit(127);
    }
  }

  // Waits for the "serving on" line; false (with the log) if the process
  // exits first or the timeout passes.
  bool WaitServingLine() {
    const absl::Time deadline = absl::Now() + kTimeout;
    while (absl::Now() < deadline) {
      if (absl::StrContains(log(), "serving on")) return true;
      int status = 0;
      if (waitpid(pid_, &status, WNOHANG) == pid_) {
        pid_ = -1;
        exit_status_ = status;
        return false;
      }
      absl::SleepFor(absl::Milliseconds(10));
    }
    return false;
  }

  // Waits for the process to exit; its wait status, or -1 on timeout.
  int WaitExit() {
    const absl::Time deadline = absl::Now() + kTimeout;
    while (pid_ > 0 && absl::Now() < deadline) {
      int status = 0;
      if (waitpid(pid_, &status, WNOHANG) == pid_) {
        pid_ = -1;
        exit_status_ = status;
        break;
      }
      absl::SleepFor(absl::Milliseconds(10));
    }
    return pid_ > 0 ? -1 : exit_status_;
  }

  void Signal(int signal) { kill(pid_, signal); }
  std::string address() const { return absl::StrCat("127.0.0.1:", port_); }
  std::string log() const { return ReadFile(log_path_); }

 private:
  const std::string log_path_;
  pid_t pid_ = -1;
  int port_ = 0;
  int exit_status_ = 0;
};

v1::ClassifyRequest SimulatedRequest(HapticClass haptic_class, uint64_t seed) {
  std::mt19937_64 rng(seed);
  v1::ClassifyRequest request;
  for (const WrenchSample& s : SimulatedTrace(haptic_class, rng)) {
    v1::WrenchSample* out = request.add_samples();
    out->set_t_s(s.t_s);
    out->set_fx_n(s.values[0]);
    out->set_fy_n(s.values[1]);
    out->set_fz_n(s.values[2]);
    out->set_tx_nm(s.values[3]);
    out->set_ty_nm(s.values[4]);
    out->set_tz_nm(s.values[5]);
  }
  return request;
}

void ExpectServesAndStops(HapticProcess& process) {
  ASSERT_TRUE(process.WaitServingLine()) << process.log();
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

  process.Signal(SIGTERM);
  const int exit_status = process.WaitExit();
  EXPECT_TRUE(WIFEXITED(exit_status) && WEXITSTATUS(exit_status) == 0)
      << "wait status " << exit_status << "\n"
      << process.log();
}

TEST(HapticBinaryTest, ServesTheEmbeddedModelWithNoModelFlags) {
  HapticProcess process("embedded");
  process.Spawn({});
  ExpectServesAndStops(process);
}

TEST(HapticBinaryTest, ServesAModelFileGivenByFlag) {
  HapticProcess process("model_flag");
  process.Spawn({absl::StrCat("--model=", BITEWISE_HAPTIC_MODEL_FILE)});
  ExpectServesAndStops(process);
  EXPECT_THAT(process.log(), HasSubstr(BITEWISE_HAPTIC_MODEL_FILE));
}

// The start must fail, non-zero, naming the problem, before the server
// exists: nothing ever reports SERVING.
void ExpectStartFails(HapticProcess& process, const std::string& message) {
  const int exit_status = process.WaitExit();
  ASSERT_NE(exit_status, -1) << "still running:\n" << process.log();
  EXPECT_TRUE(WIFEXITED(exit_status));
  EXPECT_NE(WEXITSTATUS(exit_status), 0);
  EXPECT_THAT(process.log(), HasSubstr(message));
  EXPECT_THAT(process.log(), Not(HasSubstr("serving on")));
  auto channel = MakeChannel(process.address(), ChannelOptions());
  ASSERT_TRUE(channel.ok());
  EXPECT_FALSE(CheckHealth(*channel, kServiceName, absl::Seconds(1)).ok());
}

TEST(HapticBinaryTest, MalformedModelFileStopsTheStart) {
  const std::string path = ::testing::TempDir() + "/malformed.onnx";
  std::ofstream(path) << "\x08\x06 definitely not an ONNX graph";
  HapticProcess process("malformed");
  process.Spawn({"--model=" + path});
  ExpectStartFails(process, "cannot load the HapticNet model");
  EXPECT_THAT(process.log(), HasSubstr(path));
}

TEST(HapticBinaryTest, TruncatedModelFileStopsTheStart) {
  const std::string bytes = ReadFile(BITEWISE_HAPTIC_MODEL_FILE);
  ASSERT_GT(bytes.size(), 1000u);
  const std::string path = ::testing::TempDir() + "/truncated.onnx";
  std::ofstream(path, std::ios::binary) << bytes.substr(0, bytes.size() / 2);
  HapticProcess process("truncated");
  process.Spawn({"--model=" + path});
  ExpectStartFails(process, "cannot load the HapticNet model");
}

TEST(HapticBinaryTest, MissingModelFileStopsTheStart) {
  const std::string path = ::testing::TempDir() + "/absent/hapticnet.onnx";
  HapticProcess process("missing");
  process.Spawn({"--model=" + path});
  ExpectStartFails(process, "cannot open HapticNet model file " + path);
}

TEST(HapticBinaryTest, BadPipelineFlagStopsTheStart) {
  HapticProcess process("bad_flag");
  process.Spawn({"--contact_release_n=3", "--contact_threshold_n=1"});
  ExpectStartFails(process, "release_n");
}

}  // namespace
}  // namespace bitewise::haptic
