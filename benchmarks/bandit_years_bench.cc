// bandit_years_bench: one person's model after a month, a year or years of
// meals (docs/benchmarks.md, "Years of meals"). For each log size it
// rebuilds the post hoc model from a random log (K = 6, q = 4, d = 2048 by
// default), then plays Select+Update pairs as the service does (the Update
// reuses its Select's products) and prints, per size: Select and Update
// medians, the worst single Update, the model's bytes by the allocator's
// count (glibc mallinfo2) against the bound 1.3 x 8 x sum_a min(n_a d +
// n_a^2, d^2), and the rebuild time. With --sweep=N it instead grows one
// model from 0 to N rounds, timing every Update, and prints per window the
// median and worst Update (the switch from dual to primal form included)
// and the model's peak bytes against the bound; --repeat=R grows it R times
// on the same rounds and keeps each Update's fastest run, which separates
// the code's stalls (in every run) from the machine's (in one).
// With --cold_load it times the first Select after a restart through a
// real SQLite store, from a checkpoint and from the whole log.
// With --check, a sample of the estimates is compared against a dense
// float64 evaluation of the formulas (docs/algorithms.md) at each size.
//
//   build/benchmarks/bandit_years_bench                      # 1k, 10k, 50k
//   build/benchmarks/bandit_years_bench --sizes=1000,10000 --check
//   build/benchmarks/bandit_years_bench --sweep=14000 --window=500 --repeat=3
//   build/benchmarks/bandit_years_bench --cold_load --sizes=1000,10000
#include <malloc.h>
#include <stdlib.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include "Eigen/Dense"
#include "absl/flags/flag.h"
#include "absl/flags/parse.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "benchmarks/bandit_bench_rounds.h"
#include "services/bandit/core/linucb.h"
#include "services/bandit/core/policy.h"
#include "services/bandit/engine.h"
#include "services/bandit/store/sqlite_event_store.h"
#include "services/domain/random.h"
#include "tests/bandit/dense_reference.h"

ABSL_FLAG(int, d, 2048, "Context dimension.");
ABSL_FLAG(std::string, sizes, "1000,10000,50000", "Log sizes (rounds).");
ABSL_FLAG(int, pairs, 60, "Select+Update pairs timed per size.");
ABSL_FLAG(int, sweep, 0, "Grow one model to this many rounds instead.");
ABSL_FLAG(int, window, 1000, "Sweep: rounds per reported window.");
ABSL_FLAG(int, repeat, 1,
          "Sweep: runs of the same rounds; each Update's time is its fastest "
          "run's.");
ABSL_FLAG(int, top, 0,
          "Sweep: also list this many slowest Updates (their fastest run), "
          "with the taken action, its form (P or D) and rounds after the "
          "Update, and the converting "
          "action (-1: none).");
ABSL_FLAG(bool, cold_load, false,
          "Instead: per size, write the log into a real SQLite store, save a "
          "checkpoint, add --tail events, and time the first Select of a "
          "restarted engine with and without the checkpoint.");
ABSL_FLAG(int, tail, 50, "Cold load: events after the checkpoint.");
ABSL_FLAG(bool, check, false,
          "Compare estimates against a dense float64 reference (slow at "
          "large sizes: d^3 per action).");

