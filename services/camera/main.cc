// bitewise-camera: the wrist camera's publisher (CameraService), run on the
// computer the D415 is plugged into. Flags are parsed here and nowhere
// else.
#include <cstdint>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "absl/flags/flag.h"
#include "absl/flags/usage.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_split.h"
#include "services/camera/camera_service.h"
#include "services/camera/frame_publisher.h"
#include "services/camera/realsense_source.h"
#include "services/camera/recording.h"
#include "services/camera/sim_source.h"
#include "services/common/flags_usage.h"
#include "services/common/readiness_monitor.h"
#include "services/common/rpc_environment.h"
#include "services/common/server.h"
#include "services/common/server_flags.h"

ABSL_FLAG(std::string, source, "realsense",
          "realsense (the D415 through the RealSense SDK), replay (a "
          "recording, --replay_dir) or sim (the simulated camera).");
ABSL_FLAG(std::string, realsense_library, "",
          "The RealSense SDK shared library; empty: the installed "
          "librealsense2.so.");
ABSL_FLAG(int, width, 640, "realsense: colour and depth width.");
ABSL_FLAG(int, height, 480, "realsense: colour and depth height.");
ABSL_FLAG(int, fps, 15, "realsense, sim: frames per second.");
ABSL_FLAG(std::string, replay_dir, "", "replay: the recording's directory.");
ABSL_FLAG(bool, replay_loop, false,
          "replay: start again after the last frame (otherwise the last "
          "frame ages and the camera reports itself stale).");
ABSL_FLAG(uint64_t, sim_seed, 1, "sim: seeds the plate and the noise.");
ABSL_FLAG(std::string, sim_foods, "",
          "sim: comma-separated food names; empty: the unseen foods.");
ABSL_FLAG(std::string, record, "",
          "Also write every frame into this directory as a recording "
          "(replayable with --source=replay).");
ABSL_FLAG(double, stale_after_s, 1.0,
          "Health is NOT_SERVING while the newest frame is older than this.");

namespace {

constexpr char kProgram[] = "bitewise-camera";
constexpr int kDefaultPort = 50055;

absl::StatusOr<std::unique_ptr<bitewise::camera::FrameSource>> MakeSource() {
  using namespace bitewise::camera;  // NOLINT: local, for brevity
  const std::string source = absl::GetFlag(FLAGS_source);
  if (source == "realsense") {
    RealSenseOptions options;
    options.library = absl::GetFlag(FLAGS_realsense_library);
    options.width = absl::GetFlag(FLAGS_width);
    options.height = absl::GetFlag(FLAGS_height);
    options.fps = absl::GetFlag(FLAGS_fps);
    return RealSenseSource::Open(options);
  }
  if (source == "replay") {
    ReplayOptions options;
    options.loop = absl::GetFlag(FLAGS_replay_loop);
    return ReplaySource::Open(absl::GetFlag(FLAGS_replay_dir), options);
  }
  if (source == "sim") {
    SimSourceOptions options;
    options.seed = absl::GetFlag(FLAGS_sim_seed);
    options.rate_hz = absl::GetFlag(FLAGS_fps);
    for (absl::string_view food : absl::StrSplit(absl::GetFlag(FLAGS_sim_foods),
                                                 ',', absl::SkipEmpty())) {
      options.foods.emplace_back(food);
    }
    return SimSource::Create(options);
  }
  return absl::InvalidArgumentError(absl::StrCat(
      "--source: unknown source \"", source, "\" (realsense, replay or sim)"));
}

// A frame goes out whole in one message: 3 bytes of colour and 2 of depth a
// pixel, and a few hundred bytes more. At a size whose frame is over
// --max_message_bytes the publisher would start and report SERVING, and
// every GetFrame would fail with gRPC's "Sent message larger than max"; so
// it does not start. (The RealSense's size is its flags', checked before
// the camera is opened; a replay's is its recording's, checked once the
// recording is open; the simulated camera's is 640x480.)
absl::Status FrameFitsAMessage(int64_t width, int64_t height,
                               const std::string& what) {
  constexpr int64_t kFrameOverheadBytes = 1024;
  const int64_t bytes = width * height * 5 + kFrameOverheadBytes;
  const int64_t limit = absl::GetFlag(FLAGS_max_message_bytes);
  if (width <= 0 || height <= 0 || bytes <= limit) return absl::OkStatus();
  return absl::InvalidArgumentError(absl::StrCat(
      what, ": a frame is about ", bytes, " bytes, over --max_message_bytes (",
      limit, "); give --max_message_bytes of at least ", bytes,
      " here, to bitewise-robot (which sends the frame on) and to "
      "bitewise-perception (which receives it)"));
}

}  // namespace

