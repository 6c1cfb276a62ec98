// bitewise-sim-meals: the simulated-meals experiment of docs/experiments.md.
// For each seeded trial it draws one simulated meal (8 unseen foods x
// --attempts_per_food attempts; rendered plates, force traces, outcome
// draws) and plays it with context-only LinUCB and with post hoc LinUCB fed
// the haptic log-probabilities, probabilities and one-hot class. It writes
// the mean cumulative failures per attempt, their standard errors and the
// paired differences to --out, and a summary (with per-food failures) to
// stdout.
#include <array>
#include <chrono>
#include <cstdio>
#include <map>
#include <string>
#include <tuple>
#include <vector>

#include "absl/flags/flag.h"
#include "absl/flags/usage.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_split.h"
#include "experiments/csv_writer.h"
#include "experiments/sim_meals.h"
#include "experiments/trial_stats.h"
#include "services/common/flags_usage.h"
#include "services/domain/random.h"
#include "services/sim/food_catalog.h"

ABSL_FLAG(int, trials, 200, "Seeded trials (simulated meals).");
ABSL_FLAG(int, attempts_per_food, 8, "Attempts on each of the 8 foods.");
ABSL_FLAG(int, plates_per_trial, 0,
          "Rendered plates per trial; a food's j-th attempt uses its item on "
          "plate j mod this. 0: one per attempt (a new piece every time).");
ABSL_FLAG(std::string, order, "shuffled",
          "shuffled: the 8 x attempts_per_food attempts in a random order; "
          "blocked: all attempts on one food, then the next.");
ABSL_FLAG(bool, allow_touching, false, "Let items on a plate touch.");
ABSL_FLAG(double, alpha, 0.01, "LinUCB exploration weight.");
ABSL_FLAG(double, rho_c, 1.0,
          "Context ridge in observations: lambda_c = rho_c * E||c||^2 of the "
          "default featurizer on seen foods (the shipped default).");
ABSL_FLAG(double, lambda_c, 0.0,
          "Ridge on the context model, used as given; 0: from --rho_c.");
ABSL_FLAG(double, lambda_p, 1.0, "Ridge on the post hoc terms.");
ABSL_FLAG(double, phi_radius, bitewise::bandit::BanditConfig().phi_radius,
          "poLinUCB: radius of the predicted post hoc context's ball, per "
          "unit of sqrt(c^T X^-1 c) (docs/algorithms.md).");
ABSL_FLAG(double, thompson_v,
          bitewise::experiments::SimMealsConfig().thompson_v,
          "Thompson sampling's v (theta ~ N(theta_a, v^2 Sigma_a)).");
ABSL_FLAG(double, haptic_accuracy, 0.0,
          "Sensitivity: make HapticNet right with this probability (confident "
          "wrong answers otherwise); 0 uses the shipped model as it is.");
ABSL_FLAG(std::string, trace_story, "world",
          "Where the attempts' force/torque traces come from: world (the "
          "simulated robot's model) or a trace story HapticNet may never "
          "have seen: piecewise, mechanics, compliant, puncture, "
          "poroelastic, lattice.");
ABSL_FLAG(bool, keep_no_contact, false,
          "Keep a story's attempt whose trace never reaches contact, as the "
          "product meets it: no haptic class, no post hoc context (p = 0) "
          "for the post hoc learners. False: such a trace is drawn again.");
ABSL_FLAG(std::string, unfamiliar_posthoc,
          bitewise::domain::UnfamiliarPosthocName(
              bitewise::domain::kDefaultUnfamiliarPosthoc),
          "What the post hoc learners get for an attempt whose trace is "
          "scored unfamiliar: asis (HapticNet's answer), uniform (flattened) "
          "or zero (no post hoc context). Every run also plays post hoc "
          "LinUCB (logprob) under each of the three, paired with "
          "context-only.");
ABSL_FLAG(bool, force_limit, false,
          "Let each action's force limit halt the fork on the world's traces "
          "(10 N for TA0/TA90, 20 N for TV, 25 N for VS), as the robot does: "
          "an attempt's haptic answer is then HapticNet's on the trace the "
          "chosen action leaves. Every such run also plays post hoc LinUCB "
          "(logprob) under both --limit_reached_posthoc rules.");
