#include "services/bandit/core/polinucb.h"

#include <cmath>
#include <cstring>
#include <functional>
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
// 2: the pooled factors (format 1, without them, still loads: such a model
// answers from the pooled model's rows until they would be dropped anyway).
constexpr int32_t kStateFormat = 2;
constexpr int32_t kOldestStateFormat = 1;
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

double* GrowingLower::AppendRow() {
  const int block = rows_ / kBlockRows;
  const size_t first = static_cast<size_t>(block) * kBlockRows;
  const size_t width = first + kBlockRows;
  if (block == static_cast<int>(blocks_.size())) {
    blocks_.emplace_back(new double[kBlockRows * width]);
  }
  double* out = blocks_[block].get() + (rows_ - first) * width;
  ++rows_;
  return out;
}

const double* GrowingLower::Row(int i) const {
  const int block = i / kBlockRows;
  const size_t first = static_cast<size_t>(block) * kBlockRows;
  return blocks_[block].get() + (i - first) * (first + kBlockRows);
}

GrowingLower::Block GrowingLower::BlockAt(int b) const {
  const int first = b * kBlockRows;
  const int width = first + kBlockRows;
  return Block(blocks_[b].get(), std::min(kBlockRows, rows_ - first), width,
               Eigen::OuterStride<>(width));
}

size_t GrowingLower::CapacityDoubles() const {
  size_t n = 0;
  for (size_t b = 0; b < blocks_.size(); ++b) {
    n += kBlockRows * ((b + 1) * kBlockRows);
  }
  return n;
}

VectorXd GrowingLower::Times(const Eigen::Ref<const VectorXd>& x) const {
  VectorXd y(rows_);
  for (int b = 0; b * kBlockRows < rows_; ++b) {
    const Block block = BlockAt(b);
    const int first = b * kBlockRows;
    const int r = static_cast<int>(block.rows());
    y.segment(first, r).noalias() =
        block.block(0, first, r, r).triangularView<Eigen::Lower>() *
        x.segment(first, r);
    if (first > 0) {
      y.segment(first, r).noalias() += block.leftCols(first) * x.head(first);
    }
  }
  return y;
}

MatrixXd GrowingLower::TimesMatrix(const Eigen::Ref<const MatrixXd>& x) const {
  MatrixXd y(rows_, x.cols());
  for (int b = 0; b * kBlockRows < rows_; ++b) {
    const Block block = BlockAt(b);
    const int first = b * kBlockRows;
    const int r = static_cast<int>(block.rows());
    y.middleRows(first, r).noalias() =
        block.block(0, first, r, r).triangularView<Eigen::Lower>() *
        x.middleRows(first, r);
    if (first > 0) {
      y.middleRows(first, r).noalias() +=
          block.leftCols(first) * x.topRows(first);
    }
  }
  return y;
}

VectorXd GrowingLower::Solve(const Eigen::Ref<const VectorXd>& k) const {
  VectorXd u = k;
  for (int b = 0; b * kBlockRows < rows_; ++b) {
    const Block block = BlockAt(b);
    const int first = b * kBlockRows;
    const int r = static_cast<int>(block.rows());
    if (first > 0) {
      u.segment(first, r).noalias() -= block.leftCols(first) * u.head(first);
    }
    block.block(0, first, r, r)
        .triangularView<Eigen::Lower>()
        .solveInPlace(u.segment(first, r));
  }
  return u;
}

MatrixXd GrowingLower::SolveMatrix(const Eigen::Ref<const MatrixXd>& k) const {
  MatrixXd u = k;
  for (int b = 0; b * kBlockRows < rows_; ++b) {
    const Block block = BlockAt(b);
    const int first = b * kBlockRows;
    const int r = static_cast<int>(block.rows());
    if (first > 0) {
      u.middleRows(first, r).noalias() -=
          block.leftCols(first) * u.topRows(first);
    }
    block.block(0, first, r, r)
        .triangularView<Eigen::Lower>()
        .solveInPlace(u.middleRows(first, r));
  }
  return u;
}

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
  factors_.on = true;
  factors_.per_action.resize(actions_.size());
  factors_.row.resize(actions_.size());
  factors_.scale.resize(actions_.size());
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
  // S = P - E^T C^-1 E >= ridge I exactly (the data's part is a Schur
  // complement of a positive semi-definite matrix). When the ridge is below
  // the rounding error of the inputs' squares, the subtraction cancels and
  // leaves eigenvalues below the ridge, even negative (a failed Cholesky,
  // NaN estimates); they are raised to the ridge, their true floor.
  const double ridge = config_.lambda_p + config_.prior.kappa_p();
  double smallest =
      Eigen::SelfAdjointEigenSolver<MatrixXd>(schur, Eigen::EigenvaluesOnly)
          .eigenvalues()(0);
  if (!(smallest >= ridge)) {
    const Eigen::SelfAdjointEigenSolver<MatrixXd> eigen(schur);
    const VectorXd floored = eigen.eigenvalues().cwiseMax(ridge);
    schur = eigen.eigenvectors() * floored.asDiagonal() *
            eigen.eigenvectors().transpose();
    schur = (schur + schur.transpose()) / 2;
    smallest = floored.minCoeff();
  }
  s.s_llt.compute(schur);
  s.beta = s.s_llt.solve(s.bp - s.e.transpose() * s.theta_c);
  s.s_inv_max = 1.0 / smallest;
}

