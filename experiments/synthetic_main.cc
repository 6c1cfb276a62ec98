// bitewise-synthetic: the synthetic experiment of docs/experiments.md. For each
// d_c it runs `trials` seeded trials of context-only and post hoc LinUCB on
// the same worlds and writes the mean cumulative regret, its standard error
// and the paired difference to <out_dir>/synthetic_dc<d>.csv.
#include <chrono>
#include <cstdio>
#include <string>
#include <vector>

#include "absl/flags/flag.h"
#include "absl/flags/usage.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "experiments/csv_writer.h"
#include "experiments/synthetic.h"
#include "experiments/trial_stats.h"
#include "services/common/flags_usage.h"
#include "services/domain/random.h"

ABSL_FLAG(std::vector<std::string>, context_dims,
          std::vector<std::string>({"10", "100"}),
          "Values of d_c to run, comma separated.");
ABSL_FLAG(int, trials, 40, "Trials per d_c.");
ABSL_FLAG(int, rounds, 1000, "Rounds per trial.");
ABSL_FLAG(int, num_actions, 10, "K.");
ABSL_FLAG(int, posthoc_dim, 3, "d_p.");
ABSL_FLAG(std::string, loss, "linear",
          "linear: the loss is phi_a^T p itself; bernoulli: a 0/1 loss with "
          "that mean.");
ABSL_FLAG(double, alpha, 0.01, "LinUCB exploration weight.");
ABSL_FLAG(double, lambda_c, 1000.0, "Ridge on the context model.");
ABSL_FLAG(double, lambda_p, 1.0, "Ridge on the post hoc terms.");
ABSL_FLAG(double, phi_radius, bitewise::bandit::BanditConfig().phi_radius,
          "poLinUCB: radius of the predicted post hoc context's ball.");
ABSL_FLAG(uint64_t, seed, 1,
          "Base seed; trial i of d_c uses a seed mixed "
          "from (seed, d_c, i).");
ABSL_FLAG(std::string, out_dir, ".", "Directory for the CSV files.");

namespace bitewise::experiments {
namespace {

int Run() {
  SyntheticConfig config;
  config.rounds = absl::GetFlag(FLAGS_rounds);
  config.num_actions = absl::GetFlag(FLAGS_num_actions);
  config.posthoc_dim = absl::GetFlag(FLAGS_posthoc_dim);
  config.alpha = absl::GetFlag(FLAGS_alpha);
  config.lambda_c = absl::GetFlag(FLAGS_lambda_c);
  config.lambda_p = absl::GetFlag(FLAGS_lambda_p);
  config.phi_radius = absl::GetFlag(FLAGS_phi_radius);
  const std::string loss = absl::GetFlag(FLAGS_loss);
  if (loss == "linear") {
    config.loss = SyntheticLoss::kLinear;
  } else if (loss == "bernoulli") {
    config.loss = SyntheticLoss::kBernoulli;
  } else {
    absl::FPrintF(stderr, "--loss must be linear or bernoulli, not %s\n", loss);
    return 2;
  }
  const int trials = absl::GetFlag(FLAGS_trials);
  if (trials < 1 || config.rounds < 1) {
    absl::FPrintF(stderr, "--trials and --rounds must be positive\n");
    return 2;
  }

  for (const std::string& dim_text : absl::GetFlag(FLAGS_context_dims)) {
    int dim = 0;
    if (!absl::SimpleAtoi(dim_text, &dim) || dim < config.posthoc_dim) {
      absl::FPrintF(stderr, "bad --context_dims entry %s (need >= d_p)\n",
                    dim_text);
      return 2;
    }
    config.context_dim = dim;
    const auto start = std::chrono::steady_clock::now();
    std::vector<std::vector<double>> context_only, posthoc, diff, polinucb,
        diff_polinucb;
    for (int trial = 0; trial < trials; ++trial) {
      const uint64_t seed = random::MixSeed(absl::GetFlag(FLAGS_seed),
                                            (uint64_t{1} << 32) * dim + trial);
      const SyntheticWorld world = DrawSyntheticWorld(config, seed);
      auto c = RunSyntheticTrial(config, world, bandit::Learner::kContextOnly);
      auto p = RunSyntheticTrial(config, world, bandit::Learner::kPostHoc);
      auto po = RunSyntheticTrial(config, world, bandit::Learner::kPoLinUcb);
      for (const auto* run : {&c, &p, &po}) {
        if (!run->ok()) {
          absl::FPrintF(stderr, "trial failed: %s\n", run->status().ToString());
          return 1;
        }
      }
      diff.push_back(Difference(*c, *p));
      diff_polinucb.push_back(Difference(*c, *po));
      polinucb.push_back(*std::move(po));
      context_only.push_back(*std::move(c));
      posthoc.push_back(*std::move(p));
      const double secs = std::chrono::duration<double>(
                              std::chrono::steady_clock::now() - start)
                              .count();
      absl::FPrintF(stderr,
                    "d_c=%d trial %d/%d: final regret context-only %.2f, "
                    "post hoc %.2f (%.1f s)\n",
                    dim, trial + 1, trials, context_only.back().back(),
                    posthoc.back().back(), secs);
    }
    const CurveSummary c = SummarizeCurves(context_only);
    const CurveSummary p = SummarizeCurves(posthoc);
    const CurveSummary d = SummarizeCurves(diff);
    const CurveSummary po = SummarizeCurves(polinucb);
    const CurveSummary dpo = SummarizeCurves(diff_polinucb);
    std::vector<double> round(config.rounds);
    for (int t = 0; t < config.rounds; ++t) round[t] = t + 1;
    const std::string path = absl::StrCat(absl::GetFlag(FLAGS_out_dir),
                                          "/synthetic_dc", dim, ".csv");
    const absl::Status written = WriteCsvColumns(
        path,
        {"round", "context_only_mean", "context_only_se", "posthoc_mean",
         "posthoc_se", "diff_mean", "diff_se", "polinucb_mean", "polinucb_se",
         "diff_polinucb_mean", "diff_polinucb_se"},
        {round, c.mean, c.standard_error, p.mean, p.standard_error, d.mean,
         d.standard_error, po.mean, po.standard_error, dpo.mean,
         dpo.standard_error});
    if (!written.ok()) {
      absl::FPrintF(stderr, "%s\n", written.ToString());
      return 1;
    }
    const int last = config.rounds - 1;
    absl::PrintF(
        "d_c=%d K=%d d_p=%d trials=%d rounds=%d: cumulative regret "
        "context-only %.3f +- %.3f, post hoc %.3f +- %.3f, difference %.3f "
        "+- %.3f; poLinUCB %.3f +- %.3f, difference %.3f +- %.3f (mean +- "
        "s.e.; differences context-only minus the learner); wrote %s\n",
        dim, config.num_actions, config.posthoc_dim, trials, config.rounds,
        c.mean[last], c.standard_error[last], p.mean[last],
        p.standard_error[last], d.mean[last], d.standard_error[last],
        po.mean[last], po.standard_error[last], dpo.mean[last],
        dpo.standard_error[last], path);
  }
  return 0;
}

}  // namespace
}  // namespace bitewise::experiments

int main(int argc, char** argv) {
  absl::SetProgramUsageMessage(
      "Synthetic post hoc vs context-only LinUCB regret "
      "(docs/experiments.md).");
  bitewise::ShowOwnFlagsInHelp();
  bitewise::ParseFlagsOnly(argc, argv);
  return bitewise::experiments::Run();
}
