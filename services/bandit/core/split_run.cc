#include "services/bandit/core/split_run.h"

#include <algorithm>
#include <atomic>
#include <numeric>
#include <system_error>
#include <thread>
#include <vector>

namespace bitewise::bandit {
namespace {

std::atomic<double>& MinCost() {
  static std::atomic<double> min_cost{kDefaultSplitMinCost};
  return min_cost;
}

bool HaveSecondCore() {
  static const bool have = std::thread::hardware_concurrency() >= 2;
  return have;
}

}  // namespace

double SplitMinCost() { return MinCost().load(std::memory_order_relaxed); }

void SetSplitMinCost(double min_cost) {
  MinCost().store(min_cost, std::memory_order_relaxed);
}

void SplitRun(absl::Span<const double> costs,
              absl::FunctionRef<void(int)> task) {
  const int n = static_cast<int>(costs.size());
  const double total = std::accumulate(costs.begin(), costs.end(), 0.0);
  if (n < 2 || !HaveSecondCore() || !(total >= SplitMinCost())) {
    for (int i = 0; i < n; ++i) task(i);
    return;
  }
  std::vector<int> order(n);
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(),
                   [&](int a, int b) { return costs[a] > costs[b]; });
  std::vector<int> mine, theirs;
  double my_cost = 0.0, their_cost = 0.0;
  for (int i : order) {
    if (my_cost <= their_cost) {
      mine.push_back(i);
      my_cost += costs[i];
    } else {
      theirs.push_back(i);
      their_cost += costs[i];
    }
  }
  if (theirs.empty()) {
    for (int i : mine) task(i);
    return;
  }
  std::thread helper;
  try {
    helper = std::thread([&] {
      for (int i : theirs) task(i);
    });
  } catch (const std::system_error&) {
    for (int i = 0; i < n; ++i) task(i);
    return;
  }
  for (int i : mine) task(i);
  helper.join();
}

}  // namespace bitewise::bandit
