// bitewise-featurizer-stats: regenerates models/featurizer/
// default_featurizer_stats.txt, the fixed statistics the default featurizer
// is standardised with; with --featurizer=spanet, writes "<model>.stats",
// the E||c||^2 of a SPANet model's contexts on seen foods
// (services/perception/context_scale.h). Renders plates of the simulated
// world's SEEN foods only (never the eight unseen evaluation foods), featurizes
// every visible item on its ground-truth box with the raw featurizer, and
// writes each feature's mean and standard deviation, then E||c||^2 of the
// standardised contexts on the same items (what new users' context ridge is
// scaled by).
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "absl/flags/flag.h"
#include "absl/flags/parse.h"
#include "absl/flags/usage.h"
#include "absl/status/statusor.h"
#include "absl/strings/str_format.h"
#include "experiments/sim_meals.h"
#include "services/common/flags_usage.h"
#include "services/domain/random.h"
#include "services/perception/context_scale.h"
#include "services/perception/default_featurizer.h"
#include "services/perception/spanet_featurizer.h"
#include "services/sim/food_catalog.h"
#include "services/sim/scene.h"

ABSL_FLAG(int, plates, 400, "Plates of seen foods to render.");
ABSL_FLAG(uint64_t, seed, 7001,
          "Seeds the plates (a seed range apart from the experiments').");
ABSL_FLAG(
    std::string, out, "",
    "File to write; empty: models/featurizer/default_featurizer_stats.txt "
    "(default) or <spanet_model>.stats (spanet).");
ABSL_FLAG(std::string, featurizer, "default", "default or spanet.");
ABSL_FLAG(std::string, spanet_model, "", "spanet: the ONNX model.");

