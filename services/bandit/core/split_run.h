// Running a Select's independent per-action passes on two cores. At large
// d and many rounds a Select is a pass over each action's form (its rows in
// dual form, its d x d triangle in primal form), bound by memory bandwidth,
// and one core does not draw all of it. The passes are split into two
// groups of about equal cost; the caller runs one and a second thread the
// other. Each pass is computed exactly as on one thread, so results are
// bit-identical whatever the split.
#ifndef BITEWISE_SERVICES_BANDIT_CORE_SPLIT_RUN_H_
#define BITEWISE_SERVICES_BANDIT_CORE_SPLIT_RUN_H_

#include "absl/functional/function_ref.h"
#include "absl/types/span.h"

namespace bitewise::bandit {

// Below this many numbers read in all (8 MB of doubles), a second thread
// costs about what it saves (measured: docs/benchmarks.md).
inline constexpr double kDefaultSplitMinCost = 1 << 20;

// Runs task(i) once for every i < costs.size(), costs[i] the numbers task i
// reads. When their sum reaches SplitMinCost() and the machine has a second
// core, a second thread runs some of them (longest first, each to the
// group with less so far) while the calling thread runs the rest; if the
// thread cannot be started the caller runs everything. Tasks must be safe
// to run concurrently with one another.
void SplitRun(absl::Span<const double> costs,
              absl::FunctionRef<void(int)> task);

// The process's threshold (default kDefaultSplitMinCost); infinity keeps
// every Select on its calling thread (the bitewise-bandit flag
// --select_threads=1), 0 splits every one (tests). Thread-safe.
double SplitMinCost();
void SetSplitMinCost(double min_cost);

}  // namespace bitewise::bandit

#endif  // BITEWISE_SERVICES_BANDIT_CORE_SPLIT_RUN_H_
