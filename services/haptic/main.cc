// bitewise-haptic: the HapticService binary. Flags are parsed here and
// nowhere else; everything below main takes Options structs. With no flags
// it serves the model compiled into the binary on 127.0.0.1:50053.
#include <cstdio>
#include <memory>
#include <string>

#include "absl/flags/flag.h"
#include "absl/flags/usage.h"
#include "absl/strings/str_cat.h"
#include "services/common/flags_usage.h"
#include "services/common/rpc_environment.h"
#include "services/common/server.h"
#include "services/common/server_flags.h"
#include "services/haptic/core/familiarity.h"
#include "services/haptic/core/haptic_classifier.h"
#include "services/haptic/core/haptic_net.h"
#include "services/haptic/default_model.h"
#include "services/haptic/haptic_service.h"
#include "services/haptic/model_loading.h"

ABSL_FLAG(std::string, model, "",
          "HapticNet ONNX file. Empty: the model compiled into the binary "
          "(models/hapticnet/hapticnet.onnx). A missing or malformed file "
          "stops the start.");
ABSL_FLAG(std::string, familiarity, "",
          "Familiarity model (docs/haptic.md, \"Familiarity\"). Empty: the "
          "one beside the model, <model>.familiarity (or the compiled-in one "
          "with the compiled-in model); without that file Classify answers "
          "carry no familiarity score. \"none\": no score. A named file "
          "that is missing, or any malformed file, stops the start.");
ABSL_FLAG(double, tare_s, 0.05,
          "Leading free-motion span (s) whose median is the sensor offset.");
ABSL_FLAG(double, contact_threshold_n, 1.0,
          "Tared force magnitude (N) that starts contact.");
ABSL_FLAG(double, contact_release_n, 0.5,
          "Hysteresis: contact holds while the force stays above this (N).");
ABSL_FLAG(double, min_contact_s, 0.003,
          "Shortest excursion (s) above the threshold taken as contact.");
ABSL_FLAG(double, window_s, 0,
          "HapticNet window after contact (s). 0: the model's own "
          "(bitewise.window_s in the model; 0.05 s if it records none). "
          "Any other value must match the model's, or the start stops.");
ABSL_FLAG(int, min_window_samples, 5,
          "Samples after contact the window is stretched to hold at low "
          "rates.");

namespace {

constexpr char kProgram[] = "bitewise-haptic";
constexpr int kDefaultPort = 50053;

}  // namespace

int main(int argc, char** argv) {
  bitewise::BlockTerminationSignals();
  absl::SetProgramUsageMessage(
      "HapticService: classifies food from the fork's force/torque trace "
      "(HapticNet) over gRPC.");
  bitewise::ShowOwnFlagsInHelp();
  bitewise::ParseFlagsOnly(argc, argv);

  bitewise::haptic::HapticPipelineOptions options;
  options.contact.tare_s = absl::GetFlag(FLAGS_tare_s);
  options.contact.threshold_n = absl::GetFlag(FLAGS_contact_threshold_n);
  options.contact.release_n = absl::GetFlag(FLAGS_contact_release_n);
  options.contact.min_contact_s = absl::GetFlag(FLAGS_min_contact_s);
  options.contact.require_free_tare = true;
  options.window.min_window_samples = absl::GetFlag(FLAGS_min_window_samples);
  using bitewise::haptic::HapticNet;
  const std::string model_path = absl::GetFlag(FLAGS_model);
  absl::StatusOr<std::unique_ptr<HapticNet>> net =
      bitewise::haptic::LoadHapticNet(model_path);
  if (!net.ok()) {
    return bitewise::ReportFatal(kProgram, "cannot load the HapticNet model",
                                 net.status());
  }
  absl::StatusOr<double> window_s = bitewise::haptic::ModelWindow(
      **net, absl::GetFlag(FLAGS_window_s),
      model_path.empty() ? bitewise::haptic::kDefaultHapticNetSource
                         : model_path);
  if (!window_s.ok()) {
    return bitewise::ReportFatal(kProgram, "bad flags", window_s.status());
  }
  options.window.window_s = *window_s;
  absl::Status valid = bitewise::haptic::ValidatePipelineOptions(options);
  if (!valid.ok()) return bitewise::ReportFatal(kProgram, "bad flags", valid);
  std::string familiarity_described;
  absl::StatusOr<std::unique_ptr<bitewise::haptic::FamiliarityModel>>
      familiarity = bitewise::haptic::LoadFamiliarity(
          absl::GetFlag(FLAGS_familiarity), model_path, &familiarity_described);
  if (!familiarity.ok()) {
    return bitewise::ReportFatal(kProgram, "cannot load the familiarity model",
                                 familiarity.status());
  }
  const std::string fingerprint = (*net)->fingerprint();
  const bitewise::haptic::HapticClassifier classifier(
      std::move(net).value(), options, std::move(familiarity).value());
  bitewise::RpcEnvironment env;  // what every call runs with
  bitewise::haptic::HapticServiceImpl service(&env, &classifier);

  auto server = bitewise::ServiceServer::Start(
      bitewise::ServerOptionsFromFlags(kDefaultPort), &env, {&service},
      {bitewise::haptic::kHapticServiceName});
  if (!server.ok()) {
    return bitewise::ReportFatal(kProgram, "cannot start the server",
                                 server.status());
  }
  // Ready: the model is loaded and checked, and the server accepts calls.
  (*server)->SetServing(true);
  std::fprintf(stderr,
               "bitewise-haptic: serving on %s (model %s, %s, window %g s; "
               "%s)\n",
               (*server)->description().c_str(),
               model_path.empty() ? bitewise::haptic::kDefaultHapticNetSource
                                  : model_path.c_str(),
               fingerprint.c_str(), options.window.window_s,
               familiarity_described.c_str());
  std::fflush(stderr);
  absl::Status status = bitewise::RunUntilSignal(**server);
  if (!status.ok()) return bitewise::ReportFatal(kProgram, "shutdown", status);
  return 0;
}
