// The real bitewise-perception binary as a child process: a missing or
// malformed SPANet model stops the start (non-zero exit, message naming the
// file, health never SERVING); with the generated model it serves 2048-long
// SPANet contexts and DetectFood over gRPC, and drains on SIGTERM.
#include <grpcpp/client_context.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"
#include "absl/time/time.h"
#include "bitewise/v1/perception.grpc.pb.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "services/common/channel.h"
#include "tests/common/child_process.h"
#include "tests/perception/test_frames.h"

namespace bitewise::perception {
namespace {

using ::bitewise::testing::ChildProcess;
using ::bitewise::testing::DescribeWaitStatus;
using ::testing::HasSubstr;

constexpr char kBinary[] = BITEWISE_PERCEPTION_BINARY;
constexpr char kService[] = "bitewise.v1.PerceptionService";

// The running test's own log file: ctest runs the cases in parallel, and
// ChildProcess appends, so no two runs may share one.
std::string LogPath() {
  return absl::StrCat(
      ::testing::TempDir(), "/perception_binary_test.",
      ::testing::UnitTest::GetInstance()->current_test_info()->name(), ".log");
}

// Starts the binary with `args` on a fresh log file `log`.
void Spawn(ChildProcess& child, const std::vector<std::string>& args,
           const std::string& log) {
  std::vector<std::string> argv = {kBinary};
  argv.insert(argv.end(), args.begin(), args.end());
  // ChildProcess appends; each run starts with an empty log.
  unlink(log.c_str());
  const absl::Status started = child.Start(argv, log);
  ASSERT_TRUE(started.ok()) << started;
}

void ExpectStartFails(const std::string& model, const std::string& fragment) {
  const absl::StatusOr<int> port = bitewise::testing::PickFreePort();
  ASSERT_TRUE(port.ok()) << port.status();
  const std::string log = LogPath();
  ChildProcess child;
  ASSERT_NO_FATAL_FAILURE(
      Spawn(child,
            {"--featurizer=spanet", absl::StrCat("--spanet_model=", model),
             absl::StrCat("--listen=127.0.0.1:", *port)},
            log));
  const absl::StatusOr<int> status = child.Wait(absl::Seconds(60));
  ASSERT_TRUE(status.ok()) << status.status() << "; still running; log:\n"
                           << child.log();
  ASSERT_TRUE(WIFEXITED(*status)) << DescribeWaitStatus(*status);
  EXPECT_NE(WEXITSTATUS(*status), 0);
  EXPECT_THAT(child.log(), HasSubstr(fragment));
  // Nothing ever answered health on that port.
  auto channel = MakeChannel(absl::StrCat("127.0.0.1:", *port), {});
  ASSERT_TRUE(channel.ok());
  EXPECT_FALSE(CheckHealth(*channel, kService, absl::Milliseconds(300)).ok());
}

TEST(PerceptionBinaryTest, MissingModelStopsTheStart) {
  ExpectStartFails(::testing::TempDir() + "/absent.onnx",
                   "absent.onnx\" does not exist");
}

TEST(PerceptionBinaryTest, MalformedModelStopsTheStart) {
  const std::string path = ::testing::TempDir() + "/perception_malformed.onnx";
  std::ofstream(path) << "\x08\x07garbage that is no ONNX graph";
  ExpectStartFails(path,
                   "perception_malformed.onnx\" is not a loadable ONNX model");
}

TEST(PerceptionBinaryTest, UnknownFeaturizerStopsTheStart) {
  const std::string log = LogPath();
  ChildProcess child;
  ASSERT_NO_FATAL_FAILURE(Spawn(child, {"--featurizer=resnet"}, log));
  const absl::StatusOr<int> status = child.Wait(absl::Seconds(30));
  ASSERT_TRUE(status.ok()) << status.status() << "; log:\n" << child.log();
  ASSERT_TRUE(WIFEXITED(*status)) << DescribeWaitStatus(*status);
  EXPECT_NE(WEXITSTATUS(*status), 0);
  EXPECT_THAT(child.log(), HasSubstr("unknown featurizer \"resnet\""));
}

// A SPANet model given without --featurizer=spanet would be silently
// ignored (the default featurizer would serve): the start stops instead,
// naming the flag that makes it count.
TEST(PerceptionBinaryTest, SpanetModelWithoutTheSpanetFeaturizerStops) {
  const std::string log = LogPath();
  ChildProcess child;
  ASSERT_NO_FATAL_FAILURE(Spawn(
      child, {absl::StrCat("--spanet_model=", BITEWISE_SPANET_MODEL)}, log));
  const absl::StatusOr<int> status = child.Wait(absl::Seconds(30));
  ASSERT_TRUE(status.ok()) << status.status() << "; log:\n" << child.log();
  ASSERT_TRUE(WIFEXITED(*status)) << DescribeWaitStatus(*status);
  EXPECT_NE(WEXITSTATUS(*status), 0);
  EXPECT_THAT(child.log(), HasSubstr("add --featurizer=spanet"));
}

// The child's peak resident memory (VmHWM) in MB, from /proc.
double PeakRssMb(pid_t pid) {
  std::ifstream status(absl::StrCat("/proc/", pid, "/status"));
  std::string line;
  while (std::getline(status, line)) {
    if (line.rfind("VmHWM:", 0) == 0) return std::stod(line.substr(6)) / 1024;
  }
  return -1.0;
}

// A small PNG whose header claims 20000x20000 once made every DetectFood
// take 1.2 GB before it was refused. Now the header is read first: three
// such calls are INVALID_ARGUMENT and the real binary's peak memory does
// not move.
TEST(PerceptionBinaryTest, DecompressionBombIsRefusedWithoutMemory) {
  const absl::StatusOr<int> port = bitewise::testing::PickFreePort();
  ASSERT_TRUE(port.ok()) << port.status();
  const std::string log = LogPath();
  ChildProcess child;
  ASSERT_NO_FATAL_FAILURE(
      Spawn(child, {absl::StrCat("--listen=127.0.0.1:", *port)}, log));
  auto channel = MakeChannel(absl::StrCat("127.0.0.1:", *port), {});
  ASSERT_TRUE(channel.ok());
  ASSERT_TRUE(WaitForServing(*channel, kService, absl::Seconds(60)).ok())
      << child.log();
  auto stub = v1::PerceptionService::NewStub(*channel);
  testing::TestScene scene = testing::RenderTestScene(5, 3, false);
  v1::DetectFoodRequest request;
  *request.mutable_frame() =
      testing::ToProto(scene.rendered, v1::IMAGE_ENCODING_PNG);
  {  // One real call first, so the baseline includes a decode.
    v1::DetectFoodResponse items;
    grpc::ClientContext context;
    context.set_deadline(std::chrono::system_clock::now() +
                         std::chrono::seconds(30));
    ASSERT_TRUE(stub->DetectFood(&context, request, &items).ok());
  }
  const double before_mb = PeakRssMb(child.pid());
  ASSERT_GT(before_mb, 0.0);
  std::string png = request.frame().rgb();
  for (int i = 0; i < 2; ++i) {  // IHDR width and height: 20000
    png[16 + 4 * i] = 0;
    png[17 + 4 * i] = 0;
    png[18 + 4 * i] = static_cast<char>(20000 >> 8);
    png[19 + 4 * i] = static_cast<char>(20000 & 0xFF);
  }
  request.mutable_frame()->set_rgb(png);
  for (int i = 0; i < 3; ++i) {
    v1::DetectFoodResponse items;
    grpc::ClientContext context;
    context.set_deadline(std::chrono::system_clock::now() +
                         std::chrono::seconds(30));
    const grpc::Status status = stub->DetectFood(&context, request, &items);
    EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_THAT(status.error_message(), HasSubstr("20000x20000"));
  }
  EXPECT_LT(PeakRssMb(child.pid()) - before_mb, 20.0)
      << "peak RSS " << before_mb << " MB before the three calls";
  kill(child.pid(), SIGTERM);
  ASSERT_TRUE(child.Wait(absl::Seconds(30)).ok());
}

TEST(PerceptionBinaryTest, SpanetWithoutStatsSaysWhatRidgeNewUsersGet) {
  // The model without its .stats file beside it.
  const std::string model =
      absl::StrCat(::testing::TempDir(), "/spanet_without_stats.onnx");
  unlink(model.c_str());
  ASSERT_EQ(symlink(BITEWISE_SPANET_MODEL, model.c_str()), 0);
  const std::string log = LogPath();
  ChildProcess child;
  ASSERT_NO_FATAL_FAILURE(
      Spawn(child,
            {"--featurizer=spanet", absl::StrCat("--spanet_model=", model),
             "--check_model"},
            log));
  const absl::StatusOr<int> status = child.Wait(absl::Seconds(120));
  ASSERT_TRUE(status.ok()) << status.status();
  EXPECT_TRUE(WIFEXITED(*status) && WEXITSTATUS(*status) == 0) << child.log();
  EXPECT_THAT(child.log(), HasSubstr(absl::StrCat("warning: no ", model,
                                                  ".stats beside the model")));
  EXPECT_THAT(child.log(), HasSubstr("--default_lambda_c"));
  EXPECT_THAT(child.log(), HasSubstr("bitewise-featurizer-stats"));
  unlink(model.c_str());
}

TEST(PerceptionBinaryTest, ServesSpanetFeaturesAndDrainsOnSigterm) {
  const absl::StatusOr<int> port = bitewise::testing::PickFreePort();
  ASSERT_TRUE(port.ok()) << port.status();
  const std::string log = LogPath();
  ChildProcess child;
  ASSERT_NO_FATAL_FAILURE(
      Spawn(child,
            {"--featurizer=spanet",
             absl::StrCat("--spanet_model=", BITEWISE_SPANET_MODEL),
             absl::StrCat("--listen=127.0.0.1:", *port)},
            log));
  auto channel = MakeChannel(absl::StrCat("127.0.0.1:", *port), {});
  ASSERT_TRUE(channel.ok());
  const absl::Status serving =
      WaitForServing(*channel, kService, absl::Seconds(60));
  ASSERT_TRUE(serving.ok()) << serving << "; log:\n" << child.log();
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
  // Its .stats file is beside it: no warning.
  EXPECT_THAT(child.log(), ::testing::Not(HasSubstr("warning: no")));

  const absl::StatusOr<int> status =
      child.SignalAndWait(SIGTERM, absl::Seconds(30));
  ASSERT_TRUE(status.ok()) << status.status() << "; log:\n" << child.log();
  ASSERT_TRUE(WIFEXITED(*status)) << DescribeWaitStatus(*status) << "; log:\n"
                                  << child.log();
  EXPECT_EQ(WEXITSTATUS(*status), 0);
}

}  // namespace
}  // namespace bitewise::perception
