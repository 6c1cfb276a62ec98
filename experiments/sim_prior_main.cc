// bitewise-sim-prior: the population prior in the simulated world. In each
// of --facilities facilities, --pool_users people eat --pool_meals meals
// each (post hoc LinUCB at the product's defaults), their models are pooled
// (bandit::PooledPrior: only their sufficient statistics), and then
// --new_users new people each eat a first meal of the eight unseen foods,
// once without the prior and once with it (paired: the same world, pieces,
// traces and outcome coins). --pool_foods=seen makes the pooled people eat
// only seen foods, none of the new person's foods.
#include <cmath>
#include <cstdio>
#include <optional>
#include <string>
#include <vector>

#include "absl/flags/flag.h"
#include "absl/flags/usage.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_split.h"
#include "experiments/sim_meals.h"
#include "experiments/trial_stats.h"
#include "services/bandit/core/learners.h"
#include "services/bandit/core/population_prior.h"
#include "services/common/flags_usage.h"
#include "services/domain/random.h"
#include "services/sim/food_catalog.h"

ABSL_FLAG(int, facilities, 4, "Independent facilities (pools).");
ABSL_FLAG(int, pool_users, 20, "People pooled per facility.");
ABSL_FLAG(int, pool_meals, 3, "Meals each pooled person has eaten.");
ABSL_FLAG(int, new_users, 50, "New people per facility (paired meals).");
ABSL_FLAG(std::string, prior_rounds, "16",
          "Comma-separated prior weights n_0 (rounds the prior is worth).");
ABSL_FLAG(std::string, pool_foods, "unseen",
          "What the pooled people eat: unseen (the new person's foods too) "
          "or seen (none of them).");
ABSL_FLAG(uint64_t, seed, 1, "Base seed.");

