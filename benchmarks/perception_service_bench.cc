// perception_service_bench: DetectFood as the orchestrator sees it
// (docs/benchmarks.md, "DetectFood through the service"). It renders
// --plates blind plates (experiments/blind_plates.h, the larger plates in
// the image), then, --rounds times, starts the real bitewise-perception
// binary once with --retain_freed_memory=false and once with true, and
// sends every plate's frame (raw RGB8 and depth, 1.5 MB) in turn over one
// connection. Per run it prints the first call after SERVING and the round
// trip's median, 95th percentile and maximum over the plates.
//
//   build/benchmarks/perception_service_bench
//   build/benchmarks/perception_service_bench --plates=400 --rounds=3
#include <grpcpp/create_channel.h>
#include <grpcpp/security/credentials.h>
#include <grpcpp/support/channel_arguments.h>
#include <stdlib.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "absl/flags/flag.h"
#include "absl/flags/parse.h"
#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "absl/time/time.h"
#include "bitewise/v1/perception.grpc.pb.h"
#include "experiments/blind_plates.h"
#include "services/camera/frame_proto.h"
#include "services/sim/scene.h"
#include "tests/common/child_process.h"

ABSL_FLAG(std::string, server, BITEWISE_PERCEPTION_BINARY,
          "The bitewise-perception binary to start.");
ABSL_FLAG(int, plates, 200, "Blind plates, each sent once per run.");
ABSL_FLAG(int, rounds, 2,
          "Runs of each setting, alternating (false, true, false, ...).");
ABSL_FLAG(uint64_t, seed, 7401, "Seed of the blind plates.");

namespace {

namespace v1 = bitewise::v1;
using Clock = std::chrono::steady_clock;

std::vector<v1::DetectFoodRequest> RenderRequests(int plates, uint64_t seed) {
  std::mt19937_64 rng(seed);
  bitewise::experiments::BlindPlateOptions options;
  options.overlap_probability = 0.3;
  options.same_food_touch_probability = 0.3;
  options.touch_probability = 0.3;
  std::vector<v1::DetectFoodRequest> requests(plates);
  for (v1::DetectFoodRequest& request : requests) {
    bitewise::experiments::BlindPlate plate =
        bitewise::experiments::RenderBlindPlate(rng(), options);
    bitewise::camera::FrameToProto(
        bitewise::sim::ToRgbdFrame(std::move(plate.frame), 0, 0.0), 0.0,
        "bench", request.mutable_frame());
  }
  return requests;
}

struct Run {
  double first_ms = 0.0;
  std::vector<double> ms;  // sorted
};

absl::Status RunOnce(const std::string& dir, bool retain, int index,
                     const std::vector<v1::DetectFoodRequest>& requests,
                     Run& run) {
  absl::StatusOr<int> port = bitewise::testing::PickFreePort();
  if (!port.ok()) return port.status();
  const std::string target = absl::StrCat("127.0.0.1:", *port);
  bitewise::testing::ChildProcess server;
  absl::Status status = server.Start(
      {absl::GetFlag(FLAGS_server), absl::StrCat("--listen=", target),
       absl::StrCat("--retain_freed_memory=", retain ? "true" : "false")},
      absl::StrCat(dir, "/server-", index, ".log"));
  if (!status.ok()) return status;
  status = server.WaitForLog(absl::StrCat("serving on ", target, " "),
                             absl::Seconds(60));
  if (!status.ok()) return status;
  grpc::ChannelArguments args;
  args.SetMaxSendMessageSize(8 << 20);
  auto stub = v1::PerceptionService::NewStub(grpc::CreateCustomChannel(
      target, grpc::InsecureChannelCredentials(), args));
  run.ms.clear();
  for (size_t i = 0; i <= requests.size(); ++i) {
    // The first call is the last plate, sent once more below.
    const v1::DetectFoodRequest& request =
        requests[i == 0 ? requests.size() - 1 : i - 1];
    grpc::ClientContext context;
    context.set_deadline(std::chrono::system_clock::now() +
                         std::chrono::seconds(30));
    v1::DetectFoodResponse response;
    const auto start = Clock::now();
    const grpc::Status answer = stub->DetectFood(&context, request, &response);
    const double ms =
        std::chrono::duration<double, std::milli>(Clock::now() - start).count();
    if (!answer.ok()) {
      return absl::InternalError(
          absl::StrCat("DetectFood: ", answer.error_message()));
    }
    if (i == 0) {
      run.first_ms = ms;
    } else {
      run.ms.push_back(ms);
    }
  }
  std::sort(run.ms.begin(), run.ms.end());
  return absl::OkStatus();
}

double Quantile(const std::vector<double>& sorted, double q) {
  return sorted[static_cast<size_t>(q * (sorted.size() - 1))];
}

}  // namespace

int main(int argc, char** argv) {
  absl::ParseCommandLine(argc, argv);
  const int plates = std::max(1, absl::GetFlag(FLAGS_plates));
  char dir_template[] = "/tmp/perception_service_bench.XXXXXX";
  const char* dir = mkdtemp(dir_template);
  if (dir == nullptr) {
    std::perror("mkdtemp");
    return 1;
  }
  std::printf("rendering %d blind plates (seed %llu) ...\n", plates,
              static_cast<unsigned long long>(absl::GetFlag(FLAGS_seed)));
  const std::vector<v1::DetectFoodRequest> requests =
      RenderRequests(plates, absl::GetFlag(FLAGS_seed));
  std::printf(
      "\n| --retain_freed_memory | run | first call (ms) | median (ms) | "
      "p95 (ms) | max (ms) |\n|---|---:|---:|---:|---:|---:|\n");
  int index = 0;
  for (int round = 0; round < absl::GetFlag(FLAGS_rounds); ++round) {
    for (const bool retain : {false, true}) {
      Run run;
      const absl::Status status = RunOnce(dir, retain, index++, requests, run);
      if (!status.ok()) {
        std::fprintf(stderr, "%s\n", status.ToString().c_str());
        return 1;  // the logs stay in the directory
      }
      std::printf("| %s | %d | %.1f | %.1f | %.1f | %.1f |\n",
                  retain ? "true" : "false", round + 1, run.first_ms,
                  Quantile(run.ms, 0.5), Quantile(run.ms, 0.95), run.ms.back());
      std::fflush(stdout);
    }
  }
  std::filesystem::remove_all(dir);
  return 0;
}
