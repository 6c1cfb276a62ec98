// Benchmarks of the bandit learning core: Select (Estimate + choice),
// Update and rebuild-from-log for the incremental LinUcbModel, next to the
// naive approach of the research code (dense inverses recomputed per round).
//
//   build/benchmarks/bandit_bench --benchmark_filter=Incremental
//   build/benchmarks/bandit_bench --benchmark_filter=Learner   # every learner
//
// Results and how to read them: docs/benchmarks.md.
#include <limits>
#include <memory>
#include <random>
#include <vector>

#include "Eigen/Dense"
#include "benchmark/benchmark.h"
#include "benchmarks/bandit_bench_rounds.h"
#include "services/bandit/core/learners.h"
#include "services/bandit/core/linucb.h"
#include "services/bandit/core/policy.h"
#include "services/bandit/core/split_run.h"
#include "services/domain/random.h"

namespace bitewise::bandit {
namespace {

using bench::kActions;
using bench::kPostHocDim;
using bench::RandomRound;

BanditConfig Config(int d, bool prior = false) {
  BanditConfig config;
  config.context_dim = d;
  config.posthoc_dim = kPostHocDim;
  if (prior) {
    // A population prior (values do not matter for the cost).
    config.prior.pool_version = 1;
    config.prior.rounds = 10.0;
    config.prior.context_msn = d / 3.0;
    config.prior.posthoc_msn = 1.0;
    config.prior.theta0.assign(kActions, std::vector<double>(d, 0.01));
    config.prior.phi0.assign(kActions, std::vector<double>(kPostHocDim, 0.1));
  }
  return config;
}

std::vector<Round> RandomLog(int d, int rounds, std::mt19937_64& rng) {
  std::vector<Round> log;
  log.reserve(rounds);
  for (int t = 0; t < rounds; ++t) log.push_back(RandomRound(d, rng));
  return log;
}

// The research code's approach: dense A_a, M_a, S_pp, S_pc and explicit
// inverses of every N_a recomputed after each update (O(K d^3)).
class NaiveDense {
 public:
  explicit NaiveDense(const BanditConfig& config)
      : config_(config),
        d_(config.context_dim),
        q_(config.posthoc_dim),
        a_(kActions, config.lambda_c * Eigen::MatrixXd::Identity(d_, d_)),
        b_(kActions, Eigen::VectorXd::Zero(d_)),
        m_(kActions, config.lambda_p * Eigen::MatrixXd::Identity(q_, q_)),
        r_(kActions, Eigen::VectorXd::Zero(q_)),
        n_inv_(kActions),
        theta_(kActions),
        s_pp_(config.lambda_p * Eigen::MatrixXd::Identity(q_, q_)),
        s_pc_(Eigen::MatrixXd::Zero(q_, d_)) {}

  void Accumulate(const Round& t) {
    const Eigen::Map<const Eigen::VectorXd> c(t.context.data(), d_);
    const Eigen::Map<const Eigen::VectorXd> p(t.posthoc.data(), q_);
    a_[t.action].noalias() += c * c.transpose();
    b_[t.action] += t.loss * c;
    m_[t.action].noalias() += p * p.transpose();
    r_[t.action] += t.loss * p;
    s_pp_.noalias() += p * p.transpose();
    s_pc_.noalias() += p * c.transpose();
  }

  void Solve() {
    const Eigen::MatrixXd h = s_pp_.inverse() * s_pc_;
    for (int a = 0; a < kActions; ++a) {
      n_inv_[a] = (a_[a] + h.transpose() * m_[a] * h).inverse();
      theta_[a] = n_inv_[a] * (b_[a] + h.transpose() * r_[a]);
    }
  }

  void Update(const Round& t) {
    Accumulate(t);
    Solve();
  }

  int Select(const std::vector<double>& context) const {
    const Eigen::Map<const Eigen::VectorXd> c(context.data(), d_);
    std::vector<double> lcb(kActions);
    for (int a = 0; a < kActions; ++a) {
      lcb[a] = theta_[a].dot(c) -
               config_.alpha * std::sqrt(2.0 * c.dot(n_inv_[a] * c));
    }
    return ArgMin(lcb);
  }