bool PoLinUcbModel::AllDual() const {
  if (pooled_.IsPrimal(0)) return false;
  for (int a = 0; a < num_actions(); ++a) {
    if (contexts_.IsPrimal(a)) return false;
  }
  return true;
}

VectorXd PoLinUcbModel::PooledKernel(const std::vector<VectorXd>& v) const {
  // Action a's rows of R c: D_a^-1/2 L_a (W_a c).
  VectorXd k(factors_.pooled.rows());
  for (size_t a = 0; a < actions_.size(); ++a) {
    const std::vector<int>& rows = factors_.row[a];
    if (rows.empty()) continue;
    const VectorXd raw = factors_.per_action[a].Times(v[a]);
    const std::vector<double>& scale = factors_.scale[a];
    for (size_t i = 0; i < rows.size(); ++i) k(rows[i]) = raw(i) * scale[i];
  }
  return k;
}

double PoLinUcbModel::PooledWidth(const Eigen::Ref<const VectorXd>& c,
                                  const SelectProducts* context_products,
                                  SelectProducts* pooled_products) const {
  const absl::Span<const double> span(c.data(), static_cast<size_t>(c.size()));
  if (!factors_.on) return pooled_.Estimate(span, pooled_products)[0].width;
  std::vector<VectorXd> computed;
  if (context_products == nullptr) {
    computed.resize(actions_.size());
    for (int a = 0; a < num_actions(); ++a) {
      computed[a] = contexts_.DualProducts(a, c);
    }
  }
  // u = L_X^-1 R c, which is W_X c, the pooled model's Select product.
  VectorXd u = factors_.pooled.Solve(PooledKernel(
      context_products != nullptr ? context_products->per_action : computed));
  const double var = (c.squaredNorm() - u.squaredNorm()) / pooled_.ridge();
  if (pooled_products != nullptr) {
    pooled_products->total_rounds = pooled_.TotalRounds();
    pooled_products->context.assign(span.begin(), span.end());
    pooled_products->per_action.resize(1);
    pooled_products->per_action[0] = std::move(u);
  }
  return std::sqrt(std::max(var, 0.0));
}

VectorXd PoLinUcbModel::PredictPosthoc(absl::Span<const double> c) const {
  return q_map_.transpose() * AsVector(c);
}

double PoLinUcbModel::PosthocRadius(absl::Span<const double> c) const {
  return config_.phi_radius * PooledWidth(AsVector(c), nullptr, nullptr);
}