ABSL_FLAG(std::string, limit_reached_posthoc, "zero",
          "With --force_limit, what the post hoc learners get for an attempt "
          "the limit halted: zero (no post hoc context, as for a bite without "
          "contact; the product's default for poLinUCB), uniform (flattened) "
          "or asis (HapticNet's answer on the cut trace; the product's "
          "default for post hoc LinUCB, the row \"post hoc, halted asis\").");
ABSL_FLAG(uint64_t, seed, 1,
          "Base seed; trial i uses a seed mixed from (seed, i).");
ABSL_FLAG(std::string, haptic_model, "",
          "HapticNet ONNX file; empty: the embedded "
          "models/hapticnet/hapticnet.onnx.");
ABSL_FLAG(std::string, out, "sim_meals.csv", "CSV file to write.");
ABSL_FLAG(std::string, spanet_model, "",
          "Featurize with this SPANet ONNX model (its <model>.stats gives the "
          "context scale) instead of the default featurizer.");
ABSL_FLAG(std::string, foods, "",
          "Comma-separated catalog foods of the meal; empty: the 8 unseen "
          "foods. E.g. banana_unripe in place of kiwi puts a look-alike pair "
          "(ripe and unripe banana) on the plate.");

namespace bitewise::experiments {
namespace {

constexpr std::array<HapticContext, 3> kHapticContexts = {
    HapticContext::kLogProbabilities, HapticContext::kProbabilities,
    HapticContext::kOneHot};

// One learner of the comparison. The first four (LinUCB) keep the CSV
// columns the plots read; the Thompson pair follows the expected curves.
struct LearnerSpec {
  std::string label;   // printed
  std::string column;  // CSV prefix
  bandit::Learner learner;
  HapticContext kind;  // ignored by context-only learners
  bandit::Strategy strategy;
  int baseline;  // the context-only spec it is paired with; -1: none
  // Other specs it is paired with (printed only).
  std::vector<int> versus = {};
  // What it gets for unfamiliar attempts; -1: --unfamiliar_posthoc.
  int unfamiliar = -1;
  // What it gets for attempts the force limit halted; -1:
  // --limit_reached_posthoc.
  int limit_rule = -1;
  // poLinUCB: missing post hoc contexts sent as its own prediction.
  bool impute = false;
};

std::vector<LearnerSpec> Learners(bool force_limit) {
  std::vector<LearnerSpec> specs = {
      {"context-only", "context_only", bandit::Learner::kContextOnly,
       HapticContext::kLogProbabilities, bandit::Strategy::kLinUcb, -1}};
  for (HapticContext kind : kHapticContexts) {
    specs.push_back({absl::StrCat("post hoc (", HapticContextName(kind), ")"),
                     absl::StrCat("posthoc_", HapticContextName(kind)),
                     bandit::Learner::kPostHoc, kind, bandit::Strategy::kLinUcb,
                     0});
  }
  specs.push_back(
      {"context-only TS", "context_only_ts", bandit::Learner::kContextOnly,
       HapticContext::kLogProbabilities, bandit::Strategy::kThompson, -1});
  const int ts_baseline = static_cast<int>(specs.size()) - 1;
  specs.push_back({"post hoc (logprob) TS", "posthoc_logprob_ts",
                   bandit::Learner::kPostHoc, HapticContext::kLogProbabilities,
                   bandit::Strategy::kThompson, ts_baseline});
  // Paired with context-only (the CSV) and with post hoc LinUCB (logprob).
  const int polinucb = static_cast<int>(specs.size());
  specs.push_back({"poLinUCB (logprob)",
                   "polinucb_logprob",
                   bandit::Learner::kPoLinUcb,
                   HapticContext::kLogProbabilities,
                   bandit::Strategy::kLinUcb,
                   0,
                   {1}});
  // The choice of what an unfamiliar attempt sends (docs/experiments.md,
  // "Unfamiliar traces"), each paired with context-only.
  for (domain::UnfamiliarPosthoc rule :
       {domain::UnfamiliarPosthoc::kAsIs, domain::UnfamiliarPosthoc::kUniform,
        domain::UnfamiliarPosthoc::kZero}) {
    specs.push_back(
        {absl::StrCat("post hoc, unfam. ", domain::UnfamiliarPosthocName(rule)),
         absl::StrCat("posthoc_logprob_unfamiliar_",
                      domain::UnfamiliarPosthocName(rule)),
         bandit::Learner::kPostHoc,
         HapticContext::kLogProbabilities,
         bandit::Strategy::kLinUcb,
         0,
         {},
         static_cast<int>(rule)});
  }
  // The same choice for poLinUCB, the default learner when added
  // (2026-12-06, before post hoc LinUCB became the default again),
  // each paired with context-only and with poLinUCB under
  // --unfamiliar_posthoc.
  for (domain::UnfamiliarPosthoc rule : {domain::UnfamiliarPosthoc::kUniform,
                                         domain::UnfamiliarPosthoc::kZero}) {
    specs.push_back(
        {absl::StrCat("poLinUCB, unfam. ", domain::UnfamiliarPosthocName(rule)),
         absl::StrCat("polinucb_logprob_unfamiliar_",
                      domain::UnfamiliarPosthocName(rule)),
         bandit::Learner::kPoLinUcb,
         HapticContext::kLogProbabilities,
         bandit::Strategy::kLinUcb,
         0,
         {polinucb},
         static_cast<int>(rule)});
  }
  // A study (docs/experiments.md, "A missing post hoc context for
  // poLinUCB"): poLinUCB sending its own prediction p_hat(c) where the meal
  // has no post hoc context (no contact; halted, under the zero rule),
  // paired with context-only, with poLinUCB sending p = 0 there, and with
  // post hoc LinUCB (logprob): the product's two learners.
  const int imputed = static_cast<int>(specs.size());
  specs.push_back({"poLinUCB, missing imputed",
                   "polinucb_logprob_imputed",
                   bandit::Learner::kPoLinUcb,
                   HapticContext::kLogProbabilities,
                   bandit::Strategy::kLinUcb,
                   0,
                   {polinucb, 1},
                   -1,
                   -1,
                   true});
  // The choice of what a halted attempt sends (docs/experiments.md, "A
  // trace the robot cut short"), for post hoc LinUCB and poLinUCB, each
  // paired with context-only, and "zero" with "asis" of the same learner.
  // Post hoc LinUCB with "asis", the product's default learner and its rule
  // since 2026-12-06, is also paired with "poLinUCB, missing imputed", a
  // poLinUCB person's bites (docs/experiments.md, "The learner default").
  if (force_limit) {
    for (const auto& [learner, name] :
         {std::pair{bandit::Learner::kPostHoc, "post hoc"},
          std::pair{bandit::Learner::kPoLinUcb, "poLinUCB"}}) {
      const int as_is = static_cast<int>(specs.size());
      for (domain::UnfamiliarPosthoc rule :
           {domain::UnfamiliarPosthoc::kAsIs,
            domain::UnfamiliarPosthoc::kZero}) {
        const bool zero = rule == domain::UnfamiliarPosthoc::kZero;
        specs.push_back(
            {absl::StrCat(name, ", halted ",
                          domain::UnfamiliarPosthocName(rule)),
             absl::StrCat(
                 learner == bandit::Learner::kPostHoc ? "posthoc" : "polinucb",
                 "_logprob_halted_", domain::UnfamiliarPosthocName(rule)),
             learner, HapticContext::kLogProbabilities,
             bandit::Strategy::kLinUcb, 0,
             zero                                   ? std::vector<int>{as_is}
             : learner == bandit::Learner::kPostHoc ? std::vector<int>{imputed}
                                                    : std::vector<int>{},
             -1, static_cast<int>(rule)});
      }
    }
  }
  return specs;
}
constexpr int kLinUcbLearners = 1 + kHapticContexts.size();

int Run() {
  SimMealsConfig config;
  config.attempts_per_food = absl::GetFlag(FLAGS_attempts_per_food);
  config.plates_per_trial = absl::GetFlag(FLAGS_plates_per_trial);
  config.allow_touching = absl::GetFlag(FLAGS_allow_touching);
  config.alpha = absl::GetFlag(FLAGS_alpha);
  config.lambda_c = absl::GetFlag(FLAGS_lambda_c);
  config.rho_c = absl::GetFlag(FLAGS_rho_c);
  config.thompson_v = absl::GetFlag(FLAGS_thompson_v);
  config.phi_radius = absl::GetFlag(FLAGS_phi_radius);
  config.haptic_accuracy = absl::GetFlag(FLAGS_haptic_accuracy);
  config.trace_story = absl::GetFlag(FLAGS_trace_story);
  config.keep_no_contact = absl::GetFlag(FLAGS_keep_no_contact);
  config.lambda_p = absl::GetFlag(FLAGS_lambda_p);
  config.force_limit = absl::GetFlag(FLAGS_force_limit);
  for (const auto& [flag, value, rule] :
       {std::tuple{"unfamiliar_posthoc",
                   absl::GetFlag(FLAGS_unfamiliar_posthoc),
                   &config.unfamiliar_posthoc},
        std::tuple{"limit_reached_posthoc",
                   absl::GetFlag(FLAGS_limit_reached_posthoc),
                   &config.limit_reached_posthoc}}) {
    absl::StatusOr<domain::UnfamiliarPosthoc> parsed =
        domain::ParseUnfamiliarPosthoc(value);
    if (!parsed.ok()) {
      absl::FPrintF(stderr, "--%s: %s\n", flag, parsed.status().message());
      return 2;
    }
    *rule = *parsed;
  }
  const std::string order = absl::GetFlag(FLAGS_order);
  if (order == "shuffled") {
    config.order = MealOrder::kShuffled;
  } else if (order == "blocked") {
    config.order = MealOrder::kBlocked;
  } else {
    absl::FPrintF(stderr, "--order must be shuffled or blocked, not %s\n",
                  order);
    return 2;
  }
  const int trials = absl::GetFlag(FLAGS_trials);
  const absl::Status valid = ValidateSimMealsConfig(config);
  if (trials < 1 || !valid.ok()) {
    absl::FPrintF(stderr, "bad flags: %s\n",
                  trials < 1 ? "--trials must be positive" : valid.ToString());
    return 2;
  }
  const std::string foods_flag = absl::GetFlag(FLAGS_foods);
  if (!foods_flag.empty()) {
    config.food_names = absl::StrSplit(foods_flag, ',', absl::SkipEmpty());
  }
  auto simulator = SimMealsSimulator::Create(absl::GetFlag(FLAGS_haptic_model),
                                             absl::GetFlag(FLAGS_spanet_model));
  if (!simulator.ok()) {
    absl::FPrintF(stderr, "cannot load the models: %s\n",
                  simulator.status().ToString());
    return 1;
  }

  config.context_msn = (*simulator)->featurizer().context_mean_squared_norm();
  if (!(config.context_msn > 0.0) && config.lambda_c <= 0.0) {
    absl::FPrintF(stderr,
                  "the featurizer declares no E||c||^2 (a SPANet without "
                  "<model>.stats?): pass --lambda_c\n");
    return 2;
  }
  const absl::StatusOr<std::vector<const sim::FoodType*>> meal_foods =
      MealFoods(config);
  if (!meal_foods.ok()) {
    absl::FPrintF(stderr, "--foods: %s\n", meal_foods.status().ToString());
    return 2;
  }
  const std::vector<const sim::FoodType*>& foods = *meal_foods;
  const int num_foods = static_cast<int>(foods.size());
  const std::vector<LearnerSpec> learners = Learners(config.force_limit);
  const int kLearners = static_cast<int>(learners.size());
  const auto start = std::chrono::steady_clock::now();
  double world_seconds = 0.0;
  // curves[learner][trial]; diffs[learner][trial] = its context-only
  // baseline minus it (post hoc learners only).
  std::vector<std::vector<std::vector<double>>> curves(kLearners);
  std::vector<std::vector<std::vector<double>>> diffs(kLearners);
  // versus_diffs[learner][k][trial]: the k-th versus spec's failures minus
  // the learner's (a curve of one value).
  std::vector<std::vector<std::vector<std::vector<double>>>> versus_diffs(
      kLearners);
  for (int learner = 0; learner < kLearners; ++learner) {
    versus_diffs[learner].resize(learners[learner].versus.size());
  }
  std::vector<std::vector<double>> oracle, uniform;
  // failures_by_food[learner][food], summed over trials.
  std::vector<std::vector<double>> failures_by_food(
      kLearners, std::vector<double>(num_foods, 0.0));
  // Per force limit: attempts it would halt, and HapticNet's right answers
  // on the traces it leaves.
  std::map<double, std::pair<int64_t, int64_t>> halted_by_limit;
  // Attempts the force limit halted, per learner, summed over trials.
  std::vector<int64_t> limit_reached(kLearners, 0);
  int64_t haptic_correct = 0, haptic_total = 0;
  // Attempts scored unfamiliar, and how many of them HapticNet got right.
  int64_t unfamiliar_total = 0, unfamiliar_correct = 0;
  bool scored = false;
  int plate_redraws = 0;
  // Story traces drawn again for want of contact; attempts kept without.
  int64_t story_redraws = 0, no_contact = 0;
  // Scale of what the learners see, against the ridges: mean squared norm
  // of the visual context and of each form of the haptic context.
  double context_norm2 = 0.0;
  std::array<double, kHapticContexts.size()> posthoc_norm2{};
  for (int trial = 0; trial < trials; ++trial) {
    const uint64_t seed = random::MixSeed(absl::GetFlag(FLAGS_seed), trial);
    const auto world_start = std::chrono::steady_clock::now();
    absl::StatusOr<SimMealWorld> world = (*simulator)->DrawWorld(config, seed);
    world_seconds += std::chrono::duration<double>(
                         std::chrono::steady_clock::now() - world_start)
                         .count();
    if (!world.ok()) {
      absl::FPrintF(stderr, "trial %d: %s\n", trial, world.status().ToString());
      return 1;
    }
    plate_redraws += world->plate_redraws;
    story_redraws += world->story_redraws;
    no_contact += world->no_contact;
    for (const SimAttempt& attempt : world->attempts) {
      for (double v : attempt.context) context_norm2 += v * v;
      for (size_t v = 0; v < kHapticContexts.size(); ++v) {
        for (double x : AttemptPosthoc(attempt, kHapticContexts[v],
                                       config.unfamiliar_posthoc)) {
          posthoc_norm2[v] += x * x;
        }
      }
      if (!attempt.contact) continue;
      for (const SimAttempt::Limited& limited : attempt.limited) {
        auto& [reached, right] = halted_by_limit[limited.limit_n];
        if (!limited.reached) continue;
        ++reached;
        right += static_cast<int>(limited.haptic.category) ==
                 static_cast<int>(foods[attempt.food]->category);
      }
      const bool correct = static_cast<int>(attempt.haptic.category) ==
                           static_cast<int>(foods[attempt.food]->category);
      haptic_correct += correct;
      ++haptic_total;
      scored = scored || attempt.haptic.has_familiarity;
      if (attempt.haptic.has_familiarity &&
          attempt.haptic.familiarity.unfamiliar) {
        ++unfamiliar_total;
        unfamiliar_correct += correct;
      }
    }
    oracle.push_back(OracleExpectedFailures(*world));
    uniform.push_back(UniformExpectedFailures(*world));
    for (int learner = 0; learner < kLearners; ++learner) {
      const LearnerSpec& spec = learners[learner];
      SimMealsConfig learner_config = config;
      if (spec.unfamiliar >= 0) {
        learner_config.unfamiliar_posthoc =
            static_cast<domain::UnfamiliarPosthoc>(spec.unfamiliar);
      }
      if (spec.limit_rule >= 0) {
        learner_config.limit_reached_posthoc =
            static_cast<domain::UnfamiliarPosthoc>(spec.limit_rule);
      }
      learner_config.impute_missing_posthoc = spec.impute;
      absl::StatusOr<SimMealRun> run = RunSimMealTrial(
          learner_config, *world, spec.learner, spec.kind, seed, spec.strategy);
      if (!run.ok()) {
        absl::FPrintF(stderr, "trial %d, %s: %s\n", trial, spec.label,
                      run.status().ToString());
        return 1;
      }
      limit_reached[learner] += run->limit_reached;
      for (size_t t = 0; t < run->failed.size(); ++t) {
        failures_by_food[learner][world->attempts[t].food] += run->failed[t];
      }
      curves[learner].push_back(std::move(run->cumulative_failures));
    }
    for (int learner = 0; learner < kLearners; ++learner) {
      const int baseline = learners[learner].baseline;
      if (baseline >= 0) {
        diffs[learner].push_back(
            Difference(curves[baseline].back(), curves[learner].back()));
      }
      for (size_t k = 0; k < learners[learner].versus.size(); ++k) {
        const int versus = learners[learner].versus[k];
        versus_diffs[learner][k].push_back(
            {curves[versus].back().back() - curves[learner].back().back()});
      }
    }
    const double secs =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start)
            .count();
    absl::FPrintF(stderr,
                  "trial %d/%d: failures context-only %.0f, post hoc "
                  "logprob/prob/onehot %.0f/%.0f/%.0f (%.1f s)\n",
                  trial + 1, trials, curves[0].back().back(),
                  curves[1].back().back(), curves[2].back().back(),
                  curves[3].back().back(), secs);
  }