 private:
  BanditConfig config_;
  int d_, q_;
  std::vector<Eigen::MatrixXd> a_;
  std::vector<Eigen::VectorXd> b_;
  std::vector<Eigen::MatrixXd> m_;
  std::vector<Eigen::VectorXd> r_;
  std::vector<Eigen::MatrixXd> n_inv_;
  std::vector<Eigen::VectorXd> theta_;
  Eigen::MatrixXd s_pp_, s_pc_;
};

void IncrementalSelect(benchmark::State& state, bool prior) {
  const int d = static_cast<int>(state.range(0));
  const int rounds = static_cast<int>(state.range(1));
  std::mt19937_64 rng(42);
  LinUcbModel model =
      LinUcbModel::Rebuild(Config(d, prior), RandomLog(d, rounds, rng)).value();
  const Round probe = RandomRound(d, rng);
  for (auto _ : state) {
    std::mt19937_64 select_rng = SelectRng(0, 0);
    benchmark::DoNotOptimize(ChooseAction(
        model.config(), model.Estimate(probe.context), select_rng));
  }
  state.counters["MB"] = static_cast<double>(model.MemoryBytes()) / (1 << 20);
}

void BM_IncrementalSelect(benchmark::State& state) {
  IncrementalSelect(state, false);
}
// With a population prior: folded into b_a and r_a once, so a Select costs
// what it costs without one.
void BM_IncrementalSelectWithPrior(benchmark::State& state) {
  IncrementalSelect(state, true);
}

void BM_IncrementalUpdate(benchmark::State& state) {
  const int d = static_cast<int>(state.range(0));
  const int rounds = static_cast<int>(state.range(1));
  std::mt19937_64 rng(42);
  LinUcbModel model =
      LinUcbModel::Rebuild(Config(d), RandomLog(d, rounds, rng)).value();
  // Each iteration adds one round: the model grows by at most a few percent.
  const std::vector<Round> next = RandomLog(d, 64, rng);
  size_t i = 0;
  for (auto _ : state) {
    model.Update(next[i++ % next.size()]);
  }
}

void BM_IncrementalRebuild(benchmark::State& state) {
  const int d = static_cast<int>(state.range(0));
  const int rounds = static_cast<int>(state.range(1));
  std::mt19937_64 rng(42);
  const std::vector<Round> log = RandomLog(d, rounds, rng);
  for (auto _ : state) {
    benchmark::DoNotOptimize(LinUcbModel::Rebuild(Config(d), log));
  }
}

// Every learner of the table through LearnerModel (range(2): the Learner
// number), as the service runs it: Select = Estimate + LinUCB's choice,
// Update with the products of the Select of the same context.
BanditConfig LearnerConfig(int d, int learner) {
  BanditConfig config = Config(d);
  config.learner = static_cast<Learner>(learner);
  return config;
}

// The model of the benchmark's learner (range(2)) at d = range(0), rebuilt
// from range(1) random rounds; `rng` goes on from there.
std::unique_ptr<LearnerModel> LearnerFromLog(const benchmark::State& state,
                                             std::mt19937_64& rng) {
  const int d = static_cast<int>(state.range(0));
  const int rounds = static_cast<int>(state.range(1));
  return RebuildModel(LearnerConfig(d, static_cast<int>(state.range(2))),
                      RandomLog(d, rounds, rng))
      .value();
}

// BM_LearnerSelectThreads's model: rebuilt once for its (d, rounds,
// learner) and kept for the next run of the same (the other thread count,
// the repetitions), since a rebuild at 50,000 rounds takes minutes.
const LearnerModel& CachedLearner(const benchmark::State& state, Round* probe) {
  static std::vector<int64_t> key;
  static std::unique_ptr<LearnerModel> model;
  static Round cached_probe;
  const std::vector<int64_t> wanted = {state.range(0), state.range(1),
                                       state.range(2)};
  if (model == nullptr || key != wanted) {
    model.reset();  // one model in memory at a time
    std::mt19937_64 rng(42);
    model = LearnerFromLog(state, rng);
    cached_probe = RandomRound(static_cast<int>(state.range(0)), rng);
    key = wanted;
  }
  *probe = cached_probe;
  return *model;
}

// Select = Estimate + LinUCB's choice, range(3) threads (bitewise-bandit
// --select_threads: 2 splits a large Select's passes over two cores, 1 keeps
// it on the calling thread). Wall time: with 2, part of the work is on the
// second thread.
void BM_LearnerSelect(benchmark::State& state) {
  Round probe;
  const LearnerModel& model = CachedLearner(state, &probe);
  const double saved = SplitMinCost();
  if (state.range(3) == 1) {
    SetSplitMinCost(std::numeric_limits<double>::infinity());
  }
  for (auto _ : state) {
    std::mt19937_64 select_rng = SelectRng(0, 0);
    benchmark::DoNotOptimize(ChooseAction(
        model.config(), model.Estimate(probe.context), select_rng));
  }
  SetSplitMinCost(saved);
  state.SetLabel(LearnerName(model.config().learner));
  state.counters["MB"] = static_cast<double>(model.MemoryBytes()) / (1 << 20);
}

void BM_LearnerUpdate(benchmark::State& state) {
  const int d = static_cast<int>(state.range(0));
  std::mt19937_64 rng(42);
  std::unique_ptr<LearnerModel> model = LearnerFromLog(state, rng);
  const std::vector<Round> next = RandomLog(d, 64, rng);
  size_t i = 0;
  for (auto _ : state) {
    const Round& round = next[i++ % next.size()];
    SelectProducts products;
    state.PauseTiming();
    model->Estimate(round.context, &products);
    state.ResumeTiming();
    model->Update(round, &products);
  }
  state.SetLabel(LearnerName(model->config().learner));
}

void LearnerGrid(benchmark::internal::Benchmark* b) {
  for (const LearnerSpec& spec : Learners()) {
    for (int rounds : {1000, 10000, 50000}) {
      b->Args({2048, rounds, static_cast<int>(spec.learner)});
    }
  }
  b->ArgNames({"d", "rounds", "learner"})->Unit(benchmark::kMillisecond);
}

// The same, with each point twice: two threads, then one.
void LearnerThreadsGrid(benchmark::internal::Benchmark* b) {
  for (const LearnerSpec& spec : Learners()) {
    for (int rounds : {1000, 10000, 50000}) {
      for (int threads : {2, 1}) {
        b->Args({2048, rounds, static_cast<int>(spec.learner), threads});
      }
    }
  }
  b->ArgNames({"d", "rounds", "learner", "threads"})
      ->Unit(benchmark::kMillisecond)
      ->UseRealTime();
}

// What a poLinUCB Select adds for its reply's predicted_posthoc: p_hat(c)
// = q_map^T c, d x q multiply-adds.
void BM_PoLinUcbPredictedPosthoc(benchmark::State& state) {
  Round probe;
  const LearnerModel& model = CachedLearner(state, &probe);
  for (auto _ : state) {
    benchmark::DoNotOptimize(model.PredictedPosthoc(probe.context));
  }
  state.SetLabel(LearnerName(model.config().learner));
}

void PredictedPosthocGrid(benchmark::internal::Benchmark* b) {
  for (int rounds : {1000, 10000}) {
    b->Args({2048, rounds, static_cast<int>(Learner::kPoLinUcb)});
  }
  b->ArgNames({"d", "rounds", "learner"})->Unit(benchmark::kMicrosecond);
}

void BM_NaiveSelect(benchmark::State& state) {
  const int d = static_cast<int>(state.range(0));
  const int rounds = static_cast<int>(state.range(1));
  std::mt19937_64 rng(42);
  NaiveDense naive(Config(d));
  for (const Round& t : RandomLog(d, rounds, rng)) naive.Accumulate(t);
  naive.Solve();
  const Round probe = RandomRound(d, rng);
  for (auto _ : state) benchmark::DoNotOptimize(naive.Select(probe.context));
}

void BM_NaiveUpdate(benchmark::State& state) {
  const int d = static_cast<int>(state.range(0));
  const int rounds = static_cast<int>(state.range(1));
  std::mt19937_64 rng(42);
  NaiveDense naive(Config(d));
  for (const Round& t : RandomLog(d, rounds, rng)) naive.Accumulate(t);
  const Round next = RandomRound(d, rng);
  for (auto _ : state) naive.Update(next);
}

void BM_NaiveRebuild(benchmark::State& state) {
  const int d = static_cast<int>(state.range(0));
  const int rounds = static_cast<int>(state.range(1));
  std::mt19937_64 rng(42);
  const std::vector<Round> log = RandomLog(d, rounds, rng);
  for (auto _ : state) {
    NaiveDense naive(Config(d));
    for (const Round& t : log) naive.Accumulate(t);
    naive.Solve();
    benchmark::DoNotOptimize(naive);
  }
}

void Grid(benchmark::internal::Benchmark* b) {
  for (int d : {64, 512, 2048}) {
    for (int rounds : {10, 100, 1000, 5000}) b->Args({d, rounds});
  }
  b->ArgNames({"d", "rounds"})->Unit(benchmark::kMillisecond);
}

// The naive O(K d^3) update takes seconds at d = 2048: measured once.
void NaiveGrid(benchmark::internal::Benchmark* b) {
  Grid(b);
  b->Iterations(3);
}

BENCHMARK(BM_IncrementalSelect)->Apply(Grid);
BENCHMARK(BM_IncrementalSelectWithPrior)->Apply(Grid);
BENCHMARK(BM_IncrementalUpdate)->Apply(Grid)->Iterations(40);
BENCHMARK(BM_IncrementalRebuild)->Apply(Grid)->Iterations(2);
BENCHMARK(BM_LearnerSelect)->Apply(LearnerThreadsGrid);
BENCHMARK(BM_LearnerUpdate)->Apply(LearnerGrid)->Iterations(40);
BENCHMARK(BM_PoLinUcbPredictedPosthoc)->Apply(PredictedPosthocGrid);
BENCHMARK(BM_NaiveSelect)->Apply(Grid);
BENCHMARK(BM_NaiveUpdate)->Apply(NaiveGrid);
BENCHMARK(BM_NaiveRebuild)->Apply(NaiveGrid);

}  // namespace
}  // namespace bitewise::bandit

BENCHMARK_MAIN();
