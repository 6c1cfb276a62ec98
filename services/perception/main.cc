// bitewise-perception: the PerceptionService binary. Flags are parsed here
// and nowhere else; everything below main takes Options structs.
#include <cstdio>
#include <memory>
#include <string>

#include "absl/flags/flag.h"
#include "absl/flags/usage.h"
#include "absl/strings/str_cat.h"
#include "services/common/flags_usage.h"
#include "services/common/process_memory.h"
#include "services/common/rpc_environment.h"
#include "services/common/server.h"
#include "services/common/server_flags.h"
#include "services/perception/context_scale.h"
#include "services/perception/default_featurizer.h"
#include "services/perception/food_detector.h"
#include "services/perception/model_check.h"
#include "services/perception/perception_service.h"
#include "services/perception/spanet_featurizer.h"

ABSL_FLAG(std::string, featurizer, "default",
          "Visual context for Featurize: default (weight-free, 64 numbers) "
          "or spanet (2048 numbers; needs --spanet_model).");
ABSL_FLAG(std::string, spanet_model, "",
          "SPANet ONNX file (interface in docs/perception.md). Loaded and "
          "checked before the service reports SERVING.");
ABSL_FLAG(bool, check_model, false,
          "Load and check the featurizer (and its model) as the service "
          "would, featurize --check_crops if given, print a summary and "
          "exit without serving: 0 if the model is fit to serve.");
ABSL_FLAG(std::string, check_crops, "",
          "With --check_model: PNG crops to featurize, as "
          "PATH[:isolated|wall|lettuce],...");
ABSL_FLAG(std::string, check_out, "",
          "With --check_crops: directory for crop<i>.txt (context, action "
          "scores, skewer points) and crop<i>.canvas.png (SPANet's input).");
ABSL_FLAG(double, min_food_height_mm, 4.0,
          "Height above the plate from which DetectFood counts a pixel as "
          "food.");
ABSL_FLAG(bool, retain_freed_memory, true,
          "Keep the memory each request frees for the next one (glibc "
          "malloc: no mmap below 32 MB, no heap trimming), so DetectFood "
          "does not page-fault its buffers in afresh; the process keeps its "
          "largest working set (about 37 MiB more resident memory with the "
          "default featurizer).");

namespace {

constexpr char kProgram[] = "bitewise-perception";
constexpr int kDefaultPort = 50052;

}  // namespace

int main(int argc, char** argv) {
  bitewise::BlockTerminationSignals();
  absl::SetProgramUsageMessage(
      "PerceptionService: food detection and visual features over gRPC.");
  bitewise::ShowOwnFlagsInHelp();
  bitewise::ParseFlagsOnly(argc, argv);

  const std::string which = absl::GetFlag(FLAGS_featurizer);
  std::unique_ptr<bitewise::perception::Featurizer> featurizer;
  if (which == "default") {
    if (!absl::GetFlag(FLAGS_spanet_model).empty()) {
      // A model that would be ignored is a mistake, not a choice.
      return bitewise::ReportFatal(
          kProgram, "bad flags",
          absl::InvalidArgumentError(
              "--spanet_model has no effect with --featurizer=default: add "
              "--featurizer=spanet to serve SPANet features"));
    }
    featurizer = std::make_unique<bitewise::perception::DefaultFeaturizer>();
  } else if (which == "spanet") {
    const std::string model = absl::GetFlag(FLAGS_spanet_model);
    if (model.empty()) {
      return bitewise::ReportFatal(
          kProgram, "bad flags",
          absl::InvalidArgumentError(
              "--featurizer=spanet needs --spanet_model"));
    }
    auto spanet = bitewise::perception::SpanetFeaturizer::Load(model);
    if (!spanet.ok()) {
      return bitewise::ReportFatal(kProgram, "cannot load SPANet",
                                   spanet.status());
    }
    featurizer = *std::move(spanet);
    if (featurizer->context_mean_squared_norm() <= 0.0) {
      // Not an error (a lab may set lambda_c per user), but never silent.
      const std::string stats =
          bitewise::perception::ContextScalePathFor(model);
      std::fprintf(
          stderr,
          "%s: warning: no %s beside the model, so Featurize reports "
          "context_mean_squared_norm 0 and a new user's context ridge will "
          "be the BanditService's --default_lambda_c (1000 unless set) "
          "instead of rho_c x E||c||^2 of this featurizer; write the file "
          "with: bitewise-featurizer-stats --featurizer=spanet "
          "--spanet_model=%s --out=%s\n",
          kProgram, stats.c_str(), model.c_str(), stats.c_str());
    }
  } else {
    return bitewise::ReportFatal(kProgram, "bad flags",
                                 absl::InvalidArgumentError(absl::StrCat(
                                     "--featurizer: unknown featurizer \"",
                                     which, "\" (default or spanet)")));
  }
  if (absl::GetFlag(FLAGS_check_model)) {
    const std::string spec = absl::GetFlag(FLAGS_check_crops);
    if (!spec.empty()) {
      auto crops = bitewise::perception::ParseCheckCrops(spec);
      if (!crops.ok()) {
        return bitewise::ReportFatal(kProgram, "bad flags", crops.status());
      }
      const std::string out_dir = absl::GetFlag(FLAGS_check_out);
      if (out_dir.empty()) {
        return bitewise::ReportFatal(
            kProgram, "bad flags",
            absl::InvalidArgumentError("--check_crops needs --check_out"));
      }
      absl::Status checked =
          bitewise::perception::RunModelCheck(*featurizer, *crops, out_dir);
      if (!checked.ok()) {
        return bitewise::ReportFatal(kProgram, "model check failed", checked);
      }
    }
    std::printf("%s: featurizer %s loaded and run (%d numbers per context)\n",
                kProgram, featurizer->name().c_str(), featurizer->dimension());
    return 0;
  }
  if (absl::GetFlag(FLAGS_retain_freed_memory)) {
    // A matter of speed only: said, and the service runs on (an allocator
    // that refuses, such as a sanitizer's, keeps its own policy).
    const absl::Status retained = bitewise::RetainFreedMemory();
    if (!retained.ok()) {
      std::fprintf(stderr,
                   "%s: warning: --retain_freed_memory: %s; DetectFood may "
                   "be a few ms slower\n",
                   kProgram, retained.ToString().c_str());
    }
  }
  bitewise::perception::PrepareColourConversions();
  bitewise::perception::FoodDetectorOptions detector_options;
  detector_options.min_height_mm = absl::GetFlag(FLAGS_min_food_height_mm);
  const bitewise::perception::FoodDetector detector(detector_options);
  bitewise::RpcEnvironment env;  // what every call runs with
  bitewise::perception::PerceptionServiceImpl service(&env, &detector,
                                                      featurizer.get());

  auto server = bitewise::ServiceServer::Start(
      bitewise::ServerOptionsFromFlags(kDefaultPort), &env, {&service},
      {"bitewise.v1.PerceptionService"});
  if (!server.ok()) {
    return bitewise::ReportFatal(kProgram, "cannot start the server",
                                 server.status());
  }
  // Ready: the featurizer (and its model, if any) is loaded and checked.
  (*server)->SetServing(true);
  std::fprintf(stderr, "bitewise-perception: serving on %s (featurizer %s)\n",
               (*server)->description().c_str(), featurizer->name().c_str());
  std::fflush(stderr);
  absl::Status status = bitewise::RunUntilSignal(**server);
  if (!status.ok()) return bitewise::ReportFatal(kProgram, "shutdown", status);
  return 0;
}
