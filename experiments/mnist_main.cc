// bitewise-mnist: the MNIST experiment of docs/experiments.md on IDX files
// given on the command line. Writes <out_dir>/mnist_learning.csv (test MSE
// every
// --eval_every rounds of uniform exploration, mean and standard error over
// --trials) and <out_dir>/mnist_regret.csv (cumulative regret of LinUCB over
// test digits, mean and standard error over --regret_trials).
#include <chrono>
#include <cstdio>
#include <string>
#include <vector>

#include "absl/flags/flag.h"
#include "absl/flags/usage.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "experiments/csv_writer.h"
#include "experiments/idx.h"
#include "experiments/mnist_experiment.h"
#include "experiments/trial_stats.h"
#include "services/common/flags_usage.h"
#include "services/domain/random.h"

ABSL_FLAG(std::string, train_images, "", "IDX ubyte training images.");
ABSL_FLAG(std::string, train_labels, "", "IDX ubyte training labels.");
ABSL_FLAG(std::string, test_images, "", "IDX ubyte test images.");
ABSL_FLAG(std::string, test_labels, "", "IDX ubyte test labels.");
ABSL_FLAG(int, pca_components, 200, "PCA dimensions of the context.");
ABSL_FLAG(bool, intercept, true, "Append a constant 1 to each context.");
ABSL_FLAG(int, posthoc_dim, 10, "d_p of the hidden post hoc map.");
ABSL_FLAG(int, trials, 10, "Learning-speed trials.");
ABSL_FLAG(int, exploration_rounds, 2000, "Uniform exploration rounds.");
ABSL_FLAG(int, eval_every, 10, "Rounds between test evaluations.");
ABSL_FLAG(int, regret_trials, 10, "Regret trials.");
ABSL_FLAG(int, regret_rounds, 0,
          "Regret rounds per trial, drawn with replacement from the test "
          "set; 0 = the test set's size.");
ABSL_FLAG(double, alpha, 0.01, "LinUCB exploration weight.");
ABSL_FLAG(double, lambda_c, 1000.0, "Ridge on the context model.");
ABSL_FLAG(double, lambda_p, 1.0, "Ridge on the post hoc terms.");
ABSL_FLAG(double, phi_radius, bitewise::bandit::BanditConfig().phi_radius,
          "poLinUCB: radius of the predicted post hoc context's ball.");
ABSL_FLAG(double, best_ridge, 1e-6, "Ridge of the full-feedback fit.");
ABSL_FLAG(uint64_t, seed, 1, "Base seed.");
ABSL_FLAG(std::string, out_dir, ".", "Directory for the CSV files.");

