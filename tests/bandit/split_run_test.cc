// SplitRun (split_run.h): every task runs exactly once, on two threads when
// the work is large enough; and a Select split over two threads gives every
// learner bit-identical estimates and products to one on a single thread,
// dual, primal and mixed, poLinUCB's pooled model in both forms (the
// single-thread path is checked against the dense reference in
// linucb_test.cc and polinucb_test.cc).
#include "services/bandit/core/split_run.h"

#include <atomic>
#include <limits>
#include <memory>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/synchronization/mutex.h"
#include "gtest/gtest.h"
#include "services/bandit/core/config.h"
#include "services/bandit/core/learner_model.h"
#include "services/bandit/core/learners.h"
#include "services/bandit/core/rounds.h"

namespace bitewise::bandit {
namespace {

constexpr double kNever = std::numeric_limits<double>::infinity();

// Sets the process's threshold for a scope.
class ScopedSplitMinCost {
 public:
  explicit ScopedSplitMinCost(double min_cost) : saved_(SplitMinCost()) {
    SetSplitMinCost(min_cost);
  }
  ~ScopedSplitMinCost() { SetSplitMinCost(saved_); }

 private:
  const double saved_;
};

TEST(SplitRunTest, RunsEveryTaskExactlyOnce) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> cost(0.0, 100.0);
  for (double min_cost : {0.0, 150.0, kNever}) {
    const ScopedSplitMinCost scoped(min_cost);
    for (int n = 0; n <= 9; ++n) {
      std::vector<double> costs(n);
      for (double& c : costs) c = cost(rng);
      std::vector<std::atomic<int>> runs(n);
      SplitRun(costs, [&](int i) { runs[i].fetch_add(1); });
      for (int i = 0; i < n; ++i) {
        EXPECT_EQ(runs[i].load(), 1)
            << "task " << i << " of " << n << ", threshold " << min_cost;
      }
    }
  }
}

TEST(SplitRunTest, LargeWorkRunsOnTwoThreadsAndSmallWorkOnTheCaller) {
  if (std::thread::hardware_concurrency() < 2) {
    GTEST_SKIP() << "one core: SplitRun keeps every task on the caller";
  }
  const std::vector<double> costs = {5.0, 4.0, 3.0, 3.0};
  absl::Mutex mu;
  std::vector<std::thread::id> ids(costs.size());
  auto record = [&](int i) {
    absl::MutexLock lock(&mu);
    ids[i] = std::this_thread::get_id();
  };
  {
    const ScopedSplitMinCost scoped(15.0);  // the sum reaches it
    SplitRun(costs, record);
    // Longest first, each to the lighter group: {5, 3} and {4, 3}.
    EXPECT_EQ(ids[0], std::this_thread::get_id());
    EXPECT_NE(ids[1], std::this_thread::get_id());
    EXPECT_EQ(ids[2], ids[1]);
    EXPECT_EQ(ids[3], std::this_thread::get_id());
  }
  {
    const ScopedSplitMinCost scoped(15.1);  // it does not
    SplitRun(costs, record);
    for (const std::thread::id& id : ids) {
      EXPECT_EQ(id, std::this_thread::get_id());
    }
  }
}

std::vector<double> Random(int n, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<double> v(n);
  for (double& x : v) x = u(rng);
  return v;
}

Round RandomRound(int d, int q, int k, std::mt19937_64& rng) {
  Round r;
  r.context = Random(d, rng);
  r.posthoc = Random(q, rng);
  r.action = static_cast<int>(rng() % k);
  r.loss = 0.5 * (1.0 + Random(1, rng)[0]);
  r.weight = 1.0 + 0.5 * (1.0 + Random(1, rng)[0]);
  return r;
}

struct Case {
  Learner learner;
  int primal_threshold;  // 0: 3d/4 (every action stays dual here)
  int rounds;
};

// Two copies of one model: one Selects split over two threads, the other on
// one; both Update with their own Select's products. Every estimate and the
// saved states must be equal to the bit.
void CheckSplitIsBitIdentical(const Case& c) {
  constexpr int kD = 24, kQ = 3, kK = 6;
  SCOPED_TRACE(absl::StrCat(LearnerName(c.learner), ", threshold ",
                            c.primal_threshold, ", ", c.rounds, " rounds"));
  BanditConfig config;
  config.learner = c.learner;
  config.context_dim = kD;
  config.posthoc_dim = kQ;
  config.alpha = 0.3;
  config.lambda_c = 1.5;
  config.lambda_p = 0.7;
  std::mt19937_64 rng(1234 + c.rounds + c.primal_threshold);
  std::vector<Round> log;
  for (int t = 0; t < c.rounds; ++t) {
    log.push_back(RandomRound(kD, kQ, kK, rng));
  }
  std::unique_ptr<LearnerModel> split =
      RebuildModel(config, log, c.primal_threshold).value();
  std::unique_ptr<LearnerModel> single =
      RebuildModel(config, log, c.primal_threshold).value();
  for (int step = 0; step < 40; ++step) {
    const Round next = RandomRound(kD, kQ, kK, rng);
    SelectProducts split_products, single_products;
    std::vector<ActionEstimate> split_estimates, single_estimates;
    {
      const ScopedSplitMinCost scoped(0.0);
      split_estimates = split->Estimate(next.context, &split_products);
    }
    {
      const ScopedSplitMinCost scoped(kNever);
      single_estimates = single->Estimate(next.context, &single_products);
    }
    ASSERT_EQ(split_estimates.size(), single_estimates.size());
    for (size_t a = 0; a < split_estimates.size(); ++a) {
      EXPECT_EQ(split_estimates[a].predicted_loss,
                single_estimates[a].predicted_loss)
          << "step " << step << " action " << a;
      EXPECT_EQ(split_estimates[a].width, single_estimates[a].width)
          << "step " << step << " action " << a;
      EXPECT_EQ(split_estimates[a].lcb, single_estimates[a].lcb)
          << "step " << step << " action " << a;
    }
    split->Update(next, &split_products);
    single->Update(next, &single_products);
  }
  EXPECT_TRUE(split->SaveState() == single->SaveState());
}

TEST(SplitRunTest, SplitSelectsAreBitIdenticalForEveryLearner) {
  for (Learner learner :
       {Learner::kPostHoc, Learner::kContextOnly, Learner::kPoLinUcb}) {
    // All dual (poLinUCB: its pooled factors in use).
    CheckSplitIsBitIdentical({learner, 0, 60});
    // Actions turning primal during the Updates, some primal from the
    // start, and poLinUCB's pooled model primal (its own pass beside the
    // actions').
    CheckSplitIsBitIdentical({learner, 12, 40});
    CheckSplitIsBitIdentical({learner, 6, 120});
  }
}

}  // namespace
}  // namespace bitewise::bandit
