// The real bitewise-perception binary as a child process: a missing or
// malformed SPANet model stops the start (non-zero exit, message naming the
// file, health never SERVING); with the generated model it serves 2048-long
// SPANet contexts and DetectFood over gRPC, and drains on SIGTERM.
#include <arpa/inet.h>
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
#include <sstream>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "absl/time/time.h"
#include "bitewise/v1/perception.grpc.pb.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "services/common/channel.h"
#include "tests/perception/test_frames.h"

namespace bitewise::perception {
namespace {

using ::testing::HasSubstr;

constexpr char kBinary[] = BITEWISE_PERCEPTION_BINARY;
constexpr char kService[] = "bitewise.v1.PerceptionService";

std::string ReadFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream contents;
  contents << in.rdbuf();
  return contents.str();
}

int FreePort() {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t len = sizeof(addr);
  bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr));
  getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len);
  close(fd);
  return ntohs(addr.sin_port);
}

// Runs the binary with `args`, output to `log`; returns its pid.
pid_t Spawn(const std::vector<std::string>& args, const std::string& log) {
  const pid_t pid = fork();
  if (pid == 0) {
    prctl(PR_SET_PDEATHSIG, SIGKILL);
    FILE* out = std::fopen(log.c_str(), "w");
    dup2(fileno(out), STDOUT_FILENO);
    dup2(fileno(out), STDERR_FILENO);
    std::vector<char*> argv{const_cast<char*>(kBinary)};
    for (const std::string& a : args)
      argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    execv(kBinary, argv.data());
    _exit(127);
  }
  return pid;
}

// Waits up to `timeout` for `pid` to exit; its wait status or -1.
int WaitExit(pid_t pid, absl::Duration timeout) {
  const absl::Time deadline = absl::Now() + timeout;
  while (absl::Now() < deadline) {
    int status = 0;
    if (waitpid(pid, &status, WNOHANG) == pid) return status;
    absl::SleepFor(absl::Milliseconds(10));
  }
  kill(pid, SIGKILL);
  waitpid(pid, nullptr, 0);
  return -1;
}

void ExpectStartFails(const std::string& model, const std::string& fragment) {
  const int port = FreePort();
  const std::string log = ::testing::TempDir() + "/perception_fail.log";
  const pid_t pid =
      Spawn({"--featurizer=spanet", absl::StrCat("--spanet_model=", model),
             absl::StrCat("--listen=127.0.0.1:", port)},
            log);
  const int status = WaitExit(pid, absl::Seconds(60));
  ASSERT_NE(status, -1) << "still running; log:\n" << ReadFile(log);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_NE(WEXITSTATUS(status), 0);
  EXPECT_THAT(ReadFile(log), HasSubstr(fragment));
  // Nothing ever answered health on that port.
  auto channel = MakeChannel(absl::StrCat("127.0.0.1:", port), {});
  ASSERT_TRUE(channel.ok());
  EXPECT_FALSE(CheckHealth(*channel, kService, absl::Milliseconds(300)).ok());
}

TEST(PerceptionBinaryTest, MissingModelStopsTheStart) {
  ExpectStartFails(::testing::TempDir() + "/absent.onnx",
                   "absent.onnx\" does not exist");
}

TEST(PerceptionBinaryTest, MalformedModelStopsTheStart) {
  const std::string path = ::testing::TempDir() + "/malformed.onnx";
  std::ofstream(path) << "\x08\x07garbage that is no ONNX graph";
  ExpectStartFails(path, "malformed.onnx\" is not a loadable ONNX model");
}

TEST(PerceptionBinaryTest, UnknownFeaturizerStopsTheStart) {
  const std::string log = ::testing::TempDir() + "/perception_flag.log";
  const pid_t pid = Spawn({"--featurizer=resnet"}, log);
  const int status = WaitExit(pid, absl::Seconds(30));
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_NE(WEXITSTATUS(status), 0);
  EXPECT_THAT(ReadFile(log), HasSubstr("unknown featurizer \"resnet\""));
}

TEST(PerceptionBinaryTest, ServesSpanetFeaturesAndDrainsOnSigterm) {
  const int port = FreePort();
  const std::string log = ::testing::TempDir() + "/perception_ok.log";
  const pid_t pid =
      Spawn({"--featurizer=spanet",
             absl::StrCat("--spanet_model=", BITEWISE_SPANET_MODEL),
             absl::StrCat("--listen=127.0.0.1:", port)},
            log);
  auto channel = MakeChannel(absl::StrCat("127.0.0.1:", port), {});
  ASSERT_TRUE(channel.ok());
  const absl::Status serving =
      WaitForServing(*channel, kService, absl::Seconds(60));
  ASSERT_TRUE(serving.ok()) << serving << "; log:\n" << ReadFile(log);
  auto stub = v1::PerceptionService::NewStub(*channel);

  testing::TestScene scene = testing::RenderTestScene(77, 4, true);
  v1::DetectFoodRequest detect;
  *detect.mutable_frame() =
      testing::ToProto(scene.rendered, v1::IMAGE_ENCODING_PNG);
  v1::DetectFoodResponse items;
  grpc::ClientContext c1;
  c1.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(30));
  ASSERT_TRUE(stub->DetectFood(&c1, detect, &items).ok());
  ASSERT_EQ(items.items_size(), static_cast<int>(scene.plate.items.size()));

  v1::FeaturizeRequest request;
  *request.mutable_frame() = detect.frame();
  *request.mutable_bbox() = items.items(0).bbox();
  v1::FeaturizeResponse features;
  grpc::ClientContext c2;
  c2.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(30));
  ASSERT_TRUE(stub->Featurize(&c2, request, &features).ok());
  EXPECT_EQ(features.context_size(), 2048);
  EXPECT_EQ(features.featurizer(), "spanet");

  ASSERT_EQ(kill(pid, SIGTERM), 0);
  const int status = WaitExit(pid, absl::Seconds(30));
  ASSERT_TRUE(WIFEXITED(status)) << ReadFile(log);
  EXPECT_EQ(WEXITSTATUS(status), 0);
}

}  // namespace
}  // namespace bitewise::perception