namespace {

using bitewise::experiments::FeaturizeScene;
namespace perception = bitewise::perception;
namespace sim = bitewise::sim;

int Fail(const std::string& what) {
  std::fprintf(stderr, "bitewise-featurizer-stats: %s\n", what.c_str());
  return 1;
}

// Contexts of every visible item on `plates` plates of seen foods.
absl::StatusOr<std::vector<std::vector<double>>> SeenFoodContexts(
    const perception::Featurizer& featurizer, int plates, uint64_t seed) {
  const std::vector<const sim::FoodType*> seen = sim::SeenFoods();
  std::mt19937_64 plate_rng(bitewise::random::MixSeed(seed, 1));
  std::vector<std::vector<double>> contexts;
  for (int plate = 0; plate < plates; ++plate) {
    const sim::PlateScene scene =
        sim::RandomPlate(seen, /*allow_touching=*/false, plate_rng);
    auto featurized = FeaturizeScene(
        scene, bitewise::random::MixSeed(seed, 100 + plate), featurizer);
    if (!featurized.ok()) return featurized.status();
    for (std::vector<double>& c : *featurized) {
      if (!c.empty()) contexts.push_back(std::move(c));
    }
  }
  return contexts;
}

bool WriteFile(const std::string& path, const std::string& text) {
  FILE* f = std::fopen(path.c_str(), "w");
  if (f == nullptr) return false;
  std::fputs(text.c_str(), f);
  return std::fclose(f) == 0;
}

int SpanetStats(int plates, uint64_t seed) {
  const std::string model = absl::GetFlag(FLAGS_spanet_model);
  if (model.empty()) return Fail("--featurizer=spanet needs --spanet_model");
  auto spanet = perception::SpanetFeaturizer::Load(model);
  if (!spanet.ok()) return Fail(spanet.status().ToString());
  auto contexts = SeenFoodContexts(**spanet, plates, seed);
  if (!contexts.ok()) return Fail(contexts.status().ToString());
  double msn = 0.0;
  for (const auto& c : *contexts) {
    for (double v : c) msn += v * v / contexts->size();
  }
  std::string out = absl::GetFlag(FLAGS_out);
  if (out.empty()) out = perception::ContextScalePathFor(model);
  const std::string text = perception::FormatContextScale(
      msn, absl::StrFormat(
               "E||c||^2 of this SPANet's contexts on %d items of the "
               "simulated world's seen foods\n(never the unseen evaluation "
               "foods): %d plates, seed %d.\nRegenerate: "
               "bitewise-featurizer-stats --featurizer=spanet "
               "--spanet_model=MODEL --plates=%d --seed=%d",
               contexts->size(), plates, seed, plates, seed));
  if (!WriteFile(out, text)) return Fail("cannot write " + out);
  std::printf("%zu seen-food items; E||c||^2 = %.4g; wrote %s\n",
              contexts->size(), msn, out.c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  absl::SetProgramUsageMessage(
      "Writes the default featurizer's seen-food statistics.");
  bitewise::ShowOwnFlagsInHelp();
  absl::ParseCommandLine(argc, argv);
  const int plates = absl::GetFlag(FLAGS_plates);
  const uint64_t seed = absl::GetFlag(FLAGS_seed);
  if (plates < 10) return Fail("--plates must be at least 10");

  if (absl::GetFlag(FLAGS_featurizer) == "spanet") {
    return SpanetStats(plates, seed);
  }
  if (absl::GetFlag(FLAGS_featurizer) != "default") {
    return Fail("--featurizer must be default or spanet");
  }
  perception::DefaultFeaturizerOptions raw_options;
  raw_options.standardize = false;
  const perception::DefaultFeaturizer raw(raw_options);
  auto seen_contexts = SeenFoodContexts(raw, plates, seed);
  if (!seen_contexts.ok()) return Fail(seen_contexts.status().ToString());
  const std::vector<std::vector<double>>& contexts = *seen_contexts;
  const int d = perception::kDefaultFeatureDim;
  std::vector<double> mean(d, 0.0), sd(d, 0.0);
  for (const auto& c : contexts) {
    for (int k = 0; k < d; ++k) mean[k] += c[k] / contexts.size();
  }
  for (const auto& c : contexts) {
    for (int k = 0; k < d; ++k) {
      sd[k] += (c[k] - mean[k]) * (c[k] - mean[k]) / contexts.size();
    }
  }
  for (double& s : sd) s = std::sqrt(s);

  std::string text = absl::StrFormat(
      "# bitewise default featurizer statistics: per-feature mean and sd of\n"
      "# the raw features, and E||c||^2 of the standardised contexts, on %d\n"
      "# items of the simulated world's seen foods (never the unseen\n"
      "# evaluation foods): %d plates, seed %d.\n"
      "# Regenerate: bitewise-featurizer-stats --plates=%d --seed=%d\n"
      "version 1\n",
      contexts.size(), plates, seed, plates, seed);
  for (int k = 0; k < d; ++k) {
    text += absl::StrFormat("feature %d %.9g %.9g\n", k, mean[k], sd[k]);
  }
  // E||c||^2 of the standardised contexts, through the featurizer's own
  // standardisation (parsed from what is about to be written).
  auto stats =
      perception::ParseDefaultFeaturizerStats(text + "mean_squared_norm 1\n");
  if (!stats.ok()) return Fail(stats.status().ToString());
  double msn = 0.0;
  for (std::vector<double> c : contexts) {
    perception::StandardizeDefaultFeatures(*stats, &c);
    double norm2 = 0.0;
    for (double v : c) norm2 += v * v;
    msn += norm2 / contexts.size();
  }
  text += absl::StrFormat("mean_squared_norm %.6g\n", msn);
  std::string out = absl::GetFlag(FLAGS_out);
  if (out.empty()) out = "models/featurizer/default_featurizer_stats.txt";
  if (!WriteFile(out, text)) return Fail("cannot write " + out);
  std::printf("%zu seen-food items; E||c||^2 standardised = %.3f; wrote %s\n",
              contexts.size(), msn, out.c_str());
  return 0;
}
