// The random post hoc rounds both bandit benchmarks draw (K = 6 actions
// spread uniformly, q = 4 one-hot post hoc contexts, contexts uniform in
// [0,1)^d, 30% failures), so their numbers describe the same workload.
#ifndef BITEWISE_BENCHMARKS_BANDIT_BENCH_ROUNDS_H_
#define BITEWISE_BENCHMARKS_BANDIT_BENCH_ROUNDS_H_

#include <random>
#include <string>

#include "absl/time/clock.h"
#include "services/bandit/core/config.h"
#include "services/bandit/core/linucb.h"
#include "services/bandit/store/event_store.h"
#include "services/domain/random.h"

namespace bitewise::bandit::bench {

inline constexpr int kActions = 6;
inline constexpr int kPostHocDim = 4;

inline Round RandomRound(int d, std::mt19937_64& rng) {
  Round round;
  round.context.resize(d);
  for (double& x : round.context) x = random::Canonical(rng);
  round.action = static_cast<int>(random::Canonical(rng) * kActions) % kActions;
  round.posthoc.assign(kPostHocDim, 0.0);
  round.posthoc[round.action % kPostHocDim] = 1.0;
  round.loss = random::Canonical(rng) < 0.3 ? 1.0 : 0.0;
  return round;
}

// A post hoc user of the benchmarks' shape (K = 6, q = 4).
inline BanditConfig Config(int d) {
  BanditConfig config;
  config.context_dim = d;
  config.posthoc_dim = kPostHocDim;
  // The shipped rule: lambda_c = rho_c E||c||^2, E||c||^2 = d / 3 here.
  config.lambda_c = d / 3.0;
  return config;
}

// Appends `n` completed random events for `user` straight into the store
// (what Select and Update would write).
inline void WriteEvents(EventStore& store, const std::string& user, int d,
                        int n, std::mt19937_64& rng) {
  for (int t = 0; t < n; ++t) {
    const Round round = RandomRound(d, rng);
    EventRecord event;
    event.user_id = user;
    event.meal_id = "meal";
    event.item_label = "item";
    event.context = round.context;
    event.action = round.action;
    event.selected_at = absl::Now();
    const int64_t id = store.AppendPending(event).value();
    store.CompleteEvent(id, round.loss, round.posthoc, 1.0, absl::Now())
        .value();
  }
}

}  // namespace bitewise::bandit::bench

#endif  // BITEWISE_BENCHMARKS_BANDIT_BENCH_ROUNDS_H_