int main(int argc, char** argv) {
  bitewise::BlockTerminationSignals();
  absl::SetProgramUsageMessage(
      "CameraService: the wrist camera's newest RGB-D frame over gRPC.");
  bitewise::ShowOwnFlagsInHelp();
  bitewise::ParseFlagsOnly(argc, argv);

  if (absl::GetFlag(FLAGS_source) == "realsense") {
    if (absl::Status fits = FrameFitsAMessage(
            absl::GetFlag(FLAGS_width), absl::GetFlag(FLAGS_height),
            absl::StrCat("--width=", absl::GetFlag(FLAGS_width),
                         " --height=", absl::GetFlag(FLAGS_height)));
        !fits.ok()) {
      return bitewise::ReportFatal(kProgram, "cannot serve frames of that size",
                                   fits);
    }
  }
  auto source = MakeSource();
  if (!source.ok()) {
    return bitewise::ReportFatal(kProgram, "cannot open the camera",
                                 source.status());
  }
  if (const auto* replay =
          dynamic_cast<const bitewise::camera::ReplaySource*>(source->get())) {
    const bitewise::domain::CameraIntrinsics& k = replay->intrinsics();
    if (absl::Status fits = FrameFitsAMessage(
            k.width, k.height,
            absl::StrCat("the recording's ", k.width, "x", k.height,
                         " frames (", replay->name(), ")"));
        !fits.ok()) {
      return bitewise::ReportFatal(kProgram,
                                   "cannot serve the recording's frames", fits);
    }
  }
  if (const std::string dir = absl::GetFlag(FLAGS_record); !dir.empty()) {
    // Recording is a side line of feeding: a directory that already holds
    // one (a restart after a crash, a reused name) is left alone, and the
    // camera serves without recording, saying so.
    if (absl::Status fresh =
            bitewise::camera::RecordingSource::CheckNewRecording(dir);
        !fresh.ok()) {
      std::fprintf(stderr,
                   "bitewise-camera: --record: %s; serving without "
                   "recording\n",
                   std::string(fresh.message()).c_str());
    } else {
      *source = std::make_unique<bitewise::camera::RecordingSource>(
          *std::move(source), dir, absl::GetFlag(FLAGS_fps));
    }
  }
  bitewise::camera::FramePublisher publisher(*std::move(source));
  bitewise::RpcEnvironment env;  // what every call runs with
  bitewise::camera::CameraServiceImpl service(&env, &publisher);
  auto server = bitewise::ServiceServer::Start(
      bitewise::ServerOptionsFromFlags(kDefaultPort), &env, {&service},
      {"bitewise.v1.CameraService"});
  if (!server.ok()) {
    return bitewise::ReportFatal(kProgram, "cannot start the server",
                                 server.status());
  }
  const double stale_after_s = absl::GetFlag(FLAGS_stale_after_s);
  // Each change is logged with its reason.
  bitewise::LoggedReadiness logged = bitewise::LogReadiness(
      kProgram,
      [&publisher, stale_after_s]() -> absl::Status {
        const auto c = publisher.Counters();
        if (c.newest_age_s < 0.0) {
          return absl::UnavailableError(absl::StrCat(
              "no frame yet from ", publisher.source_name(),
              c.last_error.empty() ? "" : "; last error: ", c.last_error));
        }
        if (c.newest_age_s > stale_after_s) {
          return absl::UnavailableError(absl::StrFormat(
              "the newest frame from %s is %.1f s old (--stale_after_s "
              "%.1f)%s",
              publisher.source_name(), c.newest_age_s, stale_after_s,
              c.last_error.empty() ? "" : "; last error: " + c.last_error));
        }
        return absl::OkStatus();
      },
      [s = server->get()](bool serving) { s->SetServing(serving); });
  bitewise::ReadinessMonitor readiness(logged.live, logged.set_serving);
  std::fprintf(stderr, "bitewise-camera: serving on %s (source %s)\n",
               (*server)->description().c_str(),
               publisher.source_name().c_str());
  std::fflush(stderr);
  absl::Status status = bitewise::RunUntilSignal(**server);
  if (!status.ok()) return bitewise::ReportFatal(kProgram, "shutdown", status);
  return 0;
}