namespace bitewise::bandit {
namespace {

using bench::Config;
using bench::kActions;
using bench::kPostHocDim;
using bench::RandomRound;
using bench::WriteEvents;

using Clock = std::chrono::steady_clock;

double Ms(Clock::duration t) {
  return std::chrono::duration<double, std::milli>(t).count();
}

size_t AllocatedBytes() {
  const struct mallinfo2 info = mallinfo2();
  return info.uordblks + info.hblkhd;
}

double BoundMb(const LinUcbModel& model) {
  const double d = model.context_dim();
  double doubles = 0.0;
  for (int a = 0; a < model.num_actions(); ++a) {
    const double n = static_cast<double>(model.Count(a));
    doubles += std::min(n * d + n * n, d * d);
  }
  return 1.3 * 8.0 * doubles / (1 << 20);
}

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

// One Select (estimates, choice, products) and the Update of its event;
// returns the round as played.
Round Pair(LinUcbModel& model, Round round, std::mt19937_64& rng,
           double* select_ms, double* update_ms) {
  SelectProducts products;
  const auto t0 = Clock::now();
  const std::vector<ActionEstimate> estimates =
      model.Estimate(round.context, &products);
  std::mt19937_64 select_rng = SelectRng(1, model.TotalRounds());
  const Choice choice = ChooseAction(model.config(), estimates, select_rng);
  const auto t1 = Clock::now();
  // Spread the log over the actions as the random log does.
  (void)choice;
  round.action = static_cast<int>(random::Canonical(rng) * kActions) % kActions;
  model.Update(round, &products);
  const auto t2 = Clock::now();
  *select_ms = Ms(t1 - t0);
  *update_ms = Ms(t2 - t1);
  return round;
}

// Largest relative error of the estimates against the tests' dense
// float64 evaluation of the formulas on the same log.
double CheckAgainstDense(const LinUcbModel& model,
                         const std::vector<Round>& log,
                         const std::vector<double>& probe) {
  const std::vector<testing::DenseActionModel> ref =
      testing::DenseReference(model.config(), log);
  const Eigen::Map<const Eigen::VectorXd> c(probe.data(), probe.size());
  const std::vector<ActionEstimate> est = model.Estimate(probe);
  double worst = 0.0;
  for (int k = 0; k < model.num_actions(); ++k) {
    const double pred = ref[k].theta.dot(c);
    const double width = std::sqrt(c.dot(ref[k].sigma * c));
    worst = std::max(worst, std::abs(est[k].predicted_loss - pred) /
                                std::max(1e-300, std::abs(pred)));
    worst = std::max(worst, std::abs(est[k].width - width) / width);
  }
  return worst;
}

int Sizes(int d) {
  std::vector<int> sizes;
  for (absl::string_view s :
       absl::StrSplit(absl::GetFlag(FLAGS_sizes), ',', absl::SkipEmpty())) {
    int n = 0;
    if (!absl::SimpleAtoi(s, &n) || n < 0) {
      std::fprintf(stderr, "--sizes: not a count: %s\n",
                   std::string(s).c_str());
      return 1;
    }
    sizes.push_back(n);
  }
  const int pairs = absl::GetFlag(FLAGS_pairs);
  std::printf(
      "d = %d, K = %d, q = %d, post hoc LinUCB, lambda_c = d/3; %d "
      "Select+Update pairs per size after the rebuild\n\n",
      d, kActions, kPostHocDim, pairs);
  std::printf("%8s %9s %10s %10s %10s %10s %10s %10s %6s %9s%s\n", "rounds",
              "primal", "select_ms", "update_ms", "upd_worst", "alloc_MB",
              "model_MB", "bound_MB", "ratio", "rebuild_s",
              absl::GetFlag(FLAGS_check) ? "  rel_err" : "");
  for (int n : sizes) {
    std::mt19937_64 rng(42);
    std::vector<Round> log;
    log.reserve(n);
    for (int t = 0; t < n; ++t) log.push_back(RandomRound(d, rng));
    const size_t before = AllocatedBytes();
    const auto t0 = Clock::now();
    LinUcbModel model = *LinUcbModel::Rebuild(Config(d), log);
    const double rebuild_s = Ms(Clock::now() - t0) / 1000.0;
    malloc_trim(0);
    std::vector<double> selects, updates;
    for (int i = 0; i < pairs; ++i) {
      double s = 0, u = 0;
      const Round played = Pair(model, RandomRound(d, rng), rng, &s, &u);
      selects.push_back(s);
      updates.push_back(u);
      if (absl::GetFlag(FLAGS_check)) log.push_back(played);
    }
    const double alloc_mb =
        static_cast<double>(AllocatedBytes() - before) / (1 << 20);
    const double model_mb =
        static_cast<double>(model.MemoryBytes()) / (1 << 20);
    int primal = 0;
    for (int a = 0; a < kActions; ++a) primal += model.IsPrimal(a);
    std::printf(
        "%8d %7d/6 %10.3f %10.3f %10.3f %10.1f %10.1f %10.1f %6.2f %9.2f", n,
        primal, Median(selects), Median(updates),
        *std::max_element(updates.begin(), updates.end()), alloc_mb, model_mb,
        BoundMb(model), alloc_mb / BoundMb(model), rebuild_s);
    if (absl::GetFlag(FLAGS_check)) {
      std::printf("  %.1e",
                  CheckAgainstDense(model, log, RandomRound(d, rng).context));
    }
    std::printf("\n");
    std::fflush(stdout);
  }
  return 0;
}

// Opens the store at `path` and a fresh engine on it, and times the first
// Select of `user` (its cold load).
double FirstSelectMs(const std::string& path, const std::string& user, int d,
                     std::mt19937_64& rng, int64_t* loads) {
  SqliteStoreOptions options;
  options.path = path;
  auto store = SqliteEventStore::Open(options).value();
  EngineOptions engine_options;
  engine_options.checkpoint_min_events = 0;
  BanditEngine engine(store.get(), engine_options);
  SelectInput select{user, RandomRound(d, rng).context, "meal", "item"};
  const auto t0 = Clock::now();
  engine.Select(select).value();
  const double ms = Ms(Clock::now() - t0);
  *loads = engine.Counters().checkpoint_loads;
  return ms;
}

int ColdLoad(int d) {
  const int tail = absl::GetFlag(FLAGS_tail);
  std::printf(
      "d = %d, K = %d, q = %d, post hoc LinUCB: the first Select after a "
      "restart, through a real SQLite store (page cache warm), with the "
      "checkpoint and %d events after it, and from the whole log\n\n",
      d, kActions, kPostHocDim, tail);
  std::printf("%8s %14s %16s %16s %12s\n", "events", "checkpoint_MB",
              "with_ckpt_ms", "whole_log_ms", "store_MB");
  for (absl::string_view s :
       absl::StrSplit(absl::GetFlag(FLAGS_sizes), ',', absl::SkipEmpty())) {
    int n = 0;
    if (!absl::SimpleAtoi(s, &n) || n < 1) return 1;
    std::string dir =
        std::filesystem::temp_directory_path() / "bitewise_cold_load_XXXXXX";
    if (mkdtemp(dir.data()) == nullptr) return 1;
    const std::string path = dir + "/bandit.db";
    std::mt19937_64 rng(42);
    {
      SqliteStoreOptions options;
      options.path = path;
      options.synchronous_full = false;  // setup only
      auto store = SqliteEventStore::Open(options).value();
      UserRecord user;
      user.user_id = "years";
      user.config = Config(d);
      user.created_at = absl::Now();
      if (!store->CreateUser(user).ok()) return 1;
      WriteEvents(*store, "years", d, n, rng);
      EngineOptions engine_options;
      engine_options.checkpoint_min_events = 0;
      BanditEngine engine(store.get(), engine_options);
      engine.GetModel("years").value();
      if (!engine.CheckpointUser("years").ok()) return 1;
      WriteEvents(*store, "years", d, tail, rng);
    }
    size_t checkpoint_bytes = 0;
    {
      SqliteStoreOptions options;
      options.path = path;
      auto store = SqliteEventStore::Open(options).value();
      checkpoint_bytes = store->GetCheckpoint("years").value().state.size();
    }
    int64_t loads = 0;
    const double with = FirstSelectMs(path, "years", d, rng, &loads);
    if (loads != 1) {
      std::fprintf(stderr, "the checkpoint was not used\n");
      return 1;
    }
    {
      SqliteStoreOptions options;
      options.path = path;
      auto store = SqliteEventStore::Open(options).value();
      if (!store->DeleteCheckpoint("years").ok()) return 1;
    }
    const double without = FirstSelectMs(path, "years", d, rng, &loads);
    std::printf("%8d %14.1f %16.1f %16.1f %12.1f\n", n + tail,
                checkpoint_bytes / 1048576.0, with, without,
                std::filesystem::file_size(path) / 1048576.0);
    std::fflush(stdout);
    std::filesystem::remove_all(dir);
  }
  return 0;
}

// One model grown from 0 to `total` rounds (the same rounds every run):
// every Update's time, the primal actions and the model's bytes after it.
struct SweepRun {
  std::vector<double> selects, updates, mb, bound_mb;
  std::vector<int> primal;
  std::vector<std::string> note;  // --top: the taken action, converting
};

SweepRun RunSweep(int d, int total) {
  SweepRun run;
  std::mt19937_64 rng(42);
  LinUcbModel model = *LinUcbModel::Create(Config(d));
  for (int t = 1; t <= total; ++t) {
    double s = 0, u = 0;
    const Round played = Pair(model, RandomRound(d, rng), rng, &s, &u);
    if (absl::GetFlag(FLAGS_top) > 0) {
      int conv = -1;
      for (int a = 0; a < kActions; ++a) {
        if (model.IsConverting(a)) conv = a;
      }
      run.note.push_back(absl::StrCat(
          "taken ", played.action, model.IsPrimal(played.action) ? " P" : " D",
          " n ", model.Count(played.action), " conv ", conv));
    }
    run.selects.push_back(s);
    run.updates.push_back(u);
    int primal = 0;
    for (int a = 0; a < kActions; ++a) primal += model.IsPrimal(a);
    run.primal.push_back(primal);
    run.mb.push_back(static_cast<double>(model.MemoryBytes()) / (1 << 20));
    run.bound_mb.push_back(BoundMb(model));
  }
  return run;
}

int Sweep(int d) {
  const int total = absl::GetFlag(FLAGS_sweep);
  const int window = std::max(1, absl::GetFlag(FLAGS_window));
  const int repeat = std::max(1, absl::GetFlag(FLAGS_repeat));
  std::printf(
      "d = %d, K = %d, q = %d: one model grown from 0 to %d rounds by "
      "Select+Update pairs; every Update timed%s\n\n",
      d, kActions, kPostHocDim, total,
      repeat > 1 ? absl::StrCat(", ", repeat,
                                " runs of the same rounds, each Update's "
                                "fastest run (a stall of the code is in "
                                "every run, the machine's in one)")
                       .c_str()
                 : "");
  SweepRun run = RunSweep(d, total);
  std::vector<double> raw_worst(run.updates);
  for (int r = 1; r < repeat; ++r) {
    const SweepRun again = RunSweep(d, total);
    for (int t = 0; t < total; ++t) {
      run.updates[t] = std::min(run.updates[t], again.updates[t]);
      run.selects[t] = std::min(run.selects[t], again.selects[t]);
      raw_worst[t] = std::max(raw_worst[t], again.updates[t]);
    }
  }
  std::printf("%8s %9s %10s %10s %10s %8s %9s %9s\n", "rounds", "primal",
              "select_ms", "update_ms", "upd_worst", "worst/p50", "peak_MB",
              "bound_MB");
  double overall_ratio = 0.0, peak_over_bound = 0.0;
  for (int begin = 0; begin < total; begin += window) {
    const int end = std::min(total, begin + window);
    const std::vector<double> selects(run.selects.begin() + begin,
                                      run.selects.begin() + end);
    const std::vector<double> updates(run.updates.begin() + begin,
                                      run.updates.begin() + end);
    const double median = Median(updates);
    const double worst = *std::max_element(updates.begin(), updates.end());
    overall_ratio = std::max(overall_ratio, worst / median);
    const double peak_mb =
        *std::max_element(run.mb.begin() + begin, run.mb.begin() + end);
    // The model's bytes after every Update against the bound at that size
    // (from 500 rounds on: below, fixed sums dominate a tiny bound).
    for (int t = std::max(begin, 500); t < end; ++t) {
      peak_over_bound = std::max(peak_over_bound, run.mb[t] / run.bound_mb[t]);
    }
    std::printf("%8d %7d/6 %10.3f %10.3f %10.3f %8.2f %9.1f %9.1f\n", end,
                run.primal[end - 1], Median(selects), median, worst,
                worst / median, peak_mb, run.bound_mb[end - 1]);
  }
  const double sweep_median = Median(run.updates);
  const double sweep_worst =
      *std::max_element(run.updates.begin(), run.updates.end());
  std::printf(
      "\nworst single Update / its window's median, over the sweep: %.2f\n"
      "whole sweep: Update median %.3f ms, worst %.3f ms, worst / median "
      "%.2f\nlargest model / bound at its size (after any Update past 500 "
      "rounds): %.2f\n",
      overall_ratio, sweep_median, sweep_worst, sweep_worst / sweep_median,
      peak_over_bound);
  if (absl::GetFlag(FLAGS_top) > 0) {
    std::vector<int> idx(total);
    for (int t = 0; t < total; ++t) idx[t] = t;
    std::sort(idx.begin(), idx.end(),
              [&](int a, int b) { return run.updates[a] > run.updates[b]; });
    for (int i = 0; i < absl::GetFlag(FLAGS_top) && i < total; ++i) {
      std::printf("top %2d: round %5d %.3f ms primal %d %s\n", i, idx[i] + 1,
                  run.updates[idx[i]], run.primal[idx[i]],
                  run.note.empty() ? "" : run.note[idx[i]].c_str());
    }
  }
  if (repeat > 1) {
    std::printf(
        "slowest single Update of any run: %.3f ms (round %d)\n",
        *std::max_element(raw_worst.begin(), raw_worst.end()),
        static_cast<int>(std::max_element(raw_worst.begin(), raw_worst.end()) -
                         raw_worst.begin()) +
            1);
  }
  return 0;
}

}  // namespace
}  // namespace bitewise::bandit

int main(int argc, char** argv) {
  absl::ParseCommandLine(argc, argv);
  const int d = absl::GetFlag(FLAGS_d);
  if (absl::GetFlag(FLAGS_sweep) > 0) return bitewise::bandit::Sweep(d);
  if (absl::GetFlag(FLAGS_cold_load)) return bitewise::bandit::ColdLoad(d);
  return bitewise::bandit::Sizes(d);
}
