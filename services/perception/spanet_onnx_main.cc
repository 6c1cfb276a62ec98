// bitewise-spanet-onnx: writes the seeded, architecture-faithful SPANet
// ONNX file (spanet_onnx.h) for development and tests.
#include <cstdio>
#include <string>

#include "absl/flags/flag.h"
#include "absl/flags/usage.h"
#include "services/common/flags_usage.h"
#include "services/perception/spanet_onnx.h"

ABSL_FLAG(std::string, out, "spanet.onnx", "Where to write the model.");
ABSL_FLAG(uint64_t, seed, 1, "Seed of every weight.");

int main(int argc, char** argv) {
  absl::SetProgramUsageMessage(
      "Writes an untrained SPANet with seeded weights as ONNX.");
  bitewise::ShowOwnFlagsInHelp();
  bitewise::ParseFlagsOnly(argc, argv);
  bitewise::perception::SpanetOnnxOptions options;
  options.seed = absl::GetFlag(FLAGS_seed);
  const std::string out = absl::GetFlag(FLAGS_out);
  const absl::Status status =
      bitewise::perception::WriteSpanetOnnx(out, options);
  if (!status.ok()) {
    std::fprintf(stderr, "bitewise-spanet-onnx: %s\n",
                 status.ToString().c_str());
    return 1;
  }
  return 0;
}
