#include "experiments/replay.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <random>
#include <string>
#include <utility>

#include "absl/strings/str_cat.h"
#include "services/bandit/core/learners.h"
#include "services/bandit/core/policy.h"
#include "services/common/status_macros.h"
#include "services/domain/random.h"

namespace bitewise::experiments {
namespace {

struct Mean {
  double sum = 0.0;
  int count = 0;
};

// Linear-interpolated percentile of sorted values, q in [0, 1].
double Percentile(const std::vector<double>& sorted, double q) {
  const double pos = q * (sorted.size() - 1);
  const size_t lo = static_cast<size_t>(std::floor(pos));
  const size_t hi = std::min(lo + 1, sorted.size() - 1);
  return sorted[lo] + (pos - lo) * (sorted[hi] - sorted[lo]);
}

Interval Summarize(std::vector<double> values) {
  Interval out;
  for (double v : values) out.mean += v;
  out.mean /= static_cast<double>(values.size());
  std::sort(values.begin(), values.end());
  out.lower = Percentile(values, 0.025);
  out.upper = Percentile(values, 0.975);
  return out;
}

}  // namespace

absl::StatusOr<ImputedLosses> ImputeLosses(const EventLog& log,
                                           DrWeight weight) {
  const int n = static_cast<int>(log.events.size());
  const int k = log.num_actions;
  if (n == 0 || k < 1) {
    return absl::InvalidArgumentError("the log has no events or no actions");
  }
  ImputedLosses out;
  out.direct.resize(n, k);
  if (log.labelled) {
    for (int i = 0; i < n; ++i) {
      for (int a = 0; a < k; ++a) out.direct(i, a) = log.events[i].losses[a];
    }
    out.doubly_robust = out.direct;
    return out;
  }
  std::map<std::pair<std::string, int>, Mean> by_food;
  std::vector<Mean> by_action(k);
  Mean overall;
  for (const LoggedEvent& e : log.events) {
    Mean& f = by_food[{e.item_label, e.action}];
    f.sum += e.loss;
    ++f.count;
    by_action[e.action].sum += e.loss;
    ++by_action[e.action].count;
    overall.sum += e.loss;
    ++overall.count;
  }
  for (int i = 0; i < n; ++i) {
    const LoggedEvent& e = log.events[i];
    for (int a = 0; a < k; ++a) {
      const auto it = by_food.find({e.item_label, a});
      const Mean& m = it != by_food.end()      ? it->second
                      : by_action[a].count > 0 ? by_action[a]
                                               : overall;
      out.direct(i, a) = m.sum / m.count;
    }
  }
  out.doubly_robust = out.direct;
  for (int i = 0; i < n; ++i) {
    const LoggedEvent& e = log.events[i];
    const double w = weight == DrWeight::kNumActions ? k : 1.0 / e.propensity;
    out.doubly_robust(i, e.action) += w * (e.loss - out.direct(i, e.action));
  }
  return out;
}

absl::StatusOr<ReplayEstimate> ReplaySettingOnLog(const EventLog& log,
                                                  const ImputedLosses& imputed,
                                                  const ReplaySetting& setting,
                                                  int replays, uint64_t seed) {
  const int n = static_cast<int>(log.events.size());
  if (n == 0 || replays < 1) {
    return absl::InvalidArgumentError("need events and at least one replay");
  }
  const bool posthoc = bandit::UsesPosthoc(setting.learner);
  if (posthoc && log.events.front().posthoc.empty()) {
    return absl::InvalidArgumentError(
        "the post hoc learner needs post hoc contexts in the log");
  }
  bandit::BanditConfig config;
  config.learner = setting.learner;
  config.strategy = bandit::Strategy::kLinUcb;
  config.alpha = setting.alpha;
  config.lambda_c = setting.lambda_c;
  config.lambda_p = setting.lambda_p;
  config.context_dim = static_cast<int>(log.events.front().context.size());
  config.posthoc_dim =
      posthoc ? static_cast<int>(log.events.front().posthoc.size()) : 1;
  config.action_names.clear();
  for (int a = 0; a < log.num_actions; ++a) {
    config.action_names.push_back(absl::StrCat("a", a));
  }
  std::vector<double> dm_totals, dr_totals;
  for (int r = 0; r < replays; ++r) {
    ASSIGN_OR_RETURN(std::unique_ptr<bandit::LearnerModel> owned,
                     bandit::CreateModel(config));
    bandit::LearnerModel& model = *owned;
    std::mt19937_64 rng(random::MixSeed(seed, r));
    double dm = 0.0, dr = 0.0;
    for (int t = 0; t < n; ++t) {
      const int i = random::UniformIndex(rng, n);
      const LoggedEvent& e = log.events[i];
      std::vector<double> lcb;
      for (const auto& est : model.Estimate(e.context)) lcb.push_back(est.lcb);
      const int a = bandit::ArgMin(lcb);
      dm += imputed.direct(i, a);
      dr += imputed.doubly_robust(i, a);
      bandit::Round round;
      round.context = e.context;
      round.action = a;
      round.loss = log.labelled    ? e.losses[a]
                   : a == e.action ? e.loss
                                   : imputed.direct(i, a);
      if (posthoc) round.posthoc = e.posthoc;
      RETURN_IF_ERROR(model.ValidateRound(round));
      model.Update(round);
    }
    dm_totals.push_back(dm);
    dr_totals.push_back(dr);
  }
  ReplayEstimate out;
  out.setting = setting;
  out.direct = Summarize(std::move(dm_totals));
  out.doubly_robust = Summarize(std::move(dr_totals));
  return out;
}

}  // namespace bitewise::experiments
