#include "services/bandit/core/linucb.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include "absl/strings/str_cat.h"

namespace bitewise::bandit {
namespace {

using Eigen::MatrixXd;
using Eigen::VectorXd;

Eigen::Map<const VectorXd> AsVector(absl::Span<const double> v) {
  return Eigen::Map<const VectorXd>(v.data(),
                                    static_cast<Eigen::Index>(v.size()));
}

absl::Status ValidateVector(const char* field, absl::Span<const double> v,
                            size_t expected) {
  if (v.size() != expected) {
    return absl::InvalidArgumentError(absl::StrCat(
        field, ": expected ", expected, " values, got ", v.size()));
  }
  for (size_t i = 0; i < v.size(); ++i) {
    if (!std::isfinite(v[i])) {
      return absl::InvalidArgumentError(
          absl::StrCat(field, "[", i, "]: must be finite, got ", v[i]));
    }
    if (std::abs(v[i]) > kMaxInputMagnitude) {
      return absl::InvalidArgumentError(
          absl::StrCat(field, "[", i, "]: magnitude must be at most ",
                       kMaxInputMagnitude, ", got ", v[i]));
    }
  }
  return absl::OkStatus();
}

}  // namespace

LinUcbModel::LinUcbModel(const BanditConfig& config, int primal_threshold)
    : config_(config),
      d_(config.context_dim),
      q_(config.learner == Learner::kPostHoc ? config.posthoc_dim : 0),
      primal_threshold_(primal_threshold > 0 ? primal_threshold
                                             : config.context_dim),
      lambda_a_(config.lambda_c + config.prior.kappa_c()) {
  actions_.resize(config.num_actions());
  const PopulationPrior& prior = config_.prior;
  for (size_t a = 0; a < actions_.size(); ++a) {
    ActionState& s = actions_[a];
    s.b = VectorXd::Zero(d_);
    if (prior.enabled()) s.b = prior.kappa_c() * AsVector(prior.theta0[a]);
    s.zb.resize(0);
    if (posthoc()) {
      s.M = (config_.lambda_p + prior.kappa_p()) * MatrixXd::Identity(q_, q_);
      s.r = VectorXd::Zero(q_);
      if (prior.enabled()) s.r = prior.kappa_p() * AsVector(prior.phi0[a]);
      s.e.resize(0, q_);
      s.z.resize(0, q_);
    }
  }
  if (posthoc()) {
    s_pp_ = config_.lambda_p * MatrixXd::Identity(q_, q_);
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
  for (ActionState& s : model.actions_) {
    model.RefreshLossCache(s);
    if (model.posthoc()) model.RefreshPostHocCache(s);
  }
  return model;
}

absl::Status LinUcbModel::ValidateContext(
    absl::Span<const double> context) const {
  return ValidateVector("context", context, static_cast<size_t>(d_));
}

absl::Status LinUcbModel::ValidateOutcome(
    double loss, absl::Span<const double> posthoc) const {
  if (!std::isfinite(loss) || loss < 0.0 || loss > 1.0) {
    return absl::InvalidArgumentError(
        absl::StrCat("loss: must be in [0, 1], got ", loss));
  }
  if (!this->posthoc() && posthoc.empty()) return absl::OkStatus();
  return ValidateVector("posthoc", posthoc,
                        static_cast<size_t>(config_.posthoc_dim));
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
  absl::Status status = ValidateContext(round.context);
  if (!status.ok()) return status;
  return ValidateOutcome(round.loss, round.posthoc);
}

LinUcbModel::ConstRowMap LinUcbModel::Rows(const ActionState& s) const {
  return ConstRowMap(s.rows.data(), n(s), d_);
}

VectorXd LinUcbModel::ApplyAInverse(const ActionState& s,
                                    const VectorXd& x) const {
  if (s.primal) return s.a_inv * x;
  const int m = n(s);
  if (m == 0) return x / lambda_a_;
  const ConstRowMap c = Rows(s);
  const auto l = s.chol.topLeftCorner(m, m).triangularView<Eigen::Lower>();
  VectorXd t = c * x;
  l.solveInPlace(t);
  l.transpose().solveInPlace(t);
  return (x - c.transpose() * t) / lambda_a_;
}

void LinUcbModel::AppendDualRow(ActionState& s, const VectorXd& x) {
  const int m = n(s);
  // Extend the Cholesky factor of K by one row: [L 0; l^T delta] with
  // L l = C x and delta^2 = lambda + x^T x - l^T l.
  VectorXd l_row(m);
  if (m > 0) {
    l_row.noalias() = Rows(s) * x;
    s.chol.topLeftCorner(m, m).triangularView<Eigen::Lower>().solveInPlace(
        l_row);
  }
  const double delta2 = lambda_a_ + x.squaredNorm() - l_row.squaredNorm();
  if (s.chol.rows() < m + 1) {
    const int cap = std::max(8, 2 * (m + 1));
    MatrixXd grown = MatrixXd::Zero(cap, cap);
    grown.topLeftCorner(m, m) = s.chol.topLeftCorner(m, m);
    s.chol = std::move(grown);
    if (posthoc()) {
      MatrixXd grown_e = MatrixXd::Zero(cap, q_);
      grown_e.topRows(m) = s.e.topRows(m);
      s.e = std::move(grown_e);
    }
  }
  s.chol.block(m, 0, 1, m) = l_row.transpose();
  // K is lambda-regularised, so delta2 >= lambda > 0 up to rounding.
  s.chol(m, m) = std::sqrt(std::max(delta2, lambda_a_ * 1e-300));
  if (posthoc()) s.e.row(m) = (s_pc_ * x).transpose();
  s.rows.insert(s.rows.end(), x.data(), x.data() + d_);
}

void LinUcbModel::SwitchToPrimal(ActionState& s) {
  const int m = n(s);
  MatrixXd a = lambda_a_ * MatrixXd::Identity(d_, d_);
  if (m > 0) {
    a.selfadjointView<Eigen::Lower>().rankUpdate(Rows(s).transpose());
  }
  s.a_inv =
      a.selfadjointView<Eigen::Lower>().llt().solve(MatrixXd::Identity(d_, d_));
  s.primal = true;
  std::vector<double>().swap(s.rows);
  s.chol.resize(0, 0);
  s.e.resize(0, q_);
  s.z.resize(0, q_);
  s.zb.resize(0);
}

void LinUcbModel::RecomputeH() {
  h_ = s_pp_.llt().solve(s_pc_);
  hht_.noalias() = h_ * h_.transpose();
}

void LinUcbModel::RefreshLossCache(ActionState& s) {
  if (s.primal) {
    s.beta.noalias() = s.a_inv * s.b;
    return;
  }
  const int m = n(s);
  s.zb.resize(m);
  if (m == 0) return;
  s.zb.noalias() = Rows(s) * s.b;
  s.chol.topLeftCorner(m, m).triangularView<Eigen::Lower>().solveInPlace(s.zb);
}

void LinUcbModel::RefreshPostHocCache(ActionState& s) {
  const double lambda = lambda_a_;
  MatrixXd q_mat(q_, q_);  // H A^-1 H^T
  VectorXd hab(q_);        // H A^-1 b
  if (s.primal) {
    s.a_inv_ht.noalias() = s.a_inv * h_.transpose();
    q_mat.noalias() = h_ * s.a_inv_ht;
    hab.noalias() = h_ * s.beta;
  } else {
    const int m = n(s);
    // C H^T = C S_pc^T S_pp^-1 = E S_pp^-1. No Eigen solve on an empty
    // matrix (an action without rounds): that binds a reference to a null
    // pointer inside Eigen, undefined behaviour that only works by luck.
    if (m > 0) {
      s.z = s_pp_.llt().solve(s.e.topRows(m).transpose()).transpose();
      s.chol.topLeftCorner(m, m).triangularView<Eigen::Lower>().solveInPlace(
          s.z);
    } else {
      s.z.resize(0, q_);
    }
    q_mat = hht_ / lambda;
    hab = (h_ * s.b) / lambda;
    if (m > 0) {
      q_mat.noalias() -= (s.z.transpose() * s.z) / lambda;
      hab.noalias() -= (s.z.transpose() * s.zb) / lambda;
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
    absl::Span<const double> context) const {
  const Eigen::Map<const VectorXd> c = AsVector(context);
  const double lambda = lambda_a_;
  const double cc = c.squaredNorm();
  VectorXd hc;
  if (posthoc()) hc.noalias() = h_ * c;
  std::vector<ActionEstimate> out(actions_.size());
  VectorXd z, u;
  for (size_t a = 0; a < actions_.size(); ++a) {
    const ActionState& s = actions_[a];
    double s1 = 0.0;  // c^T A^-1 c
    double s3 = 0.0;  // b^T A^-1 c
    VectorXd s2;      // H A^-1 c
    if (s.primal) {
      u.noalias() = s.a_inv * c;
      s1 = c.dot(u);
      s3 = s.beta.dot(c);
      if (posthoc()) s2.noalias() = s.a_inv_ht.transpose() * c;
    } else {
      const int m = n(s);
      double zz = 0.0, zbz = 0.0;
      if (m > 0) {
        z.noalias() = Rows(s) * c;
        s.chol.topLeftCorner(m, m).triangularView<Eigen::Lower>().solveInPlace(
            z);
        zz = z.squaredNorm();
        zbz = s.zb.dot(z);
      }
      s1 = (cc - zz) / lambda;
      s3 = (s.b.dot(c) - zbz) / lambda;
      if (posthoc()) {
        s2 = hc;
        if (m > 0) s2.noalias() -= s.z.transpose() * z;
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
  }
  return out;
}

void LinUcbModel::Update(const Round& round) {
  const Eigen::Map<const VectorXd> c = AsVector(round.context);
  const double w = round.weight;
  ActionState& taken = actions_[round.action];
  const VectorXd x = std::sqrt(w) * c;
  if (taken.primal) {
    const VectorXd u = taken.a_inv * x;
    const double scale = 1.0 / (1.0 + x.dot(u));
    taken.a_inv.noalias() -= scale * (u * u.transpose());
  } else {
    AppendDualRow(taken, x);
  }
  ++taken.count;
  ++total_rounds_;
  AddScale(round);
  taken.loss_sum += round.loss;
  taken.b.noalias() += (w * round.loss) * c;
  if (!taken.primal && taken.count >= primal_threshold_) {
    SwitchToPrimal(taken);
  }
  RefreshLossCache(taken);
  if (!posthoc()) return;

  const Eigen::Map<const VectorXd> p = AsVector(round.posthoc);
  const VectorXd wp = w * p;
  taken.M.noalias() += wp * p.transpose();
  taken.r.noalias() += round.loss * wp;
  // S_pc gains w p c^T, so every dual E = C S_pc^T gains (C c)(w p)^T.
  for (ActionState& s : actions_) {
    const int m = n(s);
    if (s.primal || m == 0) continue;
    s.e.topRows(m).noalias() += (Rows(s) * c) * wp.transpose();
  }
  s_pc_.noalias() += wp * c.transpose();
  s_pp_.noalias() += wp * p.transpose();
  RecomputeH();
  for (ActionState& s : actions_) RefreshPostHocCache(s);
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
  // Accumulate every sum first, then factor each action once.
  for (const Round& round : rounds) {
    ActionState& s = model.actions_[round.action];
    const Eigen::Map<const VectorXd> c = AsVector(round.context);
    const double w = round.weight;
    const VectorXd x = std::sqrt(w) * c;
    s.rows.insert(s.rows.end(), x.data(), x.data() + model.d_);
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
    if (m >= model.primal_threshold_) {
      model.SwitchToPrimal(s);
    } else if (m > 0) {
      const ConstRowMap rows(s.rows.data(), m, model.d_);
      MatrixXd k = lambda * MatrixXd::Identity(m, m);
      k.selfadjointView<Eigen::Lower>().rankUpdate(rows);
      s.chol = k.selfadjointView<Eigen::Lower>().llt().matrixL();
      if (model.posthoc()) s.e = rows * model.s_pc_.transpose();
    }
    model.RefreshLossCache(s);
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
    doubles += s.rows.capacity() + s.chol.size() + s.e.size() + s.a_inv.size() +
               s.z.size() + s.a_inv_ht.size() + s.b.size() + s.beta.size() +
               s.zb.size() + s.M.size() + 2 * q_ * q_;
  }
  return doubles * sizeof(double) + sizeof(*this);
}

}  // namespace bitewise::bandit
