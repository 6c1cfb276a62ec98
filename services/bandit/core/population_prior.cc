#include "services/bandit/core/population_prior.h"

#include <cmath>

#include "absl/strings/str_cat.h"

namespace bitewise::bandit {

PriorPool::PriorPool(const BanditConfig& config) : config_(config) {
  const int k = config.num_actions();
  const int q = UsesPosthoc(config.learner) ? config.posthoc_dim : 0;
  theta_sum_.assign(k, Eigen::VectorXd::Zero(config.context_dim));
  phi_sum_.assign(k, Eigen::VectorXd::Zero(q));
  counts_.assign(k, 0);
}

bool PriorPool::Accepts(const LearnerModel& model) const {
  const BanditConfig& c = model.config();
  return c.learner == config_.learner && c.context_dim == config_.context_dim &&
         (!UsesPosthoc(c.learner) || c.posthoc_dim == config_.posthoc_dim) &&
         c.action_names == config_.action_names;
}

absl::Status PriorPool::Add(const LearnerModel& model) {
  if (!Accepts(model)) {
    return absl::InvalidArgumentError(
        "the model differs from the pool in learner, dimensions or actions; "
        "only like models can be pooled");
  }
  // Checked whole before anything is added: one model's NaN would make
  // every later user's prior NaN.
  for (int a = 0; a < config_.num_actions(); ++a) {
    if (model.Count(a) == 0) continue;
    if (!model.Theta(a).allFinite() ||
        (UsesPosthoc(config_.learner) && !model.Phi(a).allFinite())) {
      return absl::FailedPreconditionError(
          absl::StrCat("the model's estimate for action ", a,
                       " is not finite; it cannot be pooled"));
    }
  }
  for (int a = 0; a < config_.num_actions(); ++a) {
    const int64_t n = model.Count(a);
    if (n == 0) continue;
    theta_sum_[a] += static_cast<double>(n) * model.Theta(a);
    if (UsesPosthoc(config_.learner)) {
      phi_sum_[a] += static_cast<double>(n) * model.Phi(a);
    }
    counts_[a] += n;
  }
  scale_.weight_sum += model.input_scale().weight_sum;
  scale_.context_sq_sum += model.input_scale().context_sq_sum;
  scale_.posthoc_sq_sum += model.input_scale().posthoc_sq_sum;
  ++users_;
  return absl::OkStatus();
}

absl::StatusOr<PopulationPrior> PriorPool::Finish(double rounds,
                                                  int64_t pool_version) const {
  if (pool_version < 1 || !std::isfinite(rounds) || rounds < 0.0) {
    return absl::InvalidArgumentError(absl::StrCat(
        "pool_version must be >= 1 and rounds finite and >= 0, got ",
        pool_version, " and ", rounds));
  }
  if (!(scale_.weight_sum > 0.0)) {
    return absl::InvalidArgumentError(
        "the pooled users have no completed rounds");
  }
  PopulationPrior prior;
  prior.pool_version = pool_version;
  prior.rounds = rounds;
  prior.context_msn = scale_.context_sq_sum / scale_.weight_sum;
  const bool posthoc = UsesPosthoc(config_.learner);
  prior.posthoc_msn = posthoc ? scale_.posthoc_sq_sum / scale_.weight_sum : 0;
  for (int a = 0; a < config_.num_actions(); ++a) {
    const double n = counts_[a] > 0 ? static_cast<double>(counts_[a]) : 1.0;
    const Eigen::VectorXd theta = theta_sum_[a] / n;
    prior.theta0.emplace_back(theta.data(), theta.data() + theta.size());
    if (posthoc) {
      const Eigen::VectorXd phi = phi_sum_[a] / n;
      prior.phi0.emplace_back(phi.data(), phi.data() + phi.size());
    }
  }
  return prior;
}

absl::StatusOr<PopulationPrior> PooledPrior(
    const std::vector<const LearnerModel*>& models, double rounds,
    int64_t pool_version) {
  if (models.empty()) {
    return absl::InvalidArgumentError("pooling needs at least one user");
  }
  PriorPool pool(models.front()->config());
  for (size_t u = 0; u < models.size(); ++u) {
    if (!pool.Accepts(*models[u])) {
      return absl::InvalidArgumentError(absl::StrCat(
          "model ", u,
          " differs from model 0 in learner, dimensions or actions; only "
          "like models can be pooled"));
    }
    absl::Status added = pool.Add(*models[u]);
    if (!added.ok()) return added;
  }
  return pool.Finish(rounds, pool_version);
}

}  // namespace bitewise::bandit
