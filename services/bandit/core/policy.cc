#include "services/bandit/core/policy.h"

#include <algorithm>
#include <cmath>

#include "absl/strings/str_cat.h"
#include "services/domain/random.h"

namespace bitewise::bandit {
namespace {

// Draws for the Monte Carlo propensity of Thompson sampling.
constexpr int kThompsonPropensityDraws = 2000;

std::vector<double> ThompsonScores(const BanditConfig& config,
                                   const std::vector<ActionEstimate>& est,
                                   std::mt19937_64& rng) {
  random::Normal normal;
  std::vector<double> scores(est.size());
  for (size_t a = 0; a < est.size(); ++a) {
    scores[a] =
        est[a].predicted_loss + config.alpha * est[a].width * normal(rng);
  }
  return scores;
}

}  // namespace

std::mt19937_64 SelectRng(uint64_t seed, int64_t select_index) {
  const auto index = static_cast<uint64_t>(select_index);
  std::seed_seq seq{
      static_cast<uint32_t>(seed), static_cast<uint32_t>(seed >> 32),
      static_cast<uint32_t>(index), static_cast<uint32_t>(index >> 32)};
  return std::mt19937_64(seq);
}

int ArgMin(const std::vector<double>& values) {
  int best = 0;
  for (size_t i = 1; i < values.size(); ++i) {
    if (values[i] < values[best]) best = static_cast<int>(i);
  }
  return best;
}

absl::Status CheckEstimatesFinite(
    const std::vector<ActionEstimate>& estimates) {
  for (size_t a = 0; a < estimates.size(); ++a) {
    const ActionEstimate& e = estimates[a];
    if (!std::isfinite(e.predicted_loss) || !std::isfinite(e.width) ||
        !std::isfinite(e.lcb)) {
      return absl::InternalError(absl::StrCat(
          "the model's estimate for action ", a, " is not finite (loss ",
          e.predicted_loss, ", width ", e.width, ", lcb ", e.lcb,
          "): nothing chosen; CheckStore, then ResetUser if it persists"));
    }
  }
  return absl::OkStatus();
}

Choice ChooseAction(const BanditConfig& config,
                    const std::vector<ActionEstimate>& estimates,
                    std::mt19937_64& rng) {
  const int k = static_cast<int>(estimates.size());
  std::vector<double> pred(k), lcb(k);
  for (int a = 0; a < k; ++a) {
    pred[a] = estimates[a].predicted_loss;
    lcb[a] = estimates[a].lcb;
  }
  switch (config.strategy) {
    case Strategy::kLinUcb:
      return {ArgMin(lcb), 1.0};
    case Strategy::kGreedy:
      return {ArgMin(pred), 1.0};
    case Strategy::kEpsilonGreedy: {
      const int greedy = ArgMin(pred);
      int action = greedy;
      if (random::Canonical(rng) < config.epsilon) {
        action = static_cast<int>(random::UniformInt(rng, 0, k - 1));
      }
      const double propensity =
          config.epsilon / k + (action == greedy ? 1.0 - config.epsilon : 0.0);
      return {action, propensity};
    }
    case Strategy::kThompson: {
      const int action = ArgMin(ThompsonScores(config, estimates, rng));
      int hits = 0;
      for (int i = 0; i < kThompsonPropensityDraws; ++i) {
        if (ArgMin(ThompsonScores(config, estimates, rng)) == action) ++hits;
      }
      // The chosen action itself counts as one draw, so hits + 1 > 0.
      return {action,
              static_cast<double>(hits + 1) / (kThompsonPropensityDraws + 1)};
    }
    case Strategy::kUniform:
      return {static_cast<int>(random::UniformInt(rng, 0, k - 1)), 1.0 / k};
  }
  return {ArgMin(lcb), 1.0};
}

}  // namespace bitewise::bandit