  const int attempts = static_cast<int>(curves[0].front().size());
  std::vector<double> attempt_index(attempts);
  for (int t = 0; t < attempts; ++t) attempt_index[t] = t + 1;
  std::vector<std::string> header = {"attempt"};
  std::vector<std::vector<double>> columns = {attempt_index};
  std::vector<CurveSummary> summaries(kLearners);
  std::vector<CurveSummary> diff_summaries(kLearners);
  for (int learner = 0; learner < kLearners; ++learner) {
    summaries[learner] = SummarizeCurves(curves[learner]);
    if (learners[learner].baseline >= 0) {
      diff_summaries[learner] = SummarizeCurves(diffs[learner]);
    }
  }
  auto add_column = [&](const std::string& name, const CurveSummary& curve) {
    header.push_back(name + "_mean");
    header.push_back(name + "_se");
    columns.push_back(curve.mean);
    columns.push_back(curve.standard_error);
  };
  // LinUCB learners, their differences, the expected curves, then the rest
  // (the plot scripts read columns by position).
  for (int learner = 0; learner < kLinUcbLearners; ++learner) {
    add_column(learners[learner].column, summaries[learner]);
  }
  for (int learner = 1; learner < kLinUcbLearners; ++learner) {
    add_column(absl::StrCat("diff_", HapticContextName(learners[learner].kind)),
               diff_summaries[learner]);
  }
  header.push_back("oracle_expected");
  const std::vector<double> oracle_mean = SummarizeCurves(oracle).mean;
  columns.push_back(oracle_mean);
  header.push_back("uniform_expected");
  const std::vector<double> uniform_mean = SummarizeCurves(uniform).mean;
  columns.push_back(uniform_mean);
  for (int learner = kLinUcbLearners; learner < kLearners; ++learner) {
    add_column(learners[learner].column, summaries[learner]);
    if (learners[learner].baseline >= 0) {
      add_column("diff_" + learners[learner].column, diff_summaries[learner]);
    }
  }
  const std::string path = absl::GetFlag(FLAGS_out);
  const absl::Status written = WriteCsvColumns(path, header, columns);
  if (!written.ok()) {
    absl::FPrintF(stderr, "%s\n", written.ToString());
    return 1;
  }

