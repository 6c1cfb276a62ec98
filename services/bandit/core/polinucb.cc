#include "services/bandit/core/polinucb.h"

#include <cmath>
#include <cstring>
#include <memory>
#include <utility>

#include "absl/strings/str_cat.h"
#include "services/bandit/core/model_state_io.h"
#include "services/common/status_macros.h"

namespace bitewise::bandit {
namespace {

using Eigen::MatrixXd;
using Eigen::VectorXd;

constexpr char kStateMagic[4] = {'B', 'W', 'P', 'O'};
constexpr int32_t kStateFormat = 1;
constexpr double kLayoutMarker = 1.0 + 1.0 / 1024;
constexpr StateHeader kStateHeader = {kStateMagic, kStateFormat, kLayoutMarker,
                                      "poLinUCB"};

// The context models see the round without its post hoc context.
Round ContextRound(const Round& round, int action, double weight) {
  Round out;
  out.context = round.context;
  out.action = action;
  out.loss = round.loss;
  out.weight = weight;
  return out;
}

// The rounds as the context models see them: per action with its weight,
// and pooled into one action with weight 1.
struct ContextRounds {
  std::vector<Round> per_action;
  std::vector<Round> pooled;
};

ContextRounds SplitRounds(const std::vector<Round>& rounds) {
  ContextRounds out;
  out.per_action.reserve(rounds.size());
  out.pooled.reserve(rounds.size());
  for (const Round& round : rounds) {
    out.per_action.push_back(ContextRound(round, round.action, round.weight));
    out.pooled.push_back(ContextRound(round, 0, 1.0));
  }
  return out;
}

}  // namespace

BanditConfig PoLinUcbModel::ContextsConfig(const BanditConfig& config) {
  BanditConfig inner = config;
  inner.learner = Learner::kContextOnly;
  inner.posthoc_dim = 0;
  inner.prior.phi0.clear();
  return inner;
}

BanditConfig PoLinUcbModel::PooledConfig(const BanditConfig& config) {
  BanditConfig pooled = config;
  pooled.learner = Learner::kContextOnly;
  pooled.posthoc_dim = 0;
  pooled.action_names = {"every round"};
  pooled.prior = PopulationPrior();
  return pooled;
}

absl::StatusOr<PoLinUcbModel> PoLinUcbModel::Create(const BanditConfig& config,
                                                    int primal_threshold) {
  RETURN_IF_ERROR(ValidateConfig(config));
  if (config.learner != Learner::kPoLinUcb) {
    return absl::InvalidArgumentError(
        absl::StrCat("learner: PoLinUcbModel is the polinucb learner, got ",
                     LearnerName(config.learner)));
  }
  ASSIGN_OR_RETURN(
      LinUcbModel contexts,
      LinUcbModel::Create(ContextsConfig(config), primal_threshold));
  ASSIGN_OR_RETURN(LinUcbModel pooled,
                   LinUcbModel::Create(PooledConfig(config), primal_threshold));
  return PoLinUcbModel(config, std::move(contexts), std::move(pooled));
}

PoLinUcbModel::PoLinUcbModel(const BanditConfig& config, LinUcbModel contexts,
                             LinUcbModel pooled)
    : config_(config),
      d_(config.context_dim),
      q_(config.posthoc_dim),
      contexts_(std::move(contexts)),
      pooled_(std::move(pooled)),
      actions_(config.num_actions()),
      s_cp_(MatrixXd::Zero(d_, q_)),
      q_map_(MatrixXd::Zero(d_, q_)) {
  const PopulationPrior& prior = config_.prior;
  const double ridge = config_.lambda_p + prior.kappa_p();
  for (size_t a = 0; a < actions_.size(); ++a) {
    ActionState& s = actions_[a];
    s.e = MatrixXd::Zero(d_, q_);
    s.g = MatrixXd::Zero(d_, q_);
    // C_a^-1 b_c: with a prior, b_c starts at kappa_c theta0.
    s.theta_c = contexts_.Theta(static_cast<int>(a));
    s.p = ridge * MatrixXd::Identity(q_, q_);
    s.bp = VectorXd::Zero(q_);
    if (prior.enabled()) s.bp = prior.kappa_p() * AsVector(prior.phi0[a]);
    Refresh(s);
  }
}

absl::Status PoLinUcbModel::ValidateContext(
    absl::Span<const double> context) const {
  return contexts_.ValidateContext(context);
}

absl::Status PoLinUcbModel::ValidateOutcome(
    double loss, absl::Span<const double> posthoc) const {
  RETURN_IF_ERROR(contexts_.ValidateOutcome(loss, {}));
  return ValidateVector("posthoc", posthoc, static_cast<size_t>(q_),
                        kMaxInputMagnitude);
}

absl::Status PoLinUcbModel::ValidateRound(const Round& round) const {
  RETURN_IF_ERROR(
      contexts_.ValidateRound(ContextRound(round, round.action, round.weight)));
  return ValidateOutcome(round.loss, round.posthoc);
}

void PoLinUcbModel::Refresh(ActionState& s) {
  MatrixXd schur = s.p - s.e.transpose() * s.g;
  schur = (schur + schur.transpose()) / 2;  // symmetric to rounding
  s.s_llt.compute(schur);
  s.beta = s.s_llt.solve(s.bp - s.e.transpose() * s.theta_c);
  const Eigen::SelfAdjointEigenSolver<MatrixXd> eigen(schur,
                                                      Eigen::EigenvaluesOnly);
  s.s_inv_max = 1.0 / eigen.eigenvalues()(0);
}

VectorXd PoLinUcbModel::PredictPosthoc(const Eigen::Ref<const VectorXd>& c,
                                       double* radius,
                                       SelectProducts* products) const {
  if (radius != nullptr) {
    // sqrt(c^T X^-1 c): the pooled model's width.
    const std::vector<ActionEstimate> pooled = pooled_.Estimate(
        absl::Span<const double>(c.data(), static_cast<size_t>(c.size())),
        products);
    *radius = config_.phi_radius * pooled[0].width;
  }
  return q_map_.transpose() * c;
}

VectorXd PoLinUcbModel::PredictPosthoc(absl::Span<const double> c) const {
  return PredictPosthoc(AsVector(c), nullptr, nullptr);
}

double PoLinUcbModel::PosthocRadius(absl::Span<const double> c) const {
  double radius = 0.0;
  PredictPosthoc(AsVector(c), &radius, nullptr);
  return radius;
}

std::vector<ActionEstimate> PoLinUcbModel::Estimate(
    absl::Span<const double> context, SelectProducts* products) const {
  const Eigen::Map<const VectorXd> c = AsVector(context);
  std::vector<ActionEstimate> out = contexts_.Estimate(context, products);
  SelectProducts* pooled_products = nullptr;
  if (products != nullptr) {
    products->nested = std::make_shared<SelectProducts>();
    pooled_products = products->nested.get();
  }
  double radius = 0.0;
  const VectorXd p_hat = PredictPosthoc(c, &radius, pooled_products);
  for (size_t a = 0; a < actions_.size(); ++a) {
    const ActionState& s = actions_[a];
    // With k = C^-1 c: [c; z]^T A^-1 [c; z] = c^T k + (z - G^T c)^T S^-1
    // (z - G^T c), and [c; z]^T [theta; beta] = c^T C^-1 b_c + beta^T
    // (z - G^T c).
    const VectorXd dz = p_hat - s.g.transpose() * c;
    ActionEstimate& est = out[a];
    const double context_part = est.width * est.width;  // c^T C^-1 c
    est.predicted_loss += s.beta.dot(dz);
    est.width =
        std::sqrt(std::max(0.0, context_part + dz.dot(s.s_llt.solve(dz)))) +
        radius * std::sqrt(s.s_inv_max);
    est.lcb =
        est.predicted_loss - config_.alpha * est.width - radius * s.beta.norm();
  }
  return out;
}

void PoLinUcbModel::AddSums(const Round& round) {
  const Eigen::Map<const VectorXd> c = AsVector(round.context);
  const Eigen::Map<const VectorXd> p = AsVector(round.posthoc);
  ActionState& s = actions_[round.action];
  const double w = round.weight;
  s.e.noalias() += w * c * p.transpose();
  s.p.noalias() += w * p * p.transpose();
  s.bp.noalias() += (w * round.loss) * p;
  s_cp_.noalias() += c * p.transpose();
  scale_.weight_sum += w;
  scale_.context_sq_sum += w * c.squaredNorm();
  scale_.posthoc_sq_sum += w * p.squaredNorm();
}

void PoLinUcbModel::Update(const Round& round, const SelectProducts* products) {
  const VectorXd c = AsVector(round.context);
  const Eigen::Map<const VectorXd> p = AsVector(round.posthoc);
  const double w = round.weight;
  ActionState& s = actions_[round.action];
  // Sherman-Morrison with k = C^-1 c before the round: C'^-1 c = k / den,
  // so G' = C'^-1 (E + w c p^T) = G + (w / den) k (p - G^T c)^T, and the
  // same for C^-1 b_c with l for p.
  // The Select's products, when they are of this state and context, save a
  // pass over each form.
  const SelectProducts* pooled_products =
      products != nullptr ? products->nested.get() : nullptr;
  const VectorXd k = contexts_.SolveA(round.action, c, products);
  const double den = 1.0 + w * c.dot(k);
  s.g.noalias() += (w / den) * k * (p - s.g.transpose() * c).transpose();
  s.theta_c.noalias() += (w / den) * (round.loss - c.dot(s.theta_c)) * k;
  // X gains c c^T (weight 1): Q' = X'^-1 (s_cp + c p^T).
  const VectorXd kx = pooled_.SolveA(0, c, pooled_products);
  const double den_x = 1.0 + c.dot(kx);
  q_map_.noalias() +=
      (1.0 / den_x) * kx * (p - q_map_.transpose() * c).transpose();
  AddSums(round);
  contexts_.Update(ContextRound(round, round.action, w), products);
  pooled_.Update(ContextRound(round, 0, 1.0), pooled_products);
  Refresh(s);
}

void PoLinUcbModel::Recompute() {
  for (size_t a = 0; a < actions_.size(); ++a) {
    ActionState& s = actions_[a];
    for (int j = 0; j < q_; ++j) {
      s.g.col(j) = contexts_.SolveA(static_cast<int>(a), s.e.col(j));
    }
    s.theta_c = contexts_.Theta(static_cast<int>(a));
    Refresh(s);
  }
  for (int j = 0; j < q_; ++j) q_map_.col(j) = pooled_.SolveA(0, s_cp_.col(j));
}

void PoLinUcbModel::Replay(const std::vector<Round>& rounds) {
  if (rounds.empty()) return;
  const ContextRounds split = SplitRounds(rounds);
  for (const Round& round : rounds) AddSums(round);
  contexts_.Replay(split.per_action);
  pooled_.Replay(split.pooled);
  Recompute();
}

absl::StatusOr<PoLinUcbModel> PoLinUcbModel::Rebuild(
    const BanditConfig& config, const std::vector<Round>& rounds,
    int primal_threshold) {
  const ContextRounds split = SplitRounds(rounds);
  ASSIGN_OR_RETURN(LinUcbModel context_model,
                   LinUcbModel::Rebuild(ContextsConfig(config),
                                        split.per_action, primal_threshold));
  ASSIGN_OR_RETURN(LinUcbModel pooled_model,
                   LinUcbModel::Rebuild(PooledConfig(config), split.pooled,
                                        primal_threshold));
  ASSIGN_OR_RETURN(PoLinUcbModel model, Create(config, primal_threshold));
  for (const Round& round : rounds) {
    RETURN_IF_ERROR(model.ValidateRound(round));
    model.AddSums(round);
  }
  model.contexts_ = std::move(context_model);
  model.pooled_ = std::move(pooled_model);
  model.Recompute();
  return model;
}

VectorXd PoLinUcbModel::Theta(int action) const {
  const ActionState& s = actions_[action];
  return s.theta_c - s.g * s.beta;
}

VectorXd PoLinUcbModel::Phi(int action) const { return actions_[action].beta; }

size_t PoLinUcbModel::MemoryBytes() const {
  size_t doubles = static_cast<size_t>(s_cp_.size() + q_map_.size());
  for (const ActionState& s : actions_) {
    doubles +=
        static_cast<size_t>(s.e.size() + s.g.size() + s.theta_c.size() +
                            2 * s.p.size() + s.bp.size() + s.beta.size());
  }
  return contexts_.MemoryBytes() + pooled_.MemoryBytes() +
         doubles * sizeof(double) + sizeof(*this) +
         actions_.size() * sizeof(ActionState);
}

size_t PoLinUcbModel::StateBytesBound() const {
  return contexts_.StateBytesBound() + pooled_.StateBytesBound() +
         MemoryBytes() + 4096;
}

void PoLinUcbModel::SaveState(std::string* state) const {
  // The context models' states are written into the same storage after
  // this header's fixed part; their lengths go first.
  const std::string contexts = contexts_.SaveState();
  const std::string pooled = pooled_.SaveState();
  StateWriter out(std::move(*state), StateBytesBound());
  WriteStateHeader(out, kStateHeader);
  out.Value(static_cast<int32_t>(d_));
  out.Value(static_cast<int32_t>(q_));
  out.Value(static_cast<int32_t>(actions_.size()));
  out.Value(config_.lambda_p + config_.prior.kappa_p());
  out.Value(scale_.weight_sum);
  out.Value(scale_.context_sq_sum);
  out.Value(scale_.posthoc_sq_sum);
  out.Doubles(s_cp_.data(), s_cp_.size());
  out.Doubles(q_map_.data(), q_map_.size());
  for (const ActionState& s : actions_) {
    out.Doubles(s.e.data(), s.e.size());
    out.Doubles(s.g.data(), s.g.size());
    out.Doubles(s.theta_c.data(), s.theta_c.size());
    out.Doubles(s.p.data(), s.p.size());
    out.Doubles(s.bp.data(), s.bp.size());
  }
  out.Value(static_cast<uint64_t>(contexts.size()));
  out.Value(static_cast<uint64_t>(pooled.size()));
  std::string head = out.Take();
  head.append(contexts);
  head.append(pooled);
  *state = std::move(head);
}

absl::StatusOr<PoLinUcbModel> PoLinUcbModel::LoadState(
    const BanditConfig& config, absl::string_view state, int primal_threshold) {
  ASSIGN_OR_RETURN(PoLinUcbModel model, Create(config, primal_threshold));
  StateReader in(state);
  RETURN_IF_ERROR(ReadStateHeader(in, kStateHeader));
  int32_t d = 0, q = 0, k = 0;
  double ridge = 0;
  RETURN_IF_ERROR(in.Value(&d, "the header"));
  RETURN_IF_ERROR(in.Value(&q, "the header"));
  RETURN_IF_ERROR(in.Value(&k, "the header"));
  RETURN_IF_ERROR(in.Value(&ridge, "the header"));
  const double want = config.lambda_p + config.prior.kappa_p();
  if (d != model.d_ || q != model.q_ || k != model.num_actions() ||
      ridge != want) {
    return absl::FailedPreconditionError(absl::StrCat(
        "model state: saved for d ", d, ", q ", q, ", ", k,
        " actions, post hoc ridge ", ridge, "; this model has ", model.d_, ", ",
        model.q_, ", ", model.num_actions(), ", ", want));
  }
  RETURN_IF_ERROR(in.Value(&model.scale_.weight_sum, "the header"));
  RETURN_IF_ERROR(in.Value(&model.scale_.context_sq_sum, "the header"));
  RETURN_IF_ERROR(in.Value(&model.scale_.posthoc_sq_sum, "the header"));
  RETURN_IF_ERROR(
      in.Doubles(model.s_cp_.data(), model.s_cp_.size(), "the pooled sums"));
  RETURN_IF_ERROR(
      in.Doubles(model.q_map_.data(), model.q_map_.size(), "the pooled map"));
  for (ActionState& s : model.actions_) {
    RETURN_IF_ERROR(in.Doubles(s.e.data(), s.e.size(), "an action's E"));
    RETURN_IF_ERROR(in.Doubles(s.g.data(), s.g.size(), "an action's G"));
    RETURN_IF_ERROR(
        in.Doubles(s.theta_c.data(), s.theta_c.size(), "an action's theta"));
    RETURN_IF_ERROR(in.Doubles(s.p.data(), s.p.size(), "an action's P"));
    RETURN_IF_ERROR(in.Doubles(s.bp.data(), s.bp.size(), "an action's r"));
  }
  uint64_t contexts_bytes = 0, pooled_bytes = 0;
  RETURN_IF_ERROR(in.Value(&contexts_bytes, "the context models' sizes"));
  RETURN_IF_ERROR(in.Value(&pooled_bytes, "the context models' sizes"));
  if (in.left() != contexts_bytes + pooled_bytes) {
    return absl::DataLossError(absl::StrCat(
        "model state: ", in.left(), " bytes of context models, expected ",
        contexts_bytes + pooled_bytes));
  }
  const absl::string_view rest = state.substr(state.size() - in.left());
  ASSIGN_OR_RETURN(
      model.contexts_,
      LinUcbModel::LoadState(ContextsConfig(config),
                             rest.substr(0, contexts_bytes), primal_threshold));
  ASSIGN_OR_RETURN(
      model.pooled_,
      LinUcbModel::LoadState(PooledConfig(config), rest.substr(contexts_bytes),
                             primal_threshold));
  for (ActionState& s : model.actions_) model.Refresh(s);
  return model;
}

}  // namespace bitewise::bandit