namespace bitewise::experiments {
namespace {

// Mean and 95% half-width (1.96 standard errors) of one value per person.
struct Interval {
  double mean;
  double half_width;
};
Interval MeanInterval(const std::vector<double>& values) {
  std::vector<std::vector<double>> curves;
  for (double v : values) curves.push_back({v});
  const CurveSummary summary = SummarizeCurves(curves);
  return {summary.mean[0], 1.96 * summary.standard_error[0]};
}

int Run() {
  std::vector<double> weights;
  for (absl::string_view w :
       absl::StrSplit(absl::GetFlag(FLAGS_prior_rounds), ',')) {
    double n0 = 0;
    if (!absl::SimpleAtod(w, &n0) || !(n0 > 0)) {
      absl::FPrintF(stderr, "--prior_rounds: bad weight \"%s\"\n", w);
      return 2;
    }
    weights.push_back(n0);
  }
  const std::string pool_foods = absl::GetFlag(FLAGS_pool_foods);
  if (pool_foods != "unseen" && pool_foods != "seen") {
    absl::FPrintF(stderr, "--pool_foods must be unseen or seen\n");
    return 2;
  }
  auto simulator = SimMealsSimulator::Create("");
  if (!simulator.ok()) {
    absl::FPrintF(stderr, "%s\n", simulator.status().ToString());
    return 1;
  }
  SimMealsConfig meal;  // the product's defaults, unseen foods
  SimMealsConfig pool_meal = meal;
  if (pool_foods == "seen") {
    for (const sim::FoodType* food : sim::SeenFoods()) {
      pool_meal.food_names.push_back(food->name);
    }
  }
  const uint64_t base = absl::GetFlag(FLAGS_seed);
  const int facilities = absl::GetFlag(FLAGS_facilities);
  const int pool_users = absl::GetFlag(FLAGS_pool_users);
  const int pool_meals = absl::GetFlag(FLAGS_pool_meals);
  const int new_users = absl::GetFlag(FLAGS_new_users);
  if (facilities < 1 || pool_users < 1 || pool_meals < 1 || new_users < 2) {
    absl::FPrintF(stderr, "counts must be positive (new_users >= 2)\n");
    return 2;
  }
  std::vector<double> without;
  std::vector<std::vector<double>> with(weights.size()), diff(weights.size());
  for (int f = 0; f < facilities; ++f) {
    const uint64_t facility_seed = random::MixSeed(base, 1000 + f);
    std::vector<std::unique_ptr<bandit::LearnerModel>> pool;
    for (int u = 0; u < pool_users; ++u) {
      const uint64_t user_seed = random::MixSeed(facility_seed, u);
      std::unique_ptr<bandit::LearnerModel> model;
      int64_t rounds = 0;
      for (int m = 0; m < pool_meals; ++m) {
        auto world =
            (*simulator)->DrawWorld(pool_meal, random::MixSeed(user_seed, m));
        if (!world.ok()) {
          absl::FPrintF(stderr, "%s\n", world.status().ToString());
          return 1;
        }
        if (!model) {
          auto created = bandit::CreateModel(SimUserConfig(
              meal, bandit::Learner::kPostHoc, bandit::Strategy::kLinUcb,
              static_cast<int>(world->attempts.front().context.size()),
              user_seed));
          if (!created.ok()) return 1;
          model = *std::move(created);
        }
        auto run = PlaySimMeal(*world, HapticContext::kLogProbabilities,
                               user_seed, rounds, *model);
        if (!run.ok()) return 1;
        rounds += static_cast<int64_t>(world->attempts.size());
      }
      pool.push_back(std::move(model));
    }
    std::vector<const bandit::LearnerModel*> pointers;
    for (const auto& m : pool) pointers.push_back(m.get());
    std::vector<bandit::PopulationPrior> priors;
    for (double n0 : weights) {
      auto prior = bandit::PooledPrior(pointers, n0, /*pool_version=*/1);
      if (!prior.ok()) {
        absl::FPrintF(stderr, "%s\n", prior.status().ToString());
        return 1;
      }
      priors.push_back(*std::move(prior));
    }
    for (int i = 0; i < new_users; ++i) {
      const uint64_t seed = random::MixSeed(facility_seed, 100000 + i);
      auto world = (*simulator)->DrawWorld(meal, seed);
      if (!world.ok()) return 1;
      auto plain = RunSimMealTrial(meal, *world, bandit::Learner::kPostHoc,
                                   HapticContext::kLogProbabilities, seed);
      if (!plain.ok()) return 1;
      const double base_failures = plain->cumulative_failures.back();
      without.push_back(base_failures);
      for (size_t w = 0; w < weights.size(); ++w) {
        auto model = bandit::CreateModel(SimUserConfig(
            meal, bandit::Learner::kPostHoc, bandit::Strategy::kLinUcb,
            static_cast<int>(world->attempts.front().context.size()), seed,
            priors[w]));
        if (!model.ok()) return 1;
        auto run = PlaySimMeal(*world, HapticContext::kLogProbabilities, seed,
                               0, **model);
        if (!run.ok()) return 1;
        with[w].push_back(run->cumulative_failures.back());
        diff[w].push_back(base_failures - run->cumulative_failures.back());
      }
    }
    absl::FPrintF(stderr, "facility %d/%d done\n", f + 1, facilities);
  }
  absl::PrintF(
      "population prior: %d facilities x (%d pooled people x %d meals of %s "
      "foods), %d new people each (first meal: 8 unseen foods x 8), post hoc "
      "LinUCB (logprob) at the product's defaults, seed %d\n",
      facilities, pool_users, pool_meals, pool_foods, new_users, base);
  absl::PrintF(
      "new person's first-meal failures (of 64; mean, 95%% interval):\n");
  const Interval plain = MeanInterval(without);
  absl::PrintF("  without the prior        %6.2f [%.2f, %.2f]\n", plain.mean,
               plain.mean - plain.half_width, plain.mean + plain.half_width);
  for (size_t w = 0; w < weights.size(); ++w) {
    const Interval primed = MeanInterval(with[w]);
    const Interval d = MeanInterval(diff[w]);
    absl::PrintF(
        "  with the prior, n0 = %-4g %6.2f [%.2f, %.2f]   paired without "
        "minus with: %+.2f [%+.2f, %+.2f] (%+.1f%% fewer)\n",
        weights[w], primed.mean, primed.mean - primed.half_width,
        primed.mean + primed.half_width, d.mean, d.mean - d.half_width,
        d.mean + d.half_width, 100.0 * d.mean / plain.mean);
  }
  return 0;
}

}  // namespace
}  // namespace bitewise::experiments

int main(int argc, char** argv) {
  absl::SetProgramUsageMessage(
      "Simulated meals: a new person's first meal with and without the "
      "population prior.");
  bitewise::ShowOwnFlagsInHelp();
  bitewise::ParseFlagsOnly(argc, argv);
  return bitewise::experiments::Run();
}
