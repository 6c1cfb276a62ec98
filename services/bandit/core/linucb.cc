#include "services/bandit/core/linucb.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <utility>

#include "absl/strings/str_cat.h"
#include "services/bandit/core/model_state_io.h"
#include "services/bandit/core/split_run.h"
#include "services/common/status_macros.h"

namespace bitewise::bandit {
namespace {

using Eigen::MatrixXd;
using Eigen::VectorXd;

// A x for a symmetric A of which only the lower triangle is read, and a
// thin x (d x k): one pass over the triangle, column by column (Eigen's
// selfadjoint product takes twice as long for a few columns).
MatrixXd LowerSymmetricTimes(const MatrixXd& a, const MatrixXd& x) {
  const int d = static_cast<int>(a.rows());
  MatrixXd y = a.diagonal().asDiagonal() * x;
  for (int j = 0; j + 1 < d; ++j) {
    const int n = d - j - 1;
    const auto col = a.col(j).tail(n);
    y.bottomRows(n).noalias() += col * x.row(j);
    y.row(j).noalias() += col.transpose() * x.bottomRows(n);
  }
  return y;
}

constexpr char kStateMagic[4] = {'B', 'W', 'L', 'U'};
// 3: each fold slice's count of rows (format 2, one count, still loads).
// 4: four fold slices (format 3 had two; it still loads, a conversion under
// way in it starting again).
constexpr int32_t kStateFormat = 4;
constexpr int kFormat3FoldSlices = 2;
constexpr int32_t kOldestStateFormat = 2;
constexpr double kLayoutMarker = 1.0 + 1.0 / 1024;  // bytes tell the layout
constexpr StateHeader kStateHeader = {kStateMagic, kStateFormat, kLayoutMarker,
                                      "model"};

}  // namespace

double* RowBlocks::Append(int n) {
  if (blocks_.empty() || blocks_.back().capacity - blocks_.back().used < n) {
    Block block;
    block.capacity = std::max(n, std::max(8, rows_ / 8));
    block.data.reset(new double[static_cast<size_t>(block.capacity) * cols_]);
    block.first = rows_;
    blocks_.push_back(std::move(block));
  }
  Block& last = blocks_.back();
  double* out = last.data.get() + static_cast<size_t>(last.used) * cols_;
  last.used += n;
  rows_ += n;
  return out;
}

const double* RowBlocks::Row(int i) const {
  auto it = std::upper_bound(
      blocks_.begin(), blocks_.end(), i,
      [](int row, const Block& block) { return row < block.first; });
  const Block& block = *std::prev(it);
  return block.data.get() + static_cast<size_t>(i - block.first) * cols_;
}

size_t RowBlocks::CapacityDoubles() const {
  size_t n = 0;
  for (const Block& block : blocks_) {
    n += static_cast<size_t>(block.capacity) * cols_;
  }
  return n;
}

void RowBlocks::ReleaseBlocks(int n) {
  for (; n > 0 && !blocks_.empty(); --n) {
    rows_ -= blocks_.back().used;
    blocks_.pop_back();
  }
}

void RowBlocks::Clear() {
  std::vector<Block>().swap(blocks_);
  rows_ = 0;
}

size_t SelectProducts::Bytes() const {
  size_t doubles = context.size();
  for (const VectorXd& v : per_action) doubles += v.size();
  return doubles * sizeof(double) + (nested != nullptr ? nested->Bytes() : 0);
}

VectorXd LinUcbModel::SolveA(int action, const VectorXd& x,
                             const SelectProducts* products) const {
  const ActionState& s = actions_[action];
  const bool reuse =
      products != nullptr && products->total_rounds == total_rounds_ &&
      products->per_action.size() == actions_.size() &&
      products->context.size() == static_cast<size_t>(x.size()) &&
      std::equal(products->context.begin(), products->context.end(),
                 x.data()) &&
      products->per_action[action].size() == (s.primal ? d_ : s.w.rows());
  if (!reuse) return ApplyAInverse(s, x);
  // The Select's product is A^-1 x (primal) or W x (dual).
  const VectorXd& v = products->per_action[action];
  if (s.primal) return v;
  if (s.w.rows() == 0) return x / lambda_a_;
  return (x - WTranspose(s, v)) / lambda_a_;
}

LinUcbModel::LinUcbModel(const BanditConfig& config, int primal_threshold)
    : config_(config),
      d_(config.context_dim),
      q_(config.learner == Learner::kPostHoc ? config.posthoc_dim : 0),
      primal_threshold_(primal_threshold > 0
                            ? primal_threshold
                            : std::max(1, config.context_dim * 3 / 4)),
      lambda_a_(config.lambda_c + config.prior.kappa_c()) {
  actions_.resize(config.num_actions());
  const PopulationPrior& prior = config_.prior;
  for (size_t a = 0; a < actions_.size(); ++a) {
    ActionState& s = actions_[a];
    s.w = RowBlocks(d_);
    s.b = VectorXd::Zero(d_);
    if (prior.enabled()) s.b = prior.kappa_c() * AsVector(prior.theta0[a]);
    s.wb.resize(0);
    if (posthoc()) {
      s.M = (config_.lambda_p + prior.kappa_p()) * MatrixXd::Identity(q_, q_);
      s.r = VectorXd::Zero(q_);
      if (prior.enabled()) s.r = prior.kappa_p() * AsVector(prior.phi0[a]);
      s.y.resize(0, q_);
      s.z.resize(0, q_);
    }
  }
  // Always computed, so that moving the model never copies an LLT's
  // uninitialised status (undefined behaviour that UBSan reports).
  s_pp_llt_.compute(MatrixXd::Identity(std::max(q_, 1), std::max(q_, 1)));
  if (posthoc()) {
    s_pp_ = config_.lambda_p * MatrixXd::Identity(q_, q_);
    s_pp_llt_.compute(s_pp_);
    s_pc_ = MatrixXd::Zero(q_, d_);
    h_ = MatrixXd::Zero(q_, d_);
    hht_ = MatrixXd::Zero(q_, q_);
  }
}

absl::StatusOr<LinUcbModel> LinUcbModel::Create(const BanditConfig& config,
                                                int primal_threshold) {
  absl::Status status = ValidateConfig(config);
  if (!status.ok()) return status;
  if (primal_threshold < 0) {
    return absl::InvalidArgumentError("primal_threshold: must be >= 0");
  }
  LinUcbModel model(config, primal_threshold);
  if (model.posthoc()) {
    for (ActionState& s : model.actions_) model.RefreshPostHocCache(s);
  }
  return model;
}

absl::Status LinUcbModel::ValidateContext(
    absl::Span<const double> context) const {
  return ValidateVector("context", context, static_cast<size_t>(d_),
                        kMaxInputMagnitude);
}

absl::Status LinUcbModel::ValidateOutcome(
    double loss, absl::Span<const double> posthoc) const {
  if (!std::isfinite(loss) || loss < 0.0 || loss > 1.0) {
    return absl::InvalidArgumentError(
        absl::StrCat("loss: must be in [0, 1], got ", loss));
  }
  if (!this->posthoc() && posthoc.empty()) return absl::OkStatus();
  return ValidateVector("posthoc", posthoc,
                        static_cast<size_t>(config_.posthoc_dim),
                        kMaxInputMagnitude);
}

absl::Status LinUcbModel::ValidateRound(const Round& round) const {
  if (round.action < 0 || round.action >= num_actions()) {
    return absl::InvalidArgumentError(absl::StrCat(
        "action: must be in [0, ", num_actions(), "), got ", round.action));
  }
  if (!std::isfinite(round.weight) || round.weight <= 0.0) {
    return absl::InvalidArgumentError(
        absl::StrCat("weight: must be finite and > 0, got ", round.weight));
  }
  RETURN_IF_ERROR(ValidateContext(round.context));
  return ValidateOutcome(round.loss, round.posthoc);
}

int LinUcbModel::ConversionStart() const {
  // ceil(T * 2/3): n = d/2 at the default T = 3d/4.
  return static_cast<int>(
      (static_cast<int64_t>(primal_threshold_) * kConversionStartNumerator +
       kConversionStartDenominator - 1) /
      kConversionStartDenominator);
}

VectorXd LinUcbModel::Product(const ActionState& s,
                              const Eigen::Ref<const VectorXd>& x) const {
  if (s.primal) return s.a_inv.selfadjointView<Eigen::Lower>() * x;
  VectorXd v(s.w.rows());
  s.w.ForEachBlock([&](int first, int rows, const double* data) {
    v.segment(first, rows).noalias() = ConstRowMap(data, rows, d_) * x;
  });
  return v;
}

MatrixXd LinUcbModel::DualProducts(int action,
                                   const Eigen::Ref<const MatrixXd>& x) const {
  const ActionState& s = actions_[action];
  MatrixXd v(s.w.rows(), x.cols());
  s.w.ForEachBlock([&](int first, int rows, const double* data) {
    v.middleRows(first, rows).noalias() = ConstRowMap(data, rows, d_) * x;
  });
  return v;
}

VectorXd LinUcbModel::WTranspose(const ActionState& s,
                                 const VectorXd& v) const {
  VectorXd out = VectorXd::Zero(d_);
  s.w.ForEachBlock([&](int first, int rows, const double* data) {
    out.noalias() +=
        ConstRowMap(data, rows, d_).transpose() * v.segment(first, rows);
  });
  return out;
}

VectorXd LinUcbModel::ApplyAInverse(const ActionState& s,
                                    const VectorXd& x) const {
  if (s.primal) return s.a_inv.selfadjointView<Eigen::Lower>() * x;
  if (s.w.rows() == 0) return x / lambda_a_;
  return (x - WTranspose(s, Product(s, x))) / lambda_a_;
}

int LinUcbModel::PrepareSteps() const {
  // 64 columns of d doubles a step at d = 2048 is 32 steps of about 1 MB.
  return std::clamp(d_ / 64, 1, kPrepareUpdates);
}

namespace {

// The first j with columns [0, j) of a d x d lower triangle holding at least
// `parts` / `of` of its entries (j d - j (j - 1) / 2 of d (d + 1) / 2).
int LowerColumnsHolding(int d, int parts, int of) {
  if (parts <= 0) return 0;
  if (parts >= of) return d;
  const double n = d;
  const double target = n * (n + 1) / 2 * parts / of;
  const double b = 2 * n + 1;
  const double j = (b - std::sqrt(std::max(0.0, b * b - 8 * target))) / 2;
  return std::clamp(static_cast<int>(std::ceil(j)), 0, d);
}

}  // namespace

int LinUcbModel::PreparedEnd(int step) const {
  // Step k ends where the columns hold (k + 1) / steps of the whole.
  return LowerColumnsHolding(d_, step + 1, PrepareSteps());
}

int LinUcbModel::SliceBegin(int slice) const {
  return LowerColumnsHolding(d_, slice, kFoldSlices);
}

void LinUcbModel::PrepareColumns(ActionState& s, int from, int to) {
  if (from >= to) return;
  // Allocated, not written: its pages are touched slice by slice.
  if (s.candidate.rows() != d_) s.candidate.resize(d_, d_);
  for (int j = from; j < to; ++j) {
    s.candidate.col(j).tail(d_ - j).setZero();
    s.candidate(j, j) = 1.0 / lambda_a_;
  }
}

LinUcbModel::ConversionWork LinUcbModel::PlanConversion(
    std::vector<ActionState>& actions) const {
  ConversionWork work;
  int next = -1;
  for (size_t i = 0; i < actions.size(); ++i) {
    const ActionState& s = actions[i];
    if (!s.primal && (s.prepared > 0 || s.converting))
      next = static_cast<int>(i);
  }
  if (next < 0) {
    // None converting: the one furthest past the start goes next.
    for (size_t i = 0; i < actions.size(); ++i) {
      const ActionState& s = actions[i];
      if (!s.primal && s.count > 0 && s.count >= ConversionStart() &&
          (next < 0 || s.count > actions[next].count)) {
        next = static_cast<int>(i);
      }
    }
    if (next < 0) return work;
  }
  ActionState& s = actions[next];
  work.action = next;
  auto turn_primal = [&s] {
    s.primal = true;
    s.converting = false;
    s.prepared = 0;
    s.folded = {};
    s.next_slice = 0;
    s.chase = 0;
  };
  if (!s.converting && s.prepared == d_) {
    // Prepared: the folding begins.
    s.converting = true;
    s.folded = {};
    s.next_slice = 0;
    s.chase = 0;
  }
  if (s.converting) {
    const int count = static_cast<int>(s.count);
    bool close = true;
    for (int f : s.folded)
      close = close && count - f <= kConversionRowsPerUpdate;
    if (close && s.chase >= kMaxChaseUpdates) {
      // Every Update brings this action a row: the last few go into the
      // whole matrix at once.
      work.kind = ConversionWork::kSwitch;
      work.from = s.folded;
      turn_primal();
      return work;
    }
    if (close) ++s.chase;
    work.kind = ConversionWork::kFold;
    work.slice = s.next_slice;
    s.next_slice = (s.next_slice + 1) % kFoldSlices;
    work.first = s.folded[work.slice];
    work.count = std::min(kConversionRowsPerUpdate, count - work.first);
    s.folded[work.slice] += work.count;
    bool current = true;
    for (int f : s.folded) current = current && f == count;
    if (current) {
      // Every slice holds every row: primal at the end of this Update.
      work.then_switch = true;
      turn_primal();
    }
    return work;
  }
  if (s.prepared < d_) {
    int step = 0;
    while (PreparedEnd(step) <= s.prepared) ++step;
    work.kind = ConversionWork::kPrepare;
    work.prepare_from = s.prepared;
    work.prepare_to = PreparedEnd(step);
    s.prepared = work.prepare_to;
    return work;
  }
  return work;  // not reached: a prepared action is converting above
}

void LinUcbModel::FoldRows(ActionState& s, int first, int count, int col_begin,
                           int col_end) {
  if (count <= 0 || col_begin >= col_end) return;
  RowMatrix rows(count, d_);
  for (int i = 0; i < count; ++i) {
    rows.row(i) = Eigen::Map<const Eigen::RowVectorXd>(s.w.Row(first + i), d_);
  }
  const double scale = -1.0 / lambda_a_;
  const int width = col_end - col_begin;
  // The slice's block on the diagonal, then the rectangle below it.
  s.candidate.block(col_begin, col_begin, width, width)
      .selfadjointView<Eigen::Lower>()
      .rankUpdate(rows.middleCols(col_begin, width).transpose(), scale);
  const int below = d_ - col_end;
  if (below > 0) {
    s.candidate.block(col_end, col_begin, below, width).noalias() +=
        scale * rows.rightCols(below).transpose() *
        rows.middleCols(col_begin, width);
  }
}

void LinUcbModel::TakePrimal(ActionState& s) {
  s.a_inv = std::move(s.candidate);
  s.candidate = MatrixXd();
  s.primal = true;
  s.converting = false;
  s.prepared = 0;
  s.retired = std::move(s.w);
  s.w = RowBlocks(d_);
  s.wb.resize(0);
  s.y.resize(0, q_);
  s.z.resize(0, q_);
}

void LinUcbModel::SwitchToPrimal(ActionState& s) {
  TakePrimal(s);
  RefreshPrimalSums(s);
}

void LinUcbModel::RecomputeH() {
  s_pp_llt_.compute(s_pp_);
  h_ = s_pp_llt_.solve(s_pc_);
  hht_.noalias() = h_ * h_.transpose();
}

void LinUcbModel::RefreshPostHocCache(ActionState& s) {
  const double lambda = lambda_a_;
  MatrixXd q_mat(q_, q_);  // H A^-1 H^T
  VectorXd hab(q_);        // H A^-1 b
  if (s.primal) {
    // H A^-1 H^T = S_pp^-1 (S_pc A^-1 S_pc^T) S_pp^-1, H A^-1 b likewise.
    const MatrixXd left = s_pp_llt_.solve(s.spq);
    q_mat = s_pp_llt_.solve(left.transpose());
    hab = s_pp_llt_.solve(s.spb);
  } else {
    const int m = s.w.rows();
    // Z = W H^T = Y S_pp^-1. No Eigen solve on an empty matrix (an action
    // without rounds): that binds a reference to a null pointer inside
    // Eigen, undefined behaviour that only works by luck.
    if (m > 0) {
      s.z = s_pp_llt_.solve(s.y.transpose()).transpose();
    } else {
      s.z.resize(0, q_);
    }
    q_mat = hht_ / lambda;
    hab = (h_ * s.b) / lambda;
    if (m > 0) {
      q_mat.noalias() -= (s.z.transpose() * s.z) / lambda;
      hab.noalias() -= (s.z.transpose() * s.wb) / lambda;
    }
  }
  s.r_factor = s.M.llt().matrixU();
  MatrixXd cap = MatrixXd::Identity(q_, q_);
  cap.noalias() += s.r_factor * q_mat * s.r_factor.transpose();
  s.cap.compute(cap);
  const VectorXd hay = hab + q_mat * s.r;  // H A^-1 y
  s.h = s.cap.solve(s.r_factor * hay);
}

std::vector<ActionEstimate> LinUcbModel::Estimate(
    absl::Span<const double> context, SelectProducts* products) const {
  return EstimateAlongside(context, products, nullptr, 0.0);
}

double LinUcbModel::SelectCost(int action) const {
  const ActionState& s = actions_[action];
  if (s.primal) return 0.5 * d_ * (d_ + 1.0);
  return static_cast<double>(s.w.rows()) * d_;
}

std::vector<ActionEstimate> LinUcbModel::EstimateAlongside(
    absl::Span<const double> context, SelectProducts* products,
    const std::function<void()>& also, double also_cost) const {
  const Eigen::Map<const VectorXd> c = AsVector(context);
  const double lambda = lambda_a_;
  const double cc = c.squaredNorm();
  VectorXd hc;
  if (posthoc()) hc.noalias() = h_ * c;
  if (products != nullptr) {
    products->total_rounds = total_rounds_;
    products->context.assign(context.begin(), context.end());
    products->per_action.resize(actions_.size());
  }
  std::vector<ActionEstimate> out(actions_.size());
  // Each action's pass writes only its own entries, so the passes may run
  // on two threads (split_run.h); `also` is one more task beside them.
  auto one = [&](size_t a) {
    const ActionState& s = actions_[a];
    VectorXd v = Product(s, c);
    double s1 = 0.0;  // c^T A^-1 c
    double s3 = 0.0;  // b^T A^-1 c
    VectorXd s2;      // H A^-1 c
    if (s.primal) {
      s1 = c.dot(v);
      s3 = s.b.dot(v);
      if (posthoc()) s2.noalias() = h_ * v;
    } else {
      const bool any = s.w.rows() > 0;
      s1 = (cc - (any ? v.squaredNorm() : 0.0)) / lambda;
      s3 = (s.b.dot(c) - (any ? s.wb.dot(v) : 0.0)) / lambda;
      if (posthoc()) {
        s2 = hc;
        if (any) s2.noalias() -= s.z.transpose() * v;
        s2 /= lambda;
      }
    }
    double pred = s3;
    double var = s1;
    if (posthoc()) {
      const VectorXd g = s.r_factor * s2;
      pred = s3 + s.r.dot(s2) - s.h.dot(g);
      var = 2.0 * (s1 - g.dot(s.cap.solve(g)));
    }
    ActionEstimate& e = out[a];
    e.predicted_loss = pred;
    e.width = std::sqrt(std::max(var, 0.0));
    e.lcb = pred - config_.alpha * e.width;
    if (products != nullptr) products->per_action[a] = std::move(v);
  };
  const int k = static_cast<int>(actions_.size());
  std::vector<double> costs(k + (also ? 1 : 0));
  for (int a = 0; a < k; ++a) costs[a] = SelectCost(a);
  if (also) costs[k] = also_cost;
  SplitRun(costs, [&](int i) {
    if (i < k) {
      one(static_cast<size_t>(i));
    } else {
      also();
    }
  });
  return out;
}

void LinUcbModel::Update(const Round& round, const SelectProducts* products) {
  Apply(round, products, /*caches=*/true);
}

void LinUcbModel::Replay(const std::vector<Round>& rounds) {
  if (rounds.size() > 1 && CanReplayInBatch(rounds)) {
    ReplayBatch(rounds);
  } else {
    for (const Round& round : rounds) Apply(round, nullptr, /*caches=*/false);
  }
  // The caches Apply left behind, once.
  if (posthoc()) RecomputeH();
  for (ActionState& s : actions_) {
    if (s.primal) {
      RefreshPrimalSums(s);
    } else {
      RefreshDualSums(s);
    }
    if (posthoc()) RefreshPostHocCache(s);
  }
}

bool LinUcbModel::CanReplayInBatch(const std::vector<Round>& rounds) const {
  std::vector<int64_t> added(actions_.size(), 0);
  for (const Round& round : rounds) ++added[round.action];
  for (size_t a = 0; a < actions_.size(); ++a) {
    const ActionState& s = actions_[a];
    if (s.primal) continue;
    // No conversion under way, and none would begin within the rounds.
    if (s.converting || s.prepared > 0 ||
        s.count + added[a] >= ConversionStart()) {
      return false;
    }
  }
  return true;
}

void LinUcbModel::ReplayBatch(const std::vector<Round>& rounds) {
  // Each action's rows x = sqrt(w) c at once. The same sums as one Apply
  // per round (equal to rounding), in matrix products that read each
  // action's form a few times instead of twice per round. Nothing converts
  // meanwhile (CanReplayInBatch), so only the per-round sums below depend
  // on the order.
  std::vector<std::vector<const Round*>> by_action(actions_.size());
  for (const Round& round : rounds) by_action[round.action].push_back(&round);
  for (size_t a = 0; a < actions_.size(); ++a) {
    const std::vector<const Round*>& taken = by_action[a];
    if (taken.empty()) continue;
    ActionState& s = actions_[a];
    const int k = static_cast<int>(taken.size());
    MatrixXd x(k, d_);
    for (int j = 0; j < k; ++j) {
      x.row(j) =
          std::sqrt(taken[j]->weight) * AsVector(taken[j]->context).transpose();
    }
    if (s.primal) {
      // Woodbury: (A + X^T X)^-1 = A^-1 - U (I + X U)^-1 U^T, U = A^-1 X^T,
      // i.e. A^-1 - V V^T with V = U L^-T and L L^T = I + X U.
      const MatrixXd u =
          s.a_inv.selfadjointView<Eigen::Lower>() * x.transpose();
      MatrixXd inner = MatrixXd::Identity(k, k);
      inner.noalias() += x * u;
      const Eigen::LLT<MatrixXd> factor(inner);
      const MatrixXd v = factor.matrixL().solve(u.transpose()).transpose();
      s.a_inv.selfadjointView<Eigen::Lower>().rankUpdate(v, -1.0);
      continue;
    }
    // Dual: K = lambda I + X X^T = L L^T and W = L^-1 X gain k rows at
    // once. With B = X_new W^T, the new block row of L is [B C] with
    // C C^T = lambda I + X_new X_new^T - B B^T, and the new rows of W are
    // C^-1 (X_new - B W) (one Apply's l = W x and delta, k rows at a time).
    const int n = s.w.rows();
    MatrixXd b(k, n);
    s.w.ForEachBlock([&](int first, int rows, const double* data) {
      b.middleCols(first, rows).noalias() =
          x * ConstRowMap(data, rows, d_).transpose();
    });
    MatrixXd gram = lambda_a_ * MatrixXd::Identity(k, k);
    gram.noalias() += x * x.transpose();
    gram.noalias() -= b * b.transpose();
    const Eigen::LLT<MatrixXd> factor(gram);
    MatrixXd rows_new = x;
    s.w.ForEachBlock([&](int first, int rows, const double* data) {
      rows_new.noalias() -=
          b.middleCols(first, rows) * ConstRowMap(data, rows, d_);
    });
    factor.matrixL().solveInPlace(rows_new);
    double* out = s.w.Append(k);
    for (int j = 0; j < k; ++j) {
      Eigen::Map<Eigen::RowVectorXd>(out + static_cast<size_t>(j) * d_, d_) =
          rows_new.row(j);
    }
  }
  // The per-round sums, in order, as Apply adds them.
  for (const Round& round : rounds) {
    const Eigen::Map<const VectorXd> c = AsVector(round.context);
    const double w = round.weight;
    ActionState& taken = actions_[round.action];
    ++taken.count;
    ++total_rounds_;
    AddScale(round);
    taken.loss_sum += round.loss;
    taken.b.noalias() += (w * round.loss) * c;
    if (posthoc()) {
      const Eigen::Map<const VectorXd> p = AsVector(round.posthoc);
      const VectorXd wp = w * p;
      taken.M.noalias() += wp * p.transpose();
      taken.r.noalias() += round.loss * wp;
      s_pc_.noalias() += wp * c.transpose();
      s_pp_.noalias() += wp * p.transpose();
    }
  }
  // What Apply releases per round (blocks of rows retired by conversions).
  for (ActionState& s : actions_) {
    s.retired.ReleaseBlocks(2 * static_cast<int>(rounds.size()));
  }
}

void LinUcbModel::RefreshDualSums(ActionState& s) {
  s.wb = Product(s, s.b);
  if (!posthoc()) return;
  s.y.resize(s.w.rows(), q_);
  s.w.ForEachBlock([&](int first, int rows, const double* data) {
    s.y.middleRows(first, rows).noalias() =
        ConstRowMap(data, rows, d_) * s_pc_.transpose();
  });
}

void LinUcbModel::RefreshPrimalSums(ActionState& s) {
  if (!posthoc()) return;
  const MatrixXd p = LowerSymmetricTimes(s.a_inv, s_pc_.transpose());
  s.spq.noalias() = s_pc_ * p;
  s.spq = (0.5 * (s.spq + s.spq.transpose())).eval();
  s.spb.noalias() = p.transpose() * s.b;
}

void LinUcbModel::PrimalSumsFromDual(ActionState& s) {
  if (!posthoc()) return;
  // A^-1 = (I - W^T W) / lambda, Y = W S_pc^T, W b: O(n q^2 + q d).
  s.spq.noalias() = s_pc_ * s_pc_.transpose();
  s.spq.noalias() -= s.y.transpose() * s.y;
  s.spq /= lambda_a_;
  s.spb.noalias() = s_pc_ * s.b;
  s.spb.noalias() -= s.y.transpose() * s.wb;
  s.spb /= lambda_a_;
}

void LinUcbModel::Apply(const Round& round, const SelectProducts* products,
                        bool caches) {
  const Eigen::Map<const VectorXd> c = AsVector(round.context);
  const double w = round.weight;
  const double sw = std::sqrt(w);
  const int a = round.action;
  ActionState& taken = actions_[a];
  // Every action's product with c before this round: the Select's if they
  // are for this model state and context, otherwise computed here.
  bool reuse = products != nullptr && products->total_rounds == total_rounds_ &&
               products->per_action.size() == actions_.size() &&
               products->context == round.context;
  for (size_t i = 0; reuse && i < actions_.size(); ++i) {
    const ActionState& s = actions_[i];
    reuse = products->per_action[i].size() == (s.primal ? d_ : s.w.rows());
  }
  std::vector<VectorXd> computed;
  if (!reuse) {
    computed.resize(actions_.size());
    for (size_t i = 0; i < actions_.size(); ++i) {
      if ((caches && posthoc()) || static_cast<int>(i) == a) {
        computed[i] = Product(actions_[i], c);
      }
    }
  }
  const std::vector<VectorXd>& prod = reuse ? products->per_action : computed;
  const VectorXd& v = prod[a];

  const VectorXd x = sw * c;
  VectorXd ainv_c;  // primal: the new A^-1 c
  VectorXd w_row;   // dual: the new row of W
  const int m = taken.primal ? 0 : taken.w.rows();
  if (taken.primal) {
    const VectorXd u = sw * v;  // A^-1 x
    const double scale = 1.0 / (1.0 + x.dot(u));
    VectorXd pu;
    if (caches && posthoc()) pu.noalias() = s_pc_ * u;
    const double bu = taken.b.dot(u);
    taken.a_inv.selfadjointView<Eigen::Lower>().rankUpdate(u, -scale);
    if (caches && posthoc()) {
      ainv_c = v - (scale * u.dot(c)) * u;
      // A^-1 loses scale u u^T, then b gains w l c.
      taken.spq.noalias() -= (scale * pu) * pu.transpose();
      taken.spb.noalias() -= (scale * bu) * pu;
      taken.spb.noalias() += (w * round.loss) * (s_pc_ * ainv_c);
    }
  } else {
    // New Cholesky row [l^T delta] with L l = C x, so l = W x; the new row
    // of W is (x - W^T l) / delta.
    const VectorXd l = sw * v;
    const double delta2 = lambda_a_ + x.squaredNorm() - l.squaredNorm();
    // K is lambda-regularised, so delta2 >= lambda exactly (a Schur
    // complement of lambda I + X X^T). In floating point it cancels to
    // noise when lambda / |x|^2 is below the rounding error, even below
    // zero; lambda is then the true value's floor, and keeps W finite.
    const double delta = std::sqrt(std::max(delta2, lambda_a_));
    w_row = (m > 0 ? VectorXd(x - WTranspose(taken, l)) : VectorXd(x)) / delta;
    if (caches && m > 0) taken.wb.noalias() += (w * round.loss) * v;
    std::copy(w_row.data(), w_row.data() + d_, taken.w.Append(1));
  }
  ++taken.count;
  ++total_rounds_;
  AddScale(round);
  taken.loss_sum += round.loss;
  taken.b.noalias() += (w * round.loss) * c;
  if (caches && !taken.primal) {
    taken.wb.conservativeResize(m + 1);
    taken.wb(m) = w_row.dot(taken.b);
  }

  if (posthoc()) {
    const Eigen::Map<const VectorXd> p = AsVector(round.posthoc);
    const VectorXd wp = w * p;
    taken.M.noalias() += wp * p.transpose();
    taken.r.noalias() += round.loss * wp;
    // S_pc gains w p c^T: with k = A^-1 c and m = S_pc k, every
    // S_pc A^-1 S_pc^T gains m (w p)^T + (w p) m^T + (c^T k) (w p)(w p)^T and
    // every S_pc A^-1 b gains (w p)(b^T k); every Y = W S_pc^T gains
    // (W c)(w p)^T on its existing rows.
    for (size_t i = 0; caches && i < actions_.size(); ++i) {
      ActionState& s = actions_[i];
      if (s.primal) {
        const VectorXd& k = static_cast<int>(i) == a ? ainv_c : prod[i];
        const VectorXd mk = s_pc_ * k;
        s.spq.noalias() += mk * wp.transpose();
        s.spq.noalias() += wp * mk.transpose();
        s.spq.noalias() += (c.dot(k) * wp) * wp.transpose();
        s.spb.noalias() += s.b.dot(k) * wp;
      } else {
        const int rows = static_cast<int>(i) == a ? m : s.w.rows();
        if (rows > 0) s.y.topRows(rows).noalias() += prod[i] * wp.transpose();
      }
    }
    s_pc_.noalias() += wp * c.transpose();
    s_pp_.noalias() += wp * p.transpose();
    if (caches) RecomputeH();
    if (caches && !taken.primal) {
      taken.y.conservativeResize(m + 1, q_);
      taken.y.row(m).noalias() = (s_pc_ * w_row).transpose();
    }
  }

  // This Update's share of the conversion (at most one action's). The
  // converting action's new row, if this Update brought one, is in W
  // already (it is dual until the switch).
  const ConversionWork work = PlanConversion(actions_);
  if (work.kind != ConversionWork::kNone) {
    ActionState& s = actions_[work.action];
    bool switch_now = false;
    switch (work.kind) {
      case ConversionWork::kPrepare:
        PrepareColumns(s, work.prepare_from, work.prepare_to);
        break;
      case ConversionWork::kFold:
        FoldRows(s, work.first, work.count, SliceBegin(work.slice),
                 SliceBegin(work.slice + 1));
        switch_now = work.then_switch;
        break;
      case ConversionWork::kSwitch:
        for (int i = 0; i < kFoldSlices; ++i) {
          FoldRows(s, work.from[i], static_cast<int>(s.count) - work.from[i],
                   SliceBegin(i), SliceBegin(i + 1));
        }
        switch_now = true;
        break;
      case ConversionWork::kNone:
        break;
    }
    if (switch_now) {
      // The primal caches from the dual ones, which hold every row
      // (Replay refreshes them at its end instead).
      if (caches) PrimalSumsFromDual(s);
      TakePrimal(s);
    }
  }
  for (ActionState& s : actions_) s.retired.ReleaseBlocks(2);
  if (caches && posthoc()) {
    for (ActionState& s : actions_) RefreshPostHocCache(s);
  }
}

absl::StatusOr<LinUcbModel> LinUcbModel::Rebuild(
    const BanditConfig& config, const std::vector<Round>& rounds,
    int primal_threshold) {
  absl::StatusOr<LinUcbModel> created = Create(config, primal_threshold);
  if (!created.ok()) return created.status();
  LinUcbModel model = std::move(created).value();
  for (size_t i = 0; i < rounds.size(); ++i) {
    absl::Status status = model.ValidateRound(rounds[i]);
    if (!status.ok()) {
      return absl::Status(status.code(),
                          absl::StrCat("round ", i, ": ", status.message()));
    }
  }
  // Each action's rows sqrt(w) c in one block, and every sum, then one
  // factorisation per action.
  const int d = model.d_;
  // The conversions as the Updates would have run them: bookkeeping only.
  std::vector<ActionState> plan(model.actions_.size());
  for (const Round& round : rounds) {
    ++plan[round.action].count;
    model.PlanConversion(plan);
  }
  std::vector<double*> next(model.actions_.size(), nullptr);
  for (size_t a = 0; a < plan.size(); ++a) {
    const int count = static_cast<int>(plan[a].count);
    if (count > 0) next[a] = model.actions_[a].w.Append(count);
  }
  for (const Round& round : rounds) {
    ActionState& s = model.actions_[round.action];
    const Eigen::Map<const VectorXd> c = AsVector(round.context);
    const double w = round.weight;
    Eigen::Map<VectorXd>(next[round.action], d) = std::sqrt(w) * c;
    next[round.action] += d;
    ++s.count;
    ++model.total_rounds_;
    model.AddScale(round);
    s.loss_sum += round.loss;
    s.b.noalias() += (w * round.loss) * c;
    if (model.posthoc()) {
      const Eigen::Map<const VectorXd> p = AsVector(round.posthoc);
      const VectorXd wp = w * p;
      s.M.noalias() += wp * p.transpose();
      s.r.noalias() += round.loss * wp;
      model.s_pc_.noalias() += wp * c.transpose();
      model.s_pp_.noalias() += wp * p.transpose();
    }
  }
  if (model.posthoc()) model.RecomputeH();
  const double lambda = model.lambda_a_;
  for (ActionState& s : model.actions_) {
    const int m = static_cast<int>(s.count);
    if (m == 0) {
      if (model.posthoc()) model.RefreshPostHocCache(s);
      continue;
    }
    double* data = s.w.MutableRow(0);
    Eigen::Map<RowMatrix> rows(data, m, d);
    const ActionState& progress = plan[&s - model.actions_.data()];
    if (progress.primal) {
      MatrixXd a = lambda * MatrixXd::Identity(d, d);
      a.selfadjointView<Eigen::Lower>().rankUpdate(rows.transpose());
      s.candidate = a.selfadjointView<Eigen::Lower>().llt().solve(
          MatrixXd::Identity(d, d));
      a = MatrixXd();
      s.w.Clear();
      model.SwitchToPrimal(s);
    } else {
      // W = L^-1 C with L L^T = lambda I + C C^T, in place.
      MatrixXd k = lambda * MatrixXd::Identity(m, m);
      k.selfadjointView<Eigen::Lower>().rankUpdate(rows);
      const Eigen::LLT<MatrixXd> llt(k);
      k = MatrixXd();
      llt.matrixL().solveInPlace(rows);
      s.wb = rows * s.b;
      if (model.posthoc()) s.y = rows * model.s_pc_.transpose();
      // Where the Updates would have left the conversion.
      model.PrepareColumns(s, 0, progress.prepared);
      s.prepared = progress.prepared;
      if (progress.converting) {
        s.converting = true;
        s.folded = progress.folded;
        s.next_slice = progress.next_slice;
        s.chase = progress.chase;
        // 64 rows at a time, so the rows copied for a fold stay small.
        constexpr int kRowsAtOnce = 64;
        for (int slice = 0; slice < kFoldSlices; ++slice) {
          const int end = s.folded[slice];
          for (int i = 0; i < end; i += kRowsAtOnce) {
            model.FoldRows(s, i, std::min(kRowsAtOnce, end - i),
                           model.SliceBegin(slice),
                           model.SliceBegin(slice + 1));
          }
        }
      }
    }
    if (model.posthoc()) model.RefreshPostHocCache(s);
  }
  return model;
}

void LinUcbModel::AddScale(const Round& round) {
  scale_.weight_sum += round.weight;
  scale_.context_sq_sum += round.weight * AsVector(round.context).squaredNorm();
  if (posthoc()) {
    scale_.posthoc_sq_sum +=
        round.weight * AsVector(round.posthoc).squaredNorm();
  }
}

VectorXd LinUcbModel::Theta(int action) const {
  const ActionState& s = actions_[action];
  if (!posthoc()) return ApplyAInverse(s, s.b);
  // theta = N^-1 y = A^-1 (b + H^T (r - R^T h)) by Woodbury.
  const VectorXd y =
      s.b + h_.transpose() * (s.r - s.r_factor.transpose() * s.h);
  return ApplyAInverse(s, y);
}

VectorXd LinUcbModel::Phi(int action) const {
  if (!posthoc()) return VectorXd();
  return h_ * Theta(action);
}

size_t LinUcbModel::MemoryBytes() const {
  size_t doubles = static_cast<size_t>(s_pc_.size() + h_.size() + s_pp_.size() +
                                       hht_.size());
  for (const ActionState& s : actions_) {
    doubles += s.w.CapacityDoubles() + s.retired.CapacityDoubles() +
               s.wb.size() + s.y.size() + s.z.size() + s.candidate.size() +
               s.a_inv.size() + s.spq.size() + s.spb.size() + s.b.size() +
               s.M.size() + s.r.size() + 2 * q_ * q_ + q_;
  }
  return doubles * sizeof(double) + sizeof(*this) +
         actions_.size() * sizeof(ActionState);
}

size_t LinUcbModel::StateBytesBound() const { return MemoryBytes() + 4096; }

void LinUcbModel::SaveState(std::string* state) const {
  StateWriter out(std::move(*state), StateBytesBound());
  WriteStateHeader(out, kStateHeader);
  out.Value(static_cast<int32_t>(d_));
  out.Value(static_cast<int32_t>(q_));
  out.Value(static_cast<int32_t>(actions_.size()));
  out.Value(static_cast<int32_t>(primal_threshold_));
  out.Value(lambda_a_);
  out.Value(total_rounds_);
  out.Value(scale_.weight_sum);
  out.Value(scale_.context_sq_sum);
  out.Value(scale_.posthoc_sq_sum);
  if (posthoc()) {
    out.Doubles(s_pp_.data(), s_pp_.size());
    out.Doubles(s_pc_.data(), s_pc_.size());
  }
  for (const ActionState& s : actions_) {
    out.Value(s.count);
    out.Value(s.loss_sum);
    out.Value(static_cast<int32_t>(s.primal));
    out.Value(static_cast<int32_t>(s.converting));
    out.Value(static_cast<int32_t>(s.prepared));
    out.Value(static_cast<int32_t>(s.next_slice));
    out.Value(static_cast<int32_t>(s.chase));
    for (int f : s.folded) out.Value(static_cast<int32_t>(f));
    out.Doubles(s.b.data(), d_);
    if (posthoc()) {
      out.Doubles(s.M.data(), s.M.size());
      out.Doubles(s.r.data(), q_);
    }
    // The lower triangle of a d x d matrix, columns [0, columns).
    auto lower = [&](const MatrixXd& m, int columns) {
      for (int j = 0; j < columns; ++j) out.Doubles(&m(j, j), d_ - j);
    };
    if (s.primal) {
      lower(s.a_inv, d_);
      if (posthoc()) {
        out.Doubles(s.spq.data(), s.spq.size());
        out.Doubles(s.spb.data(), s.spb.size());
      }
      continue;
    }
    out.Value(static_cast<int32_t>(s.w.rows()));
    s.w.ForEachBlock([&](int, int rows, const double* data) {
      out.Doubles(data, static_cast<size_t>(rows) * d_);
    });
    out.Doubles(s.wb.data(), s.wb.size());
    if (posthoc()) out.Doubles(s.y.data(), s.y.size());
    lower(s.candidate, s.prepared);
  }
  *state = out.Take();
}

absl::StatusOr<LinUcbModel> LinUcbModel::LoadState(const BanditConfig& config,
                                                   absl::string_view state,
                                                   int primal_threshold) {
  ASSIGN_OR_RETURN(LinUcbModel model, Create(config, primal_threshold));
  StateReader in(state);
  int32_t format = 0;
  RETURN_IF_ERROR(
      ReadStateHeader(in, kStateHeader, kOldestStateFormat, &format));
  int32_t d = 0, q = 0, k = 0, threshold = 0;
  double lambda = 0;
  RETURN_IF_ERROR(in.Value(&d, "the header"));
  RETURN_IF_ERROR(in.Value(&q, "the header"));
  RETURN_IF_ERROR(in.Value(&k, "the header"));
  RETURN_IF_ERROR(in.Value(&threshold, "the header"));
  RETURN_IF_ERROR(in.Value(&lambda, "the header"));
  if (d != model.d_ || q != model.q_ || k != model.num_actions() ||
      threshold != model.primal_threshold_ || lambda != model.lambda_a_) {
    return absl::FailedPreconditionError(
        absl::StrCat("model state: saved for d ", d, ", q ", q, ", ", k,
                     " actions, primal threshold ", threshold, ", lambda ",
                     lambda, "; this model has ", model.d_, ", ", model.q_,
                     ", ", model.num_actions(), ", ", model.primal_threshold_,
                     ", ", model.lambda_a_));
  }
  RETURN_IF_ERROR(in.Value(&model.total_rounds_, "the header"));
  RETURN_IF_ERROR(in.Value(&model.scale_.weight_sum, "the header"));
  RETURN_IF_ERROR(in.Value(&model.scale_.context_sq_sum, "the header"));
  RETURN_IF_ERROR(in.Value(&model.scale_.posthoc_sq_sum, "the header"));
  if (model.posthoc()) {
    RETURN_IF_ERROR(in.Doubles(model.s_pp_.data(), model.s_pp_.size(), "S_pp"));
    RETURN_IF_ERROR(in.Doubles(model.s_pc_.data(), model.s_pc_.size(), "S_pc"));
    model.RecomputeH();
  }
  const int dd = model.d_;
  int in_conversion = 0;
  for (ActionState& s : model.actions_) {
    int32_t primal = 0, converting = 0, prepared = 0, next_slice = 0, chase = 0;
    std::array<int32_t, kFoldSlices> folded{};
    RETURN_IF_ERROR(in.Value(&s.count, "an action"));
    RETURN_IF_ERROR(in.Value(&s.loss_sum, "an action"));
    RETURN_IF_ERROR(in.Value(&primal, "an action"));
    RETURN_IF_ERROR(in.Value(&converting, "an action"));
    RETURN_IF_ERROR(in.Value(&prepared, "an action"));
    bool counts_agree = s.count >= 0 && prepared >= 0 && prepared <= dd;
    if (format == 2) {
      // Rows folded then, and where the folding began; their candidate is
      // read below and dropped: the conversion starts again (the dual form,
      // which answers until the switch, is whole).
      int32_t rows = 0, converted = 0;
      RETURN_IF_ERROR(in.Value(&rows, "an action"));
      RETURN_IF_ERROR(in.Value(&converted, "an action"));
      counts_agree = counts_agree && rows >= 0 && converted >= 0 &&
                     converted <= rows && rows <= s.count;
    } else {
      // Format 3 saved two slices' counts; a conversion under way then is
      // dropped below, as for format 2.
      const int slices = format == 3 ? kFormat3FoldSlices : kFoldSlices;
      RETURN_IF_ERROR(in.Value(&next_slice, "an action"));
      RETURN_IF_ERROR(in.Value(&chase, "an action"));
      for (int i = 0; i < slices; ++i) {
        int32_t f = 0;
        RETURN_IF_ERROR(in.Value(&f, "an action"));
        counts_agree = counts_agree && f >= 0 && f <= s.count;
        if (i < kFoldSlices) folded[i] = f;
      }
      counts_agree =
          counts_agree && next_slice >= 0 && next_slice < slices && chase >= 0;
    }
    if (!counts_agree) {
      return absl::DataLossError("model state: an action's counts disagree");
    }
    // What the conversion schedule can leave: a primal action with nothing
    // of a conversion, folding only once its matrix is prepared, and one
    // action at most between the two forms.
    if ((primal != 0 && (converting != 0 || prepared != 0)) ||
        (converting != 0 && prepared != dd)) {
      return absl::DataLossError(
          "model state: an action's form and conversion disagree");
    }
    if (primal == 0 && (prepared > 0 || converting != 0) &&
        ++in_conversion > 1) {
      return absl::DataLossError(
          "model state: more than one action converting (a state of another "
          "conversion schedule)");
    }
    s.primal = primal != 0;
    s.converting = converting != 0;
    s.prepared = prepared;
    std::copy(folded.begin(), folded.end(), s.folded.begin());
    s.next_slice = next_slice;
    s.chase = chase;
    RETURN_IF_ERROR(in.Doubles(s.b.data(), dd, "b"));
    if (model.posthoc()) {
      RETURN_IF_ERROR(in.Doubles(s.M.data(), s.M.size(), "M"));
      RETURN_IF_ERROR(in.Doubles(s.r.data(), s.r.size(), "r"));
    }
    auto lower = [&](MatrixXd& m, int columns) -> absl::Status {
      if (columns == 0) return absl::OkStatus();
      m.resize(dd, dd);
      for (int j = 0; j < columns; ++j) {
        RETURN_IF_ERROR(in.Doubles(&m(j, j), dd - j, "a d x d factor"));
      }
      return absl::OkStatus();
    };
    if (s.primal) {
      RETURN_IF_ERROR(lower(s.a_inv, dd));
      if (model.posthoc()) {
        s.spq.resize(model.q_, model.q_);
        s.spb.resize(model.q_);
        RETURN_IF_ERROR(
            in.Doubles(s.spq.data(), s.spq.size(), "S_pc A^-1 S_pc^T"));
        RETURN_IF_ERROR(in.Doubles(s.spb.data(), s.spb.size(), "S_pc A^-1 b"));
      }
    } else {
      int32_t n = 0;
      RETURN_IF_ERROR(in.Value(&n, "an action"));
      if (n != s.count) {
        return absl::DataLossError(absl::StrCat("model state: an action has ",
                                                s.count, " rounds and ", n,
                                                " rows"));
      }
      if (in.left() / sizeof(double) / dd < static_cast<size_t>(n)) {
        return absl::DataLossError("model state: truncated in W");
      }
      if (n > 0) {
        RETURN_IF_ERROR(
            in.Doubles(s.w.Append(n), static_cast<size_t>(n) * dd, "W"));
      }
      s.wb.resize(n);
      RETURN_IF_ERROR(in.Doubles(s.wb.data(), n, "W b"));
      if (model.posthoc()) {
        s.y.resize(n, model.q_);
        RETURN_IF_ERROR(in.Doubles(s.y.data(), s.y.size(), "W S_pc^T"));
      }
      RETURN_IF_ERROR(lower(s.candidate, s.prepared));
      if (format < 4 && s.converting) {
        s.candidate = MatrixXd();
        s.converting = false;
        s.prepared = 0;
        s.folded = {};
        s.next_slice = 0;
        s.chase = 0;
      }
    }
    if (model.posthoc()) model.RefreshPostHocCache(s);
  }
  if (in.left() != 0) {
    return absl::DataLossError(
        absl::StrCat("model state: ", in.left(), " bytes past its end"));
  }
  return model;
}

}  // namespace bitewise::bandit
