#include "services/bandit/core/config.h"

#include <cmath>

#include "absl/strings/str_cat.h"
#include "services/bandit/core/learners.h"
#include "services/domain/skewering_actions.h"

namespace bitewise::bandit {

const char* LearnerName(Learner learner) {
  const LearnerSpec* spec = FindLearner(learner);
  return spec != nullptr ? spec->name : "unknown";
}

bool UsesPosthoc(Learner learner) {
  const LearnerSpec* spec = FindLearner(learner);
  return spec != nullptr && spec->uses_posthoc;
}

const char* StrategyName(Strategy strategy) {
  switch (strategy) {
    case Strategy::kLinUcb:
      return "linucb";
    case Strategy::kGreedy:
      return "greedy";
    case Strategy::kEpsilonGreedy:
      return "epsilon_greedy";
    case Strategy::kThompson:
      return "thompson";
    case Strategy::kUniform:
      return "uniform";
  }
  return "unknown";
}

std::vector<std::string> DefaultActionNames() {
  std::vector<std::string> names;
  for (const domain::SkeweringAction& action : domain::kSkeweringActions) {
    names.push_back(action.name);
  }
  return names;
}

absl::Status ValidateConfig(const BanditConfig& config) {
  auto bad = [](auto... parts) {
    return absl::InvalidArgumentError(absl::StrCat(parts...));
  };
  if (FindLearner(config.learner) == nullptr) {
    return bad("learner: unknown value ", static_cast<int>(config.learner),
               " (known: ", LearnerNames(), ")");
  }
  if (static_cast<int>(config.strategy) < 1 ||
      static_cast<int>(config.strategy) > 5) {
    return bad("strategy: unknown value ", static_cast<int>(config.strategy));
  }
  if (!std::isfinite(config.alpha) || config.alpha < 0) {
    return bad("alpha: must be finite and >= 0, got ", config.alpha);
  }
  if (!std::isfinite(config.lambda_c) || config.lambda_c <= 0) {
    return bad("lambda_c: must be finite and > 0, got ", config.lambda_c);
  }
  if (!std::isfinite(config.lambda_p) || config.lambda_p <= 0) {
    return bad("lambda_p: must be finite and > 0, got ", config.lambda_p);
  }
  if (!std::isfinite(config.phi_radius) || config.phi_radius < 0) {
    return bad("phi_radius: must be finite and >= 0, got ", config.phi_radius);
  }
  if (!std::isfinite(config.epsilon) || config.epsilon < 0 ||
      config.epsilon > 1) {
    return bad("epsilon: must be in [0, 1], got ", config.epsilon);
  }
  constexpr int kMaxDim = 1 << 16;
  if (config.context_dim < 1 || config.context_dim > kMaxDim) {
    return bad("context_dim: must be in [1, ", kMaxDim, "], got ",
               config.context_dim);
  }
  if (config.posthoc_dim < 0 || config.posthoc_dim > 1024) {
    return bad("posthoc_dim: must be in [0, 1024], got ", config.posthoc_dim);
  }
  if (UsesPosthoc(config.learner) && config.posthoc_dim < 1) {
    return bad("posthoc_dim: the ", LearnerName(config.learner),
               " learner needs posthoc_dim >= 1");
  }
  if (config.num_actions() < 1 || config.num_actions() > 256) {
    return bad("action_names: need between 1 and 256 actions, got ",
               config.num_actions());
  }
  for (size_t i = 0; i < config.action_names.size(); ++i) {
    if (config.action_names[i].empty() ||
        config.action_names[i].size() > kMaxActionNameBytes) {
      return bad("action_names[", i, "]: must be 1-", kMaxActionNameBytes,
                 " bytes, got ", config.action_names[i].size());
    }
    for (size_t j = 0; j < i; ++j) {
      if (config.action_names[i] == config.action_names[j]) {
        return bad("action_names[", i, "]: duplicate name \"",
                   config.action_names[i], "\"");
      }
    }
  }
  const PopulationPrior& prior = config.prior;
  if (prior.pool_version < 0) {
    return bad("prior.pool_version: must be >= 0, got ", prior.pool_version);
  }
  // A prior worth more rounds than any person eats in years; far beyond it
  // the ridge rounds * msn overflows (1e300 rounds: an infinite ridge and a
  // model of NaN, which every Select then refuses).
  constexpr double kMaxPriorRounds = 1e6;
  if (!std::isfinite(prior.rounds) || prior.rounds < 0 ||
      prior.rounds > kMaxPriorRounds) {
    return bad("prior.rounds: must be in [0, ", kMaxPriorRounds, "], got ",
               prior.rounds);
  }
  if (prior.enabled()) {
    const bool posthoc = UsesPosthoc(config.learner);
    if (!std::isfinite(prior.context_msn) || prior.context_msn <= 0 ||
        (posthoc &&
         (!std::isfinite(prior.posthoc_msn) || prior.posthoc_msn <= 0)) ||
        !std::isfinite(prior.rounds * prior.context_msn) ||
        (posthoc && !std::isfinite(prior.rounds * prior.posthoc_msn))) {
      return bad(
          "prior: context_msn (and posthoc_msn for the post hoc "
          "learner) must be finite and > 0, and so must the ridges rounds "
          "x msn");
    }
    auto check = [&](const char* field,
                     const std::vector<std::vector<double>>& rows,
                     int dim) -> absl::Status {
      if (static_cast<int>(rows.size()) != config.num_actions()) {
        return bad("prior.", field, ": expected ", config.num_actions(),
                   " actions, got ", rows.size());
      }
      for (size_t a = 0; a < rows.size(); ++a) {
        if (static_cast<int>(rows[a].size()) != dim) {
          return bad("prior.", field, "[", a, "]: expected ", dim,
                     " values, got ", rows[a].size());
        }
        for (double v : rows[a]) {
          if (!std::isfinite(v)) {
            return bad("prior.", field, "[", a, "]: must be finite");
          }
        }
      }
      return absl::OkStatus();
    };
    if (absl::Status s = check("theta0", prior.theta0, config.context_dim);
        !s.ok()) {
      return s;
    }
    if (posthoc) {
      if (absl::Status s = check("phi0", prior.phi0, config.posthoc_dim);
          !s.ok()) {
        return s;
      }
    }
  }
  return absl::OkStatus();
}

}  // namespace bitewise::bandit
