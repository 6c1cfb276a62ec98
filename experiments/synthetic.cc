#include "experiments/synthetic.h"

#include <memory>
#include <random>
#include <string>

#include "absl/strings/str_cat.h"
#include "services/bandit/core/learners.h"
#include "services/bandit/core/policy.h"
#include "services/common/status_macros.h"
#include "services/domain/random.h"

namespace bitewise::experiments {

SyntheticWorld DrawSyntheticWorld(const SyntheticConfig& config,
                                  uint64_t seed) {
  std::mt19937_64 rng(seed);
  SyntheticWorld world;
  world.phi.resize(config.num_actions, config.posthoc_dim);
  for (int a = 0; a < config.num_actions; ++a) {
    for (int j = 0; j < config.posthoc_dim; ++j) {
      world.phi(a, j) = random::Uniform01(rng) / config.posthoc_dim;
    }
  }
  world.contexts.resize(config.rounds, config.context_dim);
  world.coins.resize(config.rounds);
  for (int t = 0; t < config.rounds; ++t) {
    for (int j = 0; j < config.context_dim; ++j) {
      world.contexts(t, j) = random::Uniform01(rng);
    }
    world.coins(t) = random::Uniform01(rng);
  }
  return world;
}

absl::StatusOr<std::vector<double>> RunSyntheticTrial(
    const SyntheticConfig& config, const SyntheticWorld& world,
    bandit::Learner learner) {
  bandit::BanditConfig bc;
  bc.learner = learner;
  bc.strategy = bandit::Strategy::kLinUcb;
  bc.alpha = config.alpha;
  bc.lambda_c = config.lambda_c;
  bc.lambda_p = config.lambda_p;
  bc.phi_radius = config.phi_radius;
  bc.context_dim = config.context_dim;
  bc.posthoc_dim = config.posthoc_dim;
  bc.action_names.clear();
  for (int a = 0; a < config.num_actions; ++a) {
    bc.action_names.push_back(absl::StrCat("a", a));
  }
  ASSIGN_OR_RETURN(std::unique_ptr<bandit::LearnerModel> owned,
                   bandit::CreateModel(bc));
  bandit::LearnerModel& model = *owned;

  std::vector<double> cumulative(config.rounds);
  double total = 0.0;
  std::vector<double> context(config.context_dim);
  for (int t = 0; t < config.rounds; ++t) {
    for (int j = 0; j < config.context_dim; ++j) {
      context[j] = world.contexts(t, j);
    }
    const Eigen::VectorXd p = world.contexts.row(t).head(config.posthoc_dim);
    const Eigen::VectorXd mean_loss = world.phi * p;
    std::vector<double> lcb;
    for (const auto& e : model.Estimate(context)) lcb.push_back(e.lcb);
    const int action = bandit::ArgMin(lcb);
    total += mean_loss(action) - mean_loss.minCoeff();
    cumulative[t] = total;

    bandit::Round round;
    round.context = context;
    round.action = action;
    round.loss = config.loss == SyntheticLoss::kLinear
                     ? mean_loss(action)
                     : (world.coins(t) < mean_loss(action) ? 1.0 : 0.0);
    if (bandit::UsesPosthoc(learner)) {
      round.posthoc.assign(p.data(), p.data() + p.size());
    }
    RETURN_IF_ERROR(model.ValidateRound(round));
    model.Update(round);
  }
  return cumulative;
}

}  // namespace bitewise::experiments
