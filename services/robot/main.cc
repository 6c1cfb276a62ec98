// bitewise-robot: the RobotService binary. Flags are parsed here and nowhere
// else; everything below main takes Options structs.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "absl/flags/flag.h"
#include "absl/flags/usage.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "absl/time/clock.h"
#include "absl/time/time.h"
#include "services/common/flags_usage.h"
#include "services/common/metrics.h"
#include "services/common/readiness_monitor.h"
#include "services/common/rpc_environment.h"
#include "services/common/server.h"
#include "services/common/server_flags.h"
#include "services/common/status_macros.h"
#include "services/domain/steady_time.h"
#include "services/robot/backend.h"
#include "services/robot/camera_client.h"
#include "services/robot/netft/netft_rdt_client.h"
#include "services/robot/robot_service.h"
#include "services/robot/sim/sim_netft_box.h"

ABSL_FLAG(std::string, backend, "sim",
          "sim (simulated world, arm and Net F/T box on loopback) or jaco2 "
          "(Kinova SDK and a real Net F/T box).");
ABSL_FLAG(uint64_t, seed, 1,
          "sim: seeds the plate, the outcomes and the sensor noise.");
ABSL_FLAG(std::string, foods, "",
          "sim: comma-separated foods on the plate (names from the food "
          "catalog); empty means the paper's eight unseen foods.");
ABSL_FLAG(double, sim_ft_rate_hz, 1000.0,
          "sim: records per second from the simulated Net F/T box (<= 7000).");
ABSL_FLAG(int, sim_ft_port, 0,
          "sim: UDP port of the simulated box on 127.0.0.1; 0 picks one.");
ABSL_FLAG(std::string, ft_host, "192.168.1.1",
          "jaco2: address of the Net F/T box.");
ABSL_FLAG(int, ft_port, 49152, "jaco2: RDT port of the Net F/T box.");
ABSL_FLAG(double, ft_counter_rate_hz, 7000.0,
          "Rate at which the Net F/T box's ft_sequence counter advances (its "
          "internal sample rate; 7000 on a factory box). 0 learns it from "
          "arrival times. Checked continuously: a counter that disagrees, "
          "stalls or jumps stops the arm and drops health.");
ABSL_FLAG(double, sim_ft_counter_rate_hz, 7000.0,
          "sim: the rate at which the simulated box's ft_sequence advances; "
          "equal to --sim_ft_rate_hz it counts once per record.");
ABSL_FLAG(bool, check_sensor, false,
          "Connect to the F/T sensor only (the simulated box with "
          "--backend=sim), watch it for --check_sensor_s, print record rate, "
          "counter rate, noise and bias, and exit: 0 if the stream is fit to "
          "move the arm, 1 if not.");
ABSL_FLAG(double, check_sensor_s, 3.0, "How long --check_sensor watches.");
ABSL_FLAG(double, counts_per_force, 1e6,
          "Net F/T counts per newton (the box's configuration page).");
ABSL_FLAG(double, counts_per_torque, 1e6,
          "Net F/T counts per newton-metre (the box's configuration page).");
ABSL_FLAG(double, ft_silence_timeout_s, 0.0,
          "No F/T sample for this long: the sensor is silent and health "
          "reports NOT_SERVING. 0: 0.1 s on jaco2, 1 s in sim.");
ABSL_FLAG(double, ft_frozen_after_s,
          bitewise::netft::NetFtRdtClientOptions().frozen_after_s,
          "All six F/T readings identical for this long (and at least 10 "
          "records): the gauges are not being read, health reports "
          "NOT_SERVING and the arm does not move. 0: off.");
ABSL_FLAG(double, watchdog_s, 0.0,
          "The arm stops when the F/T stream is silent this long during an "
          "Acquire. 0: 0.1 s on jaco2, 1 s in sim.");
ABSL_FLAG(std::string, jaco2_sdk, "",
          "jaco2: path of the Kinova SDK library; empty means the vendor's "
          "file name for --jaco2_transport, found by the dynamic loader.");
ABSL_FLAG(std::string, jaco2_transport, "usb", "jaco2: usb or ethernet.");
ABSL_FLAG(std::string, task_origin_in_base_m, "0,-0.45,-0.05",
          "jaco2: the plate centre in the arm base frame, x,y,z metres.");
ABSL_FLAG(double, camera_height_m, 0.35,
          "jaco2: height of the wrist camera above the plate at capture.");
ABSL_FLAG(std::string, camera_address, "",
          "jaco2: host:port of bitewise-camera (the wrist camera's "
          "publisher); empty: no camera, CaptureFrame refuses.");