  const double total_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start)
          .count();
  const int last = attempts - 1;
  absl::PrintF(
      "simulated meals: %d trials x %d attempts (%d foods x %d, %s order, %d "
      "plate(s) per trial), alpha=%g lambda_c=%g (rho_c %g) lambda_p=%g, "
      "Thompson v=%g, poLinUCB phi_radius=%g, seed %d\n",
      trials, attempts, num_foods, config.attempts_per_food, order,
      ResolvedPlatesPerTrial(config), config.alpha, ResolvedLambdaC(config),
      ResolvedLambdaC(config) / config.context_msn, config.lambda_p,
      config.thompson_v, config.phi_radius, absl::GetFlag(FLAGS_seed));
  absl::PrintF(
      "plates drawn again because a food did not fit or was not visible: "
      "%d of %d\n",
      plate_redraws, plate_redraws + trials * ResolvedPlatesPerTrial(config));
  const double all_attempts = static_cast<double>(haptic_total + no_contact);
  if (config.trace_story != "world") {
    absl::PrintF(
        "story traces drawn again for want of contact: %d; attempts kept "
        "without contact (--keep_no_contact; no post hoc context): %d of "
        "%d\n",
        story_redraws, no_contact, haptic_total + no_contact);
  }
  absl::PrintF("HapticNet category accuracy on the attempts' traces: %.2f%%\n",
               100.0 * haptic_correct / haptic_total);
  if (scored) {
    absl::PrintF(
        "attempts scored unfamiliar: %.2f%% (HapticNet right on %.2f%% of "
        "them, %.2f%% of the others); post hoc learners given %s for them "
        "(--unfamiliar_posthoc)\n",
        100.0 * unfamiliar_total / haptic_total,
        unfamiliar_total > 0 ? 100.0 * unfamiliar_correct / unfamiliar_total
                             : 0.0,
        haptic_total > unfamiliar_total
            ? 100.0 * (haptic_correct - unfamiliar_correct) /
                  (haptic_total - unfamiliar_total)
            : 0.0,
        domain::UnfamiliarPosthocName(config.unfamiliar_posthoc));
  } else {
    absl::PrintF("no familiarity score (no familiarity model beside %s)\n",
                 absl::GetFlag(FLAGS_haptic_model));
  }
  absl::PrintF(
      "mean squared norm: visual context (d_c = %d) %.2f; haptic context "
      "logprob %.1f, prob %.3f, onehot %.3f\n",
      (*simulator)->featurizer().dimension(), context_norm2 / all_attempts,
      posthoc_norm2[0] / all_attempts, posthoc_norm2[1] / all_attempts,
      posthoc_norm2[2] / all_attempts);
  absl::PrintF(
      "expected failures over the meal: best action every time %.2f, uniform "
      "random %.2f\n",
      oracle_mean[last], uniform_mean[last]);
  absl::PrintF(
      "cumulative failures after %d attempts (mean, 95%% interval = mean +- "
      "1.96 s.e.):\n",
      attempts);
  const double uniform_last = uniform_mean[last];
  for (int learner = 0; learner < kLearners; ++learner) {
    const double m = summaries[learner].mean[last];
    const double h = 1.96 * summaries[learner].standard_error[last];
    absl::PrintF("  %-22s %6.2f [%.2f, %.2f] (%+.1f%% vs uniform)",
                 learners[learner].label, m, m - h, m + h,
                 100.0 * (m - uniform_last) / uniform_last);
    if (learners[learner].baseline >= 0) {
      const CurveSummary& d = diff_summaries[learner];
      const double dh = 1.96 * d.standard_error[last];
      absl::PrintF(
          "   paired context-only minus this: %+.2f [%+.2f, %+.2f] (%+.1f%% "
          "of context-only)",
          d.mean[last], d.mean[last] - dh, d.mean[last] + dh,
          100.0 * d.mean[last] /
              summaries[learners[learner].baseline].mean[last]);
    }
    for (size_t k = 0; k < learners[learner].versus.size(); ++k) {
      const int versus = learners[learner].versus[k];
      const CurveSummary v = SummarizeCurves(versus_diffs[learner][k]);
      const double half = 1.96 * v.standard_error[0];
      absl::PrintF("   paired %s minus this: %+.2f [%+.2f, %+.2f]",
                   learners[versus].label, v.mean[0], v.mean[0] - half,
                   v.mean[0] + half);
    }
    absl::PrintF("\n");
  }
  for (const auto& [limit_n, counts] : halted_by_limit) {
    absl::PrintF(
        "a %g N force limit halts the fork on %.2f%% of the attempts; "
        "HapticNet right on %.2f%% of the traces it leaves\n",
        limit_n, 100.0 * counts.first / haptic_total,
        counts.first > 0 ? 100.0 * counts.second / counts.first : 0.0);
  }
  if (config.force_limit) {
    absl::PrintF(
        "attempts the chosen action's force limit halted (--force_limit; "
        "mean per meal), post hoc learners given %s for them "
        "(--limit_reached_posthoc):\n",
        domain::UnfamiliarPosthocName(config.limit_reached_posthoc));
    for (int learner = 0; learner < kLearners; ++learner) {
      absl::PrintF("  %-22s %6.2f\n", learners[learner].label,
                   static_cast<double>(limit_reached[learner]) / trials);
    }
  }
  absl::PrintF("failures per food (mean per trial, out of %d attempts):\n",
               config.attempts_per_food);
  absl::PrintF("  %-14s", "food");
  for (int learner = 0; learner < kLearners; ++learner) {
    absl::PrintF(" %22s", learners[learner].label);
  }
  absl::PrintF("\n");
  for (int food = 0; food < num_foods; ++food) {
    absl::PrintF("  %-14s", foods[food]->name);
    for (int learner = 0; learner < kLearners; ++learner) {
      absl::PrintF(" %22.2f", failures_by_food[learner][food] / trials);
    }
    absl::PrintF("\n");
  }
  absl::PrintF(
      "run time %.1f s (drawing the worlds: rendering, featurizing, "
      "classifying %.1f s); wrote %s\n",
      total_seconds, world_seconds, path);
  return 0;
}

}  // namespace
}  // namespace bitewise::experiments

int main(int argc, char** argv) {
  absl::SetProgramUsageMessage(
      "Simulated meals: post hoc vs context-only LinUCB failures on the 8 "
      "unseen foods (docs/experiments.md).");
  bitewise::ShowOwnFlagsInHelp();
  bitewise::ParseFlagsOnly(argc, argv);
  return bitewise::experiments::Run();
}