std::vector<ActionEstimate> PoLinUcbModel::Estimate(
    absl::Span<const double> context, SelectProducts* products) const {
  const Eigen::Map<const VectorXd> c = AsVector(context);
  // The context models' products feed the pooled factors: kept here when
  // the caller does not want them.
  SelectProducts own;
  SelectProducts* context_products =
      products != nullptr ? products : (factors_.on ? &own : nullptr);
  SelectProducts* pooled_products = nullptr;
  if (products != nullptr) {
    products->nested = std::make_shared<SelectProducts>();
    pooled_products = products->nested.get();
  }
  // Without the factors the pooled width is a pass of its own over X^-1,
  // run beside the six actions' passes; with them it comes from theirs.
  double pooled_width = 0.0;
  std::function<void()> pooled_pass;
  if (!factors_.on) {
    pooled_pass = [&] {
      pooled_width = PooledWidth(c, nullptr, pooled_products);
    };
  }
  std::vector<ActionEstimate> out = contexts_.EstimateAlongside(
      context, context_products, pooled_pass, pooled_.SelectCost(0));
  if (factors_.on) {
    pooled_width = PooledWidth(c, context_products, pooled_products);
  }
  const double radius = config_.phi_radius * pooled_width;
  const VectorXd p_hat = q_map_.transpose() * c;
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

void PoLinUcbModel::GrowFactors(const Round& round, const VectorXd& v,
                                const VectorXd& u) {
  const Eigen::Map<const VectorXd> c = AsVector(round.context);
  // L_X's new row [u^T delta], delta^2 = lambda + |c|^2 - |u|^2.
  const int n = factors_.pooled.rows();
  const double lambda_x = pooled_.ridge();
  double* row = factors_.pooled.AppendRow();
  std::copy(u.data(), u.data() + n, row);
  // delta^2 >= lambda exactly; its floor when rounding cancels it
  // (LinUcbModel::Update).
  row[n] = std::sqrt(
      std::max(lambda_x + c.squaredNorm() - u.squaredNorm(), lambda_x));
  // L_a's, as LinUcbModel's Update computes it: [l^T delta] with
  // l = sqrt(w) W_a c.
  const int a = round.action;
  const double sw = std::sqrt(round.weight);
  const double lambda_a = contexts_.ridge();
  const VectorXd x = sw * c;
  const VectorXd l = sw * v;
  const double delta2 = lambda_a + x.squaredNorm() - l.squaredNorm();
  GrowingLower& factor = factors_.per_action[a];
  const int m = factor.rows();
  row = factor.AppendRow();
  std::copy(l.data(), l.data() + m, row);
  row[m] = std::sqrt(std::max(delta2, lambda_a));
  factors_.row[a].push_back(n);
  factors_.scale[a].push_back(1.0 / sw);
}

void PoLinUcbModel::ExtendFactors(const std::vector<Round>& rounds) {
  const int k = static_cast<int>(rounds.size());
  const int n = factors_.pooled.rows();
  MatrixXd cols(d_, k);  // the new contexts
  for (int j = 0; j < k; ++j) cols.col(j) = AsVector(rounds[j].context);
  // Every action's W_a (new contexts), and from them R_old (new contexts).
  std::vector<MatrixXd> v(actions_.size());
  MatrixXd k12(n, k);
  for (size_t a = 0; a < actions_.size(); ++a) {
    const std::vector<int>& rows = factors_.row[a];
    if (rows.empty()) continue;
    v[a] = contexts_.DualProducts(static_cast<int>(a), cols);
    const MatrixXd raw = factors_.per_action[a].TimesMatrix(v[a]);
    for (size_t i = 0; i < rows.size(); ++i) {
      k12.row(rows[i]) = raw.row(i) * factors_.scale[a][i];
    }
  }
  // L_X's new block row [B L22]: B^T = L_X^-1 K12, L22 L22^T = lambda I +
  // R_new R_new^T - B B^T.
  const MatrixXd bt = factors_.pooled.SolveMatrix(k12);
  MatrixXd k22 = pooled_.ridge() * MatrixXd::Identity(k, k);
  k22.selfadjointView<Eigen::Lower>().rankUpdate(cols.transpose());
  if (n > 0) k22.selfadjointView<Eigen::Lower>().rankUpdate(bt.transpose(), -1);
  const Eigen::LLT<MatrixXd> llt(k22);
  const MatrixXd l22 = llt.matrixL();
  for (int j = 0; j < k; ++j) {
    double* row = factors_.pooled.AppendRow();
    if (n > 0) Eigen::Map<VectorXd>(row, n) = bt.col(j);
    Eigen::Map<Eigen::RowVectorXd>(row + n, j + 1) = l22.row(j).head(j + 1);
  }
  // Each L_a likewise, with X_a = D^1/2 C_new: B = X_a W_a^T, L22 L22^T =
  // lambda I + X_a X_a^T - B B^T.
  for (size_t a = 0; a < actions_.size(); ++a) {
    std::vector<int> taken;
    for (int j = 0; j < k; ++j) {
      if (rounds[j].action == static_cast<int>(a)) taken.push_back(j);
    }
    if (taken.empty()) continue;
    GrowingLower& factor = factors_.per_action[a];
    const int m = factor.rows();
    const int t = static_cast<int>(taken.size());
    MatrixXd x(t, d_);
    MatrixXd b(t, m);
    for (int i = 0; i < t; ++i) {
      const double sw = std::sqrt(rounds[taken[i]].weight);
      x.row(i) = sw * cols.col(taken[i]).transpose();
      if (m > 0) b.row(i) = sw * v[a].col(taken[i]).transpose();
    }
    MatrixXd g = contexts_.ridge() * MatrixXd::Identity(t, t);
    g.selfadjointView<Eigen::Lower>().rankUpdate(x);
    if (m > 0) g.selfadjointView<Eigen::Lower>().rankUpdate(b, -1);
    const Eigen::LLT<MatrixXd> factor_llt(g);
    const MatrixXd lower = factor_llt.matrixL();
    for (int i = 0; i < t; ++i) {
      double* row = factor.AppendRow();
      if (m > 0) Eigen::Map<Eigen::RowVectorXd>(row, m) = b.row(i);
      Eigen::Map<Eigen::RowVectorXd>(row + m, i + 1) = lower.row(i).head(i + 1);
      factors_.row[a].push_back(n + taken[i]);
      factors_.scale[a].push_back(1.0 / std::sqrt(rounds[taken[i]].weight));
    }
  }
}

void PoLinUcbModel::Update(const Round& round, const SelectProducts* products) {
  const VectorXd c = AsVector(round.context);
  const Eigen::Map<const VectorXd> p = AsVector(round.posthoc);
  const double w = round.weight;
  ActionState& s = actions_[round.action];
  // The Select's products, when they are of this state and context, save a
  // pass over each form.
  const SelectProducts* pooled_products =
      products != nullptr ? products->nested.get() : nullptr;
  SelectProducts own, own_pooled;
  if (factors_.on) {
    // The factors gain the round from every action's W_a c and u = W_X c:
    // the Select's if they are current, else computed here (one pass over
    // the actions' rows, none over the pooled model's), and then handed to
    // the context models' Updates as if from a Select.
    bool current = products != nullptr &&
                   products->total_rounds == contexts_.TotalRounds() &&
                   products->context == round.context &&
                   products->per_action.size() == actions_.size();
    for (int a = 0; current && a < num_actions(); ++a) {
      current = products->per_action[a].size() == contexts_.Count(a);
    }
    if (!current) {
      own.total_rounds = contexts_.TotalRounds();
      own.context = round.context;
      own.per_action.resize(actions_.size());
      for (int a = 0; a < num_actions(); ++a) {
        own.per_action[a] = contexts_.DualProducts(a, c);
      }
      products = &own;
    }
    const bool pooled_current =
        pooled_products != nullptr &&
        pooled_products->total_rounds == pooled_.TotalRounds() &&
        pooled_products->context == round.context &&
        pooled_products->per_action.size() == 1 &&
        pooled_products->per_action[0].size() == pooled_.TotalRounds();
    if (!pooled_current) {
      PooledWidth(c, products, &own_pooled);
      pooled_products = &own_pooled;
    }
    GrowFactors(round, products->per_action[round.action],
                pooled_products->per_action[0]);
  }
  // Sherman-Morrison with k = C^-1 c before the round: C'^-1 c = k / den,
  // so G' = C'^-1 (E + w c p^T) = G + (w / den) k (p - G^T c)^T, and the
  // same for C^-1 b_c with l for p.
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
  if (factors_.on && !AllDual()) DropFactors();
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
  // The factors gain the rounds first (they read the context models' rows
  // as they are), unless the pooled model would pass its threshold: the
  // factors of that many rounds would soon go.
  if (factors_.on) {
    if (pooled_.TotalRounds() + static_cast<int64_t>(rounds.size()) >=
        pooled_.primal_threshold()) {
      DropFactors();
    } else {
      ExtendFactors(rounds);
    }
  }
  const ContextRounds split = SplitRounds(rounds);
  for (const Round& round : rounds) AddSums(round);
  contexts_.Replay(split.per_action);
  pooled_.Replay(split.pooled);
  if (factors_.on && !AllDual()) DropFactors();
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
  // The factors from the rounds themselves (empty factors read no rows),
  // when every context model is dual.
  if (model.AllDual()) {
    if (!rounds.empty()) model.ExtendFactors(rounds);
  } else {
    model.DropFactors();
  }
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
  return contexts_.MemoryBytes() + pooled_.MemoryBytes() + FactorBytes() +
         doubles * sizeof(double) + sizeof(*this) +
         actions_.size() * sizeof(ActionState);
}

size_t PoLinUcbModel::FactorBytes() const {
  size_t doubles = factors_.pooled.CapacityDoubles();
  size_t ints = 0;
  for (size_t a = 0; a < factors_.per_action.size(); ++a) {
    doubles +=
        factors_.per_action[a].CapacityDoubles() + factors_.scale[a].capacity();
    ints += factors_.row[a].capacity();
  }
  return doubles * sizeof(double) + ints * sizeof(int) +
         factors_.per_action.size() *
             (sizeof(GrowingLower) + sizeof(std::vector<int>) +
              sizeof(std::vector<double>));
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
  // Format 2: the pooled factors, if on: per action its rows' pooled
  // indices and 1 / sqrt(w), then L_X and every L_a row by row.
  out.Value(static_cast<int32_t>(factors_.on));
  if (factors_.on) {
    for (size_t a = 0; a < actions_.size(); ++a) {
      out.Value(static_cast<int32_t>(factors_.row[a].size()));
      for (int i : factors_.row[a]) out.Value(static_cast<int32_t>(i));
      out.Doubles(factors_.scale[a].data(), factors_.scale[a].size());
    }
    auto lower = [&out](const GrowingLower& l) {
      for (int i = 0; i < l.rows(); ++i) out.Doubles(l.Row(i), i + 1);
    };
    lower(factors_.pooled);
    for (const GrowingLower& l : factors_.per_action) lower(l);
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
  int32_t format = 0;
  RETURN_IF_ERROR(
      ReadStateHeader(in, kStateHeader, kOldestStateFormat, &format));
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
  // Format 1 has no factors: the model answers from the pooled model's rows
  // (which a state of that format has no order of rounds to rebuild them
  // from) until it would have dropped them.
  int32_t factors_on = 0;
  if (format >= 2) RETURN_IF_ERROR(in.Value(&factors_on, "the factors"));
  if (factors_on != 0) {
    int64_t total = 0;
    for (size_t a = 0; a < model.actions_.size(); ++a) {
      int32_t rows = 0;
      RETURN_IF_ERROR(in.Value(&rows, "the factors"));
      if (rows < 0 || static_cast<size_t>(rows) > in.left() / sizeof(int32_t)) {
        return absl::DataLossError("model state: truncated in the factors");
      }
      total += rows;
      std::vector<int>& row = model.factors_.row[a];
      row.resize(rows);
      for (int& i : row) {
        int32_t v = 0;
        RETURN_IF_ERROR(in.Value(&v, "the factors"));
        i = v;
      }
      std::vector<double>& scale = model.factors_.scale[a];
      if (static_cast<size_t>(rows) > in.left() / sizeof(double)) {
        return absl::DataLossError("model state: truncated in the factors");
      }
      scale.resize(rows);
      RETURN_IF_ERROR(in.Doubles(scale.data(), scale.size(), "the factors"));
    }
    // Every pooled row belongs to one action's row, in order within each.
    std::vector<char> seen(static_cast<size_t>(total), 0);
    for (const std::vector<int>& row : model.factors_.row) {
      for (size_t i = 0; i < row.size(); ++i) {
        if (row[i] < 0 || row[i] >= total || seen[row[i]] != 0 ||
            (i > 0 && row[i] <= row[i - 1])) {
          return absl::DataLossError("model state: the factors' rows disagree");
        }
        seen[row[i]] = 1;
      }
    }
    auto lower = [&in](GrowingLower& l, int64_t rows) -> absl::Status {
      for (int64_t i = 0; i < rows; ++i) {
        if (static_cast<size_t>(i + 1) > in.left() / sizeof(double)) {
          return absl::DataLossError("model state: truncated in a factor");
        }
        RETURN_IF_ERROR(in.Doubles(l.AppendRow(), i + 1, "a factor"));
      }
      return absl::OkStatus();
    };
    RETURN_IF_ERROR(lower(model.factors_.pooled, total));
    for (size_t a = 0; a < model.actions_.size(); ++a) {
      RETURN_IF_ERROR(
          lower(model.factors_.per_action[a],
                static_cast<int64_t>(model.factors_.row[a].size())));
    }
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
  if (factors_on == 0) {
    model.DropFactors();
  } else {
    // The factors must be of these context models, all dual.
    bool agree = model.AllDual() &&
                 model.factors_.pooled.rows() == model.pooled_.TotalRounds();
    for (int a = 0; agree && a < model.num_actions(); ++a) {
      agree = static_cast<int64_t>(model.factors_.row[a].size()) ==
              model.contexts_.Count(a);
    }
    if (!agree) {
      return absl::DataLossError(
          "model state: the pooled factors disagree with the context models");
    }
  }
  for (ActionState& s : model.actions_) model.Refresh(s);
  return model;
}

}  // namespace bitewise::bandit
