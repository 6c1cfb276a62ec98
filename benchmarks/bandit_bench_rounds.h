// The random post hoc rounds both bandit benchmarks draw (K = 6 actions
// spread uniformly, q = 4 one-hot post hoc contexts, contexts uniform in
// [0,1)^d, 30% failures), so their numbers describe the same workload.
#ifndef BITEWISE_BENCHMARKS_BANDIT_BENCH_ROUNDS_H_
#define BITEWISE_BENCHMARKS_BANDIT_BENCH_ROUNDS_H_

#include <random>

#include "services/bandit/core/linucb.h"
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

}  // namespace bitewise::bandit::bench

#endif  // BITEWISE_BENCHMARKS_BANDIT_BENCH_ROUNDS_H_
