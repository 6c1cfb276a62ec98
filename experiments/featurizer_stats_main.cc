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
ABSL_FLAG(bool, appearance_report, false,
          "Instead of writing statistics, report how much the shipped "
          "(standardised) features say about an unseen food's haptic "
          "category: each unseen piece's nearest seen-food centroid.");

namespace {

using bitewise::experiments::FeaturizeScene;
namespace perception = bitewise::perception;
namespace sim = bitewise::sim;

int Fail(const std::string& what) {
  std::fprintf(stderr, "bitewise-featurizer-stats: %s\n", what.c_str());
  return 1;
}

struct FoodContext {
  const sim::FoodType* food;
  std::vector<double> context;
};

// Contexts of every visible item on `plates` plates of `foods`.
absl::StatusOr<std::vector<FoodContext>> FoodContexts(
    const std::vector<const sim::FoodType*>& foods,
    const perception::Featurizer& featurizer, int plates, uint64_t seed) {
  std::mt19937_64 plate_rng(bitewise::random::MixSeed(seed, 1));
  std::vector<FoodContext> contexts;
  for (int plate = 0; plate < plates; ++plate) {
    const sim::PlateScene scene =
        sim::RandomPlate(foods, /*allow_touching=*/false, plate_rng);
    auto featurized = FeaturizeScene(
        scene, bitewise::random::MixSeed(seed, 100 + plate), featurizer);
    if (!featurized.ok()) return featurized.status();
    for (size_t i = 0; i < featurized->size(); ++i) {
      if ((*featurized)[i].empty()) continue;
      contexts.push_back({scene.items[i].food, std::move((*featurized)[i])});
    }
  }
  return contexts;
}

// Contexts of every visible item on `plates` plates of seen foods.
absl::StatusOr<std::vector<std::vector<double>>> SeenFoodContexts(
    const perception::Featurizer& featurizer, int plates, uint64_t seed) {
  auto contexts = FoodContexts(sim::SeenFoods(), featurizer, plates, seed);
  if (!contexts.ok()) return contexts.status();
  std::vector<std::vector<double>> out;
  for (FoodContext& c : *contexts) out.push_back(std::move(c.context));
  return out;
}

double Cosine(const std::vector<double>& a, const std::vector<double>& b) {
  double ab = 0.0, aa = 0.0, bb = 0.0;
  for (size_t k = 0; k < a.size(); ++k) {
    ab += a[k] * b[k];
    aa += a[k] * a[k];
    bb += b[k] * b[k];
  }
  return ab / std::sqrt(aa * bb);
}

double SquaredDistance(const std::vector<double>& a,
                       const std::vector<double>& b) {
  double s = 0.0;
  for (size_t k = 0; k < a.size(); ++k) s += (a[k] - b[k]) * (a[k] - b[k]);
  return s;
}

// How informative the shipped features are about an unseen food's haptic
// category: the seen foods' centroids (plates of seen foods, `seed`) and,
// for each unseen piece (plates of unseen foods, another seed range), the
// category of the nearest seen-food centroid. Chance is 1 in 4.
int AppearanceReport(int plates, uint64_t seed) {
  const perception::DefaultFeaturizer featurizer;  // standardised, as shipped
  auto seen = FoodContexts(sim::SeenFoods(), featurizer, plates, seed);
  if (!seen.ok()) return Fail(seen.status().ToString());
  auto unseen = FoodContexts(sim::UnseenFoods(), featurizer, plates,
                             bitewise::random::MixSeed(seed, 2));
  if (!unseen.ok()) return Fail(unseen.status().ToString());
  auto centroids = [](const std::vector<FoodContext>& contexts,
                      const std::vector<const sim::FoodType*>& foods) {
    std::vector<std::vector<double>> out(foods.size());
    for (size_t f = 0; f < foods.size(); ++f) {
      int n = 0;
      for (const FoodContext& c : contexts) {
        if (c.food != foods[f]) continue;
        if (out[f].empty()) out[f].assign(c.context.size(), 0.0);
        for (size_t k = 0; k < c.context.size(); ++k) {
          out[f][k] += c.context[k];
        }
        ++n;
      }
      for (double& v : out[f]) v /= n;
    }
    return out;
  };
  const std::vector<const sim::FoodType*> seen_foods = sim::SeenFoods();
  const std::vector<const sim::FoodType*> unseen_foods = sim::UnseenFoods();
  const auto seen_centroids = centroids(*seen, seen_foods);
  const auto unseen_centroids = centroids(*unseen, unseen_foods);
  std::printf(
      "Appearance of the unseen foods through the shipped default features\n"
      "(standardised; seen-food plates seed %llu, unseen-food plates a "
      "seed mixed from it; %d plates each). Per unseen food: its pieces'\n"
      "nearest seen-food centroid's category (right = the food's own "
      "category; chance 25%%), the seen food its centroid is nearest to,\n"
      "and their cosine; and the most alike other unseen food (centroid "
      "cosine).\n\n",
      static_cast<unsigned long long>(seed), plates);
  std::printf("%-14s %-10s %7s %6s  %-14s %-10s %6s  %-14s %-10s %6s\n",
              "unseen food", "category", "pieces", "right", "nearest seen",
              "its cat.", "cosine", "most alike", "its cat.", "cosine");
  int total = 0, right_total = 0, foods_right = 0;
  for (size_t u = 0; u < unseen_foods.size(); ++u) {
    int pieces = 0, right = 0;
    for (const FoodContext& c : *unseen) {
      if (c.food != unseen_foods[u]) continue;
      size_t best = 0;
      for (size_t s = 1; s < seen_foods.size(); ++s) {
        if (SquaredDistance(c.context, seen_centroids[s]) <
            SquaredDistance(c.context, seen_centroids[best])) {
          best = s;
        }
      }
      ++pieces;
      right += seen_foods[best]->category == unseen_foods[u]->category;
    }
    size_t nearest = 0;
    for (size_t s = 1; s < seen_foods.size(); ++s) {
      if (SquaredDistance(unseen_centroids[u], seen_centroids[s]) <
          SquaredDistance(unseen_centroids[u], seen_centroids[nearest])) {
        nearest = s;
      }
    }
    foods_right += seen_foods[nearest]->category == unseen_foods[u]->category;
    // The most similar other unseen food: a look-alike on the plate.
    size_t alike = u == 0 ? 1 : 0;
    for (size_t v = 0; v < unseen_foods.size(); ++v) {
      if (v != u && Cosine(unseen_centroids[u], unseen_centroids[v]) >
                        Cosine(unseen_centroids[u], unseen_centroids[alike])) {
        alike = v;
      }
    }
    total += pieces;
    right_total += right;
    std::printf(
        "%-14s %-10s %7d %5.1f%%  %-14s %-10s %6.3f  %-14s %-10s %6.3f\n",
        unseen_foods[u]->name.c_str(),
        bitewise::domain::HapticClassName(unseen_foods[u]->category), pieces,
        100.0 * right / pieces, seen_foods[nearest]->name.c_str(),
        bitewise::domain::HapticClassName(seen_foods[nearest]->category),
        Cosine(unseen_centroids[u], seen_centroids[nearest]),
        unseen_foods[alike]->name.c_str(),
        bitewise::domain::HapticClassName(unseen_foods[alike]->category),
        Cosine(unseen_centroids[u], unseen_centroids[alike]));
  }
  std::printf(
      "\nall unseen pieces: %d, nearest seen centroid of the right category "
      "%.1f%%; foods whose centroid is nearest a seen food of their own "
      "category: %d of %zu\n",
      total, 100.0 * right_total / total, foods_right, unseen_foods.size());
  return 0;
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
  bitewise::ParseFlagsOnly(argc, argv);
  const int plates = absl::GetFlag(FLAGS_plates);
  const uint64_t seed = absl::GetFlag(FLAGS_seed);
  if (plates < 10) return Fail("--plates must be at least 10");
  if (absl::GetFlag(FLAGS_appearance_report)) {
    return AppearanceReport(plates, seed);
  }

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