ABSL_FLAG(double, camera_max_frame_age_s, 0.5,
          "jaco2: CaptureFrame refuses a frame older than this (seconds, "
          "capture to arrival).");
ABSL_FLAG(std::string, camera_tls_ca, "",
          "jaco2: PEM CA that signed bitewise-camera's certificate (TLS on "
          "the camera link); empty: plaintext.");
ABSL_FLAG(std::string, camera_tls_cert, "",
          "jaco2: PEM client certificate the robot presents to "
          "bitewise-camera (mutual TLS, for a camera started with "
          "--tls_client_ca); with --camera_tls_key.");
ABSL_FLAG(std::string, camera_tls_key, "",
          "jaco2: PEM private key of --camera_tls_cert.");
ABSL_FLAG(double, static_load_threshold_n, 0.02,
          "jaco2: success when the fork carries at least this load after "
          "extraction; 0 leaves success to the operator.");

namespace {

constexpr char kProgram[] = "bitewise-robot";
constexpr int kDefaultPort = 50054;

absl::StatusOr<bitewise::robot::RobotBackendOptions> OptionsFromFlags() {
  using bitewise::robot::BackendKind;
  bitewise::robot::RobotBackendOptions options;
  const std::string backend = absl::GetFlag(FLAGS_backend);
  if (backend == "sim") {
    options.kind = BackendKind::kSim;
  } else if (backend == "jaco2") {
    options.kind = BackendKind::kJaco2;
  } else {
    return absl::InvalidArgumentError(
        absl::StrCat("--backend must be sim or jaco2, got \"", backend, "\""));
  }
  options.sim.seed = absl::GetFlag(FLAGS_seed);
  const std::string foods = absl::GetFlag(FLAGS_foods);
  if (!foods.empty()) {
    options.sim.foods = absl::StrSplit(foods, ',', absl::SkipEmpty());
  }
  options.sim.box.rate_hz = absl::GetFlag(FLAGS_sim_ft_rate_hz);
  options.sim.box.internal_rate_hz =
      absl::GetFlag(FLAGS_sim_ft_counter_rate_hz);
  options.ft.counter.expected_rate_hz = absl::GetFlag(FLAGS_ft_counter_rate_hz);
  const int sim_port = absl::GetFlag(FLAGS_sim_ft_port);
  const int ft_port = absl::GetFlag(FLAGS_ft_port);
  if (sim_port < 0 || sim_port > 65535 || ft_port <= 0 || ft_port > 65535) {
    return absl::InvalidArgumentError(
        "--sim_ft_port and --ft_port must be UDP ports");
  }
  options.sim.box.port = static_cast<uint16_t>(sim_port);
  options.ft.host = absl::GetFlag(FLAGS_ft_host);
  options.ft.port = static_cast<uint16_t>(ft_port);
  options.ft.counts_per_force = absl::GetFlag(FLAGS_counts_per_force);
  options.ft.counts_per_torque = absl::GetFlag(FLAGS_counts_per_torque);
  // The simulated box shares two cores with everything else on a
  // development or CI machine, where a scheduling hiccup is not a sensor
  // fault; real hardware keeps the tight 100 ms.
  const bool sim = backend == "sim";
  const double silence_default_s = sim ? 1.0 : 0.1;
  // Each of these is how long the arm may move on a sensor that has gone
  // silent or reads nothing. On the JACO2 at most kMaxJaco2SensorTimeoutS:
  // at the approach speed (0.15 m/s) that is under 4 cm moved blind, 1.25 cm
  // in the descent; the defaults are 0.1 s. The simulated box, which shares
  // two cores with everything else, may wait up to kMaxSimSensorTimeoutS.
  constexpr double kMaxJaco2SensorTimeoutS = 0.25;
  constexpr double kMaxSimSensorTimeoutS = 2.0;
  const double max_timeout_s =
      sim ? kMaxSimSensorTimeoutS : kMaxJaco2SensorTimeoutS;
  // `zero`: what 0 means for the flag, or null where 0 is refused.
  const auto check_timeout = [&](const char* flag, double value,
                                 const char* zero) -> absl::Status {
    if (std::isfinite(value) && value <= max_timeout_s &&
        (value > 0.0 || (value == 0.0 && zero != nullptr))) {
      return absl::OkStatus();
    }
    return absl::InvalidArgumentError(absl::StrCat(
        "--", flag, " must be ",
        zero != nullptr ? absl::StrCat("0 (", zero, ") or ") : "",
        "above 0 and at most ", max_timeout_s, " s on --backend=", backend,
        ", got ", value,
        ": the arm may move that long on a sensor that is silent or reads "
        "nothing"));
  };
  const double silence_s = absl::GetFlag(FLAGS_ft_silence_timeout_s);
  const double watchdog_s = absl::GetFlag(FLAGS_watchdog_s);
  RETURN_IF_ERROR(
      check_timeout("ft_silence_timeout_s", silence_s, "the default"));
  RETURN_IF_ERROR(check_timeout("watchdog_s", watchdog_s, "the default"));
  options.ft.silence_timeout_s =
      silence_s > 0.0 ? silence_s : silence_default_s;
  options.ft.frozen_after_s = absl::GetFlag(FLAGS_ft_frozen_after_s);
  // 0 turns the frozen-gauge check off: in the simulation only.
  RETURN_IF_ERROR(check_timeout("ft_frozen_after_s", options.ft.frozen_after_s,
                                sim ? "off" : nullptr));
  options.acquisition.watchdog_timeout_s =
      watchdog_s > 0.0 ? watchdog_s : silence_default_s;
  const double camera_height_m = absl::GetFlag(FLAGS_camera_height_m);
  if (!(camera_height_m > 0.0 && camera_height_m <= 2.0)) {
    return absl::InvalidArgumentError(
        absl::StrCat("--camera_height_m must be above 0 and at most 2 m, got ",
                     camera_height_m));
  }
  options.acquisition.X_TaskCamera =
      bitewise::robot::CameraLookingDown(camera_height_m);
  options.hardware.arm.sdk_library = absl::GetFlag(FLAGS_jaco2_sdk);
  const std::string transport = absl::GetFlag(FLAGS_jaco2_transport);
  if (transport == "usb") {
    options.hardware.arm.transport = bitewise::jaco2::Jaco2Transport::kUsb;
  } else if (transport == "ethernet") {
    options.hardware.arm.transport = bitewise::jaco2::Jaco2Transport::kEthernet;
  } else {
    return absl::InvalidArgumentError(absl::StrCat(
        "--jaco2_transport must be usb or ethernet, got \"", transport, "\""));
  }
  const std::vector<std::string> origin =
      absl::StrSplit(absl::GetFlag(FLAGS_task_origin_in_base_m), ',');
  if (origin.size() != 3) {
    return absl::InvalidArgumentError(
        "--task_origin_in_base_m must be three comma-separated numbers");
  }
  for (int i = 0; i < 3; ++i) {
    double& x = options.hardware.arm.p_BaseTask_m[i];
    if (!absl::SimpleAtod(origin[i], &x)) {
      return absl::InvalidArgumentError(absl::StrCat(
          "--task_origin_in_base_m: \"", origin[i], "\" is not a number"));
    }
    // The JACO2 reaches 0.9 m from its base.
    if (!(std::abs(x) <= 1.0)) {
      return absl::InvalidArgumentError(absl::StrCat(
          "--task_origin_in_base_m: ", origin[i],
          " m is not a finite number within 1 m of the arm's base"));
    }
  }
  options.hardware.static_load_threshold_n =
      absl::GetFlag(FLAGS_static_load_threshold_n);
  return options;
}

// --check_sensor: the F/T stream alone, summarised for a person at the
// robot (docs/hardware.md walks through reading it).
int CheckSensor(const bitewise::robot::RobotBackendOptions& options) {
  namespace netft = bitewise::netft;
  std::unique_ptr<bitewise::sim::SimNetFtBox> box;
  netft::NetFtRdtClientOptions ft = options.ft;
  if (options.kind == bitewise::robot::BackendKind::kSim) {
    const bitewise::sim::SimNetFtBoxOptions box_options =
        bitewise::robot::SimBoxOptions(options);
    auto started = bitewise::sim::SimNetFtBox::Start(box_options, nullptr);
    if (!started.ok()) {
      return bitewise::ReportFatal(kProgram, "cannot start the simulated box",
                                   started.status());
    }
    box = std::move(started).value();
    ft.host = box_options.host;
    ft.port = box->port();
  }
  auto client = netft::NetFtRdtClient::Connect(ft);
  if (!client.ok()) {
    return bitewise::ReportFatal(kProgram, "cannot reach the F/T sensor",
                                 client.status());
  }
  const double watch_s = std::max(1.0, absl::GetFlag(FLAGS_check_sensor_s));
  absl::SleepFor(absl::Seconds(watch_s));
  std::vector<netft::FtSample> samples;
  (*client)->SamplesSince(0, &samples);
  // Noise and bias over the second half of the watch (after any start-up).
  const double from_s = bitewise::SteadyNowS() - watch_s / 2;
  std::array<double, 6> sum{}, sum_sq{};
  int n = 0;
  for (const netft::FtSample& s : samples) {
    if (s.arrival_s < from_s) continue;
    for (int i = 0; i < 6; ++i) {
      const double v = i < 3 ? s.wrench.force_n[i] : s.wrench.torque_nm[i - 3];
      sum[i] += v;
      sum_sq[i] += v * v;
    }
    ++n;
  }
  const netft::StreamHealth health = (*client)->Health();
  const netft::RdtStats stats = (*client)->stats();
  std::printf("%s\n", (*client)->name().c_str());
  std::printf(
      "  stream          %s, %.0f records/s, %llu received, %llu lost, "
      "%llu out of order, %llu malformed, status word 0x%08x\n",
      netft::StreamStateName(health.state), health.rate_hz,
      static_cast<unsigned long long>(stats.samples_accepted),
      static_cast<unsigned long long>(stats.packets_lost),
      static_cast<unsigned long long>(stats.out_of_order),
      static_cast<unsigned long long>(stats.malformed), stats.last_status);
  std::printf("  counter         %s: measured %.0f Hz, in use %.0f Hz%s%s\n",
              netft::CounterClockStateName(health.counter.state),
              health.counter.measured_rate_hz, health.counter.rate_hz,
              health.counter.problem.empty() ? "" : "; ",
              health.counter.problem.c_str());
  static constexpr const char* kAxes[6] = {"Fx N",  "Fy N",  "Fz N",
                                           "Tx Nm", "Ty Nm", "Tz Nm"};
  std::printf("  %-6s %12s %12s   (over the last %.1f s, %d samples)\n", "axis",
              "bias", "noise sd", watch_s / 2, n);
  for (int i = 0; i < 6 && n > 1; ++i) {
    const double mean = sum[i] / n;
    const double var = std::max(0.0, sum_sq[i] / n - mean * mean);
    std::printf("  %-6s %12.4f %12.5f\n", kAxes[i], mean, std::sqrt(var));
  }
  const absl::Status live = (*client)->CheckLive();
  std::printf(
      "  verdict         %s\n",
      live.ok() ? "fit to move the arm" : std::string(live.message()).c_str());
  std::fflush(stdout);
  return live.ok() ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  bitewise::BlockTerminationSignals();
  absl::SetProgramUsageMessage(
      "RobotService: the JACO2 with the Forque, or the simulated world.");
  bitewise::ShowOwnFlagsInHelp();
  bitewise::ParseFlagsOnly(argc, argv);

  absl::StatusOr<bitewise::robot::RobotBackendOptions> options =
      OptionsFromFlags();
  if (!options.ok()) {
    return bitewise::ReportFatal(kProgram, "bad flags", options.status());
  }
  if (absl::GetFlag(FLAGS_check_sensor)) return CheckSensor(*options);
  std::unique_ptr<bitewise::robot::CameraClient> camera;
  if (const std::string address = absl::GetFlag(FLAGS_camera_address);
      !address.empty()) {
    bitewise::robot::CameraClientOptions camera_options;
    camera_options.address = address;
    camera_options.max_frame_age_s =
        absl::GetFlag(FLAGS_camera_max_frame_age_s);
    camera_options.channel.tls_ca_file = absl::GetFlag(FLAGS_camera_tls_ca);
    camera_options.channel.tls_cert_file = absl::GetFlag(FLAGS_camera_tls_cert);
    camera_options.channel.tls_key_file = absl::GetFlag(FLAGS_camera_tls_key);
    // A 1280x720 RGB-D frame is 4.6 MB, more than gRPC's default 4 MiB.
    camera_options.channel.max_message_bytes = 64 << 20;
    auto created = bitewise::robot::CameraClient::Create(camera_options);
    if (!created.ok()) {
      return bitewise::ReportFatal(kProgram, "bad camera flags",
                                   created.status());
    }
    camera = *std::move(created);
    options->hardware.camera = camera.get();
  }
  auto backend = bitewise::robot::RobotBackend::Create(*options);
  if (!backend.ok()) {
    return bitewise::ReportFatal(kProgram, "cannot start the robot",
                                 backend.status());
  }
  bitewise::RpcEnvironment env;  // what every call runs with
  bitewise::robot::RobotServiceImpl service(&env, backend->get());

  auto server = bitewise::ServiceServer::Start(
      bitewise::ServerOptionsFromFlags(kDefaultPort), &env, {&service},
      {"bitewise.v1.RobotService"});
  if (!server.ok()) {
    return bitewise::ReportFatal(kProgram, "cannot start the server",
                                 server.status());
  }
  // Metrics read at scrape time (docs/operations.md).
  {
    using bitewise::ScrapeType;
    using bitewise::ScrapeValue;
    bitewise::Metrics& metrics = env.metrics();
    bitewise::robot::RobotBackend* b = backend->get();
    auto status_value = [b](auto field) {
      return [b, field]() -> std::vector<ScrapeValue> {
        // Not the arm's pose: a scrape must not compete with the control
        // loop for the JACO2's USB link.
        return {{{}, field(b->robot().Status(/*ask_arm=*/false))}};
      };
    };
    using Info = bitewise::robot::RobotStatusInfo;
    metrics.AddScrapeValues(
        "bitewise_robot_ft_rate_hz", "F/T samples accepted per second",
        ScrapeType::kGauge,
        status_value([](const Info& i) { return i.ft_health.rate_hz; }));
    metrics.AddScrapeValues(
        "bitewise_robot_ft_silent_seconds",
        "Seconds since the last accepted F/T sample", ScrapeType::kGauge,
        status_value([](const Info& i) { return i.ft_health.silent_for_s; }));
    metrics.AddScrapeValues(
        "bitewise_robot_ft_live", "1 while the F/T stream is live",
        ScrapeType::kGauge, [b]() -> std::vector<ScrapeValue> {
          return {{{}, b->FtLive() ? 1.0 : 0.0}};
        });
    metrics.AddScrapeValues(
        "bitewise_robot_ft_packets_skipped_total",
        "RDT sequence numbers skipped (counted when skipped, even if the "
        "packet arrives late)",
        ScrapeType::kCounter, status_value([](const Info& i) {
          return static_cast<double>(i.ft_stats.packets_skipped);
        }));
    metrics.AddScrapeValues(
        "bitewise_robot_ft_packets_late_total",
        "RDT packets that arrived after a later one", ScrapeType::kCounter,
        status_value([](const Info& i) {
          return static_cast<double>(i.ft_stats.out_of_order);
        }));
    metrics.AddScrapeValues(
        "bitewise_robot_ft_stream_restarts_total",
        "Start requests re-sent to a silent box (the packets of a silence "
        "are not counted as skipped: its sequence starts again)",
        ScrapeType::kCounter, status_value([](const Info& i) {
          return static_cast<double>(i.ft_stats.restarts);
        }));
    metrics.AddScrapeValues("bitewise_robot_acquisitions_total",
                            "Acquisitions run", ScrapeType::kCounter,
                            status_value([](const Info& i) {
                              return static_cast<double>(i.acquisitions);
                            }));
    metrics.AddScrapeValues("bitewise_robot_acquisitions_failed_total",
                            "Acquisitions that ended in an error",
                            ScrapeType::kCounter,
                            status_value([](const Info& i) {
                              return static_cast<double>(i.acquisitions_failed);
                            }));
    metrics.AddScrapeValues(
        "bitewise_robot_control_overruns_total",
        "Control periods that began after their tick had passed (the loop "
        "or the machine was too slow for the control rate)",
        ScrapeType::kCounter, status_value([](const Info& i) {
          return static_cast<double>(i.control_overruns);
        }));
    metrics.AddScrapeValues("bitewise_robot_force_limit_trips_total",
                            "Force-limit trips", ScrapeType::kCounter,
                            status_value([](const Info& i) {
                              return static_cast<double>(i.force_limit_trips);
                            }));
  }
  // Ready while the F/T stream is live and the arm answers; each change is
  // logged with its reason.
  bitewise::LoggedReadiness logged = bitewise::LogReadiness(
      kProgram, [b = backend->get()] { return b->Readiness(); },
      [s = server->get()](bool serving) { s->SetServing(serving); });
  bitewise::ReadinessMonitor readiness(logged.live, logged.set_serving);
  std::fprintf(stderr, "bitewise-robot: serving on %s (backend %s, %s)\n",
               (*server)->description().c_str(),
               absl::GetFlag(FLAGS_backend).c_str(),
               (*backend)->ft()->name().c_str());
  std::fflush(stderr);
  absl::Status status = bitewise::RunUntilSignal(**server);
  if (!status.ok()) return bitewise::ReportFatal(kProgram, "shutdown", status);
  return 0;
}