namespace bitewise::experiments {
namespace {

double Seconds(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start)
      .count();
}

int Fail(const absl::Status& status) {
  absl::FPrintF(stderr, "error: %s\n", status.ToString());
  return 1;
}

int Run() {
  const auto start = std::chrono::steady_clock::now();
  auto train_images = ReadIdxImages(absl::GetFlag(FLAGS_train_images));
  if (!train_images.ok()) return Fail(train_images.status());
  auto train_labels = ReadIdxLabels(absl::GetFlag(FLAGS_train_labels));
  if (!train_labels.ok()) return Fail(train_labels.status());
  auto test_images = ReadIdxImages(absl::GetFlag(FLAGS_test_images));
  if (!test_images.ok()) return Fail(test_images.status());
  auto test_labels = ReadIdxLabels(absl::GetFlag(FLAGS_test_labels));
  if (!test_labels.ok()) return Fail(test_labels.status());

  MnistConfig config;
  config.pca_components = absl::GetFlag(FLAGS_pca_components);
  config.intercept = absl::GetFlag(FLAGS_intercept);
  config.posthoc_dim = absl::GetFlag(FLAGS_posthoc_dim);
  config.exploration_rounds = absl::GetFlag(FLAGS_exploration_rounds);
  config.eval_every = absl::GetFlag(FLAGS_eval_every);
  config.regret_rounds = absl::GetFlag(FLAGS_regret_rounds);
  config.alpha = absl::GetFlag(FLAGS_alpha);
  config.lambda_c = absl::GetFlag(FLAGS_lambda_c);
  config.lambda_p = absl::GetFlag(FLAGS_lambda_p);
  config.phi_radius = absl::GetFlag(FLAGS_phi_radius);
  config.best_ridge = absl::GetFlag(FLAGS_best_ridge);
  auto problem = BuildMnistProblem(*train_images, *train_labels, *test_images,
                                   *test_labels, config);
  if (!problem.ok()) return Fail(problem.status());
  absl::FPrintF(stderr,
                "loaded %d training and %d test digits; PCA-%d component "
                "variances %.3g (first) to %.3g (last) (%.1f s)\n",
                train_images->count, test_images->count, config.pca_components,
                problem->pca_variances(0),
                problem->pca_variances(problem->pca_variances.size() - 1),
                Seconds(start));
  const double best = BestLinearTestMse(*problem, config.best_ridge);
  const std::string out_dir = absl::GetFlag(FLAGS_out_dir);
  const uint64_t seed = absl::GetFlag(FLAGS_seed);

  // Learning speed under uniform exploration.
  std::vector<std::vector<double>> co, ph, phm;
  std::vector<double> rounds;
  const int trials = absl::GetFlag(FLAGS_trials);
  for (int trial = 0; trial < trials; ++trial) {
    auto curve =
        RunLearningSpeedTrial(*problem, config, random::MixSeed(seed, trial));
    if (!curve.ok()) return Fail(curve.status());
    rounds = curve->rounds;
    co.push_back(curve->context_only_mse);
    ph.push_back(curve->posthoc_mse);
    phm.push_back(curve->posthoc_model_mse);
    absl::FPrintF(stderr,
                  "learning speed trial %d/%d: final test MSE context-only "
                  "%.4f, post hoc %.4f, post hoc model %.2e (%.1f s)\n",
                  trial + 1, trials, co.back().back(), ph.back().back(),
                  phm.back().back(), Seconds(start));
  }
  if (trials > 0) {
    const CurveSummary c = SummarizeCurves(co), p = SummarizeCurves(ph),
                       m = SummarizeCurves(phm);
    const std::vector<double> best_column(rounds.size(), best);
    const std::string path = absl::StrCat(out_dir, "/mnist_learning.csv");
    const absl::Status written = WriteCsvColumns(
        path,
        {"round", "context_only_mse", "context_only_se", "posthoc_mse",
         "posthoc_se", "posthoc_model_mse", "posthoc_model_se",
         "best_linear_mse"},
        {rounds, c.mean, c.standard_error, p.mean, p.standard_error, m.mean,
         m.standard_error, best_column});
    if (!written.ok()) return Fail(written);
    absl::PrintF(
        "learning speed (%d trials, %d rounds): best linear test MSE "
        "%.4f\n",
        trials, config.exploration_rounds, best);
    for (size_t i = 0; i < rounds.size(); ++i) {
      const int r = static_cast<int>(rounds[i]);
      if (r == 50 || r == 100 || r == 200 || r == 500 || r == 1000 ||
          r == 2000 || i + 1 == rounds.size()) {
        absl::PrintF(
            "  round %4d: test MSE context-only %.4f +- %.4f, post hoc "
            "%.4f +- %.4f, post hoc model %.2e\n",
            r, c.mean[i], c.standard_error[i], p.mean[i], p.standard_error[i],
            m.mean[i]);
      }
    }
    absl::PrintF("  wrote %s\n", path);
  }

  // Cumulative regret with LinUCB.
  std::vector<std::vector<double>> rc, rp, rd, rpo, rdpo;
  const int regret_trials = absl::GetFlag(FLAGS_regret_trials);
  for (int trial = 0; trial < regret_trials; ++trial) {
    const uint64_t trial_seed = random::MixSeed(seed, 1000 + trial);
    auto c = RunMnistRegretTrial(*problem, config,
                                 bandit::Learner::kContextOnly, trial_seed);
    if (!c.ok()) return Fail(c.status());
    auto p = RunMnistRegretTrial(*problem, config, bandit::Learner::kPostHoc,
                                 trial_seed);
    if (!p.ok()) return Fail(p.status());
    auto po = RunMnistRegretTrial(*problem, config, bandit::Learner::kPoLinUcb,
                                  trial_seed);
    if (!po.ok()) return Fail(po.status());
    rd.push_back(Difference(*c, *p));
    rdpo.push_back(Difference(*c, *po));
    rpo.push_back(*std::move(po));
    rc.push_back(*std::move(c));
    rp.push_back(*std::move(p));
    absl::FPrintF(stderr,
                  "regret trial %d/%d: context-only %.0f, post hoc %.0f "
                  "mistakes in %d rounds (%.1f s)\n",
                  trial + 1, regret_trials, rc.back().back(), rp.back().back(),
                  static_cast<int>(rc.back().size()), Seconds(start));
  }
  if (regret_trials > 0) {
    const CurveSummary c = SummarizeCurves(rc), p = SummarizeCurves(rp),
                       d = SummarizeCurves(rd), po = SummarizeCurves(rpo),
                       dpo = SummarizeCurves(rdpo);
    std::vector<double> round(c.mean.size());
    for (size_t t = 0; t < round.size(); ++t) round[t] = t + 1;
    const std::string path = absl::StrCat(out_dir, "/mnist_regret.csv");
    const absl::Status written = WriteCsvColumns(
        path,
        {"round", "context_only_mean", "context_only_se", "posthoc_mean",
         "posthoc_se", "diff_mean", "diff_se", "polinucb_mean", "polinucb_se",
         "diff_polinucb_mean", "diff_polinucb_se"},
        {round, c.mean, c.standard_error, p.mean, p.standard_error, d.mean,
         d.standard_error, po.mean, po.standard_error, dpo.mean,
         dpo.standard_error});
    if (!written.ok()) return Fail(written);
    const size_t last = round.size() - 1;
    absl::PrintF(
        "regret (%d trials, %zu rounds): context-only %.1f +- %.1f, post hoc "
        "%.1f +- %.1f, difference %.1f +- %.1f; poLinUCB %.1f +- %.1f, "
        "difference %.1f +- %.1f (context-only minus the learner)\n  wrote "
        "%s\n",
        regret_trials, round.size(), c.mean[last], c.standard_error[last],
        p.mean[last], p.standard_error[last], d.mean[last],
        d.standard_error[last], po.mean[last], po.standard_error[last],
        dpo.mean[last], dpo.standard_error[last], path);
  }
  absl::FPrintF(stderr, "done in %.1f s\n", Seconds(start));
  return 0;
}

}  // namespace
}  // namespace bitewise::experiments

int main(int argc, char** argv) {
  absl::SetProgramUsageMessage(
      "MNIST post hoc bandit experiment (docs/experiments.md) on IDX files.");
  bitewise::ShowOwnFlagsInHelp();
  bitewise::ParseFlagsOnly(argc, argv);
  return bitewise::experiments::Run();
}
