// A dense float64 evaluation of docs/algorithms.md, written straight from the
// formulas with explicit inverses, with the population prior of
// docs/algorithms.md when the config has one. It is the independent reference
// that the incremental LinUcbModel is checked against; it is slow on purpose.
#ifndef BITEWISE_TESTS_BANDIT_DENSE_REFERENCE_H_
#define BITEWISE_TESTS_BANDIT_DENSE_REFERENCE_H_

#include <cmath>
#include <vector>

#include "Eigen/Dense"
#include "services/bandit/core/config.h"
#include "services/bandit/core/linucb.h"

namespace bitewise::bandit::testing {

struct DenseActionModel {
  Eigen::VectorXd theta;
  Eigen::VectorXd phi;
  Eigen::MatrixXd sigma;  // the matrix under the width: A^-1 or 2 N^-1
};

inline std::vector<DenseActionModel> DenseReference(
    const BanditConfig& config, const std::vector<Round>& rounds) {
  using Eigen::MatrixXd;
  using Eigen::VectorXd;
  const int d = config.context_dim;
  const int q = config.posthoc_dim;
  const int k = config.num_actions();
  const bool posthoc = config.learner == Learner::kPostHoc;
  auto vec = [](const std::vector<double>& v) {
    return Eigen::Map<const VectorXd>(v.data(), v.size());
  };
  // The prior: ridges kappa_c ||theta - theta0||^2 and
  // kappa_p ||phi - phi0||^2 on top of lambda_c ||theta||^2, lambda_p
  // ||phi||^2.
  const PopulationPrior& prior = config.prior;
  const double kappa_c = prior.enabled() ? prior.rounds * prior.context_msn : 0;
  const double kappa_p = prior.enabled() ? prior.rounds * prior.posthoc_msn : 0;
  std::vector<MatrixXd> a(
      k, (config.lambda_c + kappa_c) * MatrixXd::Identity(d, d));
  std::vector<VectorXd> b(k, VectorXd::Zero(d));
  std::vector<MatrixXd> m(
      k, (config.lambda_p + kappa_p) * MatrixXd::Identity(q, q));
  std::vector<VectorXd> r(k, VectorXd::Zero(q));
  if (prior.enabled()) {
    for (int i = 0; i < k; ++i) {
      b[i] = kappa_c * vec(prior.theta0[i]);
      if (posthoc) r[i] = kappa_p * vec(prior.phi0[i]);
    }
  }
  MatrixXd s_pp = config.lambda_p * MatrixXd::Identity(q, q);
  MatrixXd s_pc = MatrixXd::Zero(q, d);
  for (const Round& t : rounds) {
    const VectorXd c = vec(t.context);
    a[t.action] += t.weight * c * c.transpose();
    b[t.action] += t.weight * t.loss * c;
    if (posthoc) {
      const VectorXd p = vec(t.posthoc);
      m[t.action] += t.weight * p * p.transpose();
      r[t.action] += t.weight * t.loss * p;
      s_pp += t.weight * p * p.transpose();
      s_pc += t.weight * p * c.transpose();
    }
  }
  std::vector<DenseActionModel> out(k);
  const MatrixXd h = s_pp.inverse() * s_pc;
  for (int i = 0; i < k; ++i) {
    if (!posthoc) {
      out[i].sigma = a[i].inverse();
      out[i].theta = out[i].sigma * b[i];
      continue;
    }
    const MatrixXd n_inv = (a[i] + h.transpose() * m[i] * h).inverse();
    out[i].theta = n_inv * (b[i] + h.transpose() * r[i]);
    out[i].phi = h * out[i].theta;
    out[i].sigma = 2.0 * n_inv;
  }
  return out;
}

// poLinUCB (docs/algorithms.md, "poLinUCB"), evaluated at one context c:
// per action the ridge regression on u = [c; p] with the explicit
// (d+q) x (d+q) inverse, and the post hoc prediction p_hat(c) from the
// explicit inverse of X.
struct DensePoLinUcb {
  Eigen::VectorXd p_hat;
  double radius = 0.0;
  std::vector<Eigen::VectorXd> theta;
  std::vector<Eigen::VectorXd> beta;
  std::vector<double> predicted;
  std::vector<double> width;
  std::vector<double> lcb;
};

inline DensePoLinUcb DensePoLinUcbReference(const BanditConfig& config,
                                            const std::vector<Round>& rounds,
                                            const std::vector<double>& at) {
  using Eigen::MatrixXd;
  using Eigen::VectorXd;
  const int d = config.context_dim;
  const int q = config.posthoc_dim;
  const int k = config.num_actions();
  auto vec = [](const std::vector<double>& v) {
    return Eigen::Map<const VectorXd>(v.data(), v.size());
  };
  const PopulationPrior& prior = config.prior;
  const double kappa_c = prior.enabled() ? prior.rounds * prior.context_msn : 0;
  const double kappa_p = prior.enabled() ? prior.rounds * prior.posthoc_msn : 0;
  // Eq. (3)-(4) with the ridges diag(lambda_c + kappa_c, lambda_p +
  // kappa_p), centred on the prior's (theta0, phi0).
  MatrixXd ridge = MatrixXd::Zero(d + q, d + q);
  ridge.topLeftCorner(d, d) =
      (config.lambda_c + kappa_c) * MatrixXd::Identity(d, d);
  ridge.bottomRightCorner(q, q) =
      (config.lambda_p + kappa_p) * MatrixXd::Identity(q, q);
  std::vector<MatrixXd> a(k, ridge);
  std::vector<VectorXd> b(k, VectorXd::Zero(d + q));
  if (prior.enabled()) {
    for (int i = 0; i < k; ++i) {
      b[i].head(d) = kappa_c * vec(prior.theta0[i]);
      b[i].tail(q) = kappa_p * vec(prior.phi0[i]);
    }
  }
  MatrixXd x = config.lambda_c * MatrixXd::Identity(d, d);
  MatrixXd s_cp = MatrixXd::Zero(d, q);
  for (const Round& t : rounds) {
    VectorXd u(d + q);
    u << vec(t.context), vec(t.posthoc);
    a[t.action] += t.weight * u * u.transpose();
    b[t.action] += t.weight * t.loss * u;
    x += vec(t.context) * vec(t.context).transpose();
    s_cp += vec(t.context) * vec(t.posthoc).transpose();
  }
  DensePoLinUcb out;
  const VectorXd c = vec(at);
  const MatrixXd x_inv = x.inverse();
  out.p_hat = s_cp.transpose() * x_inv * c;
  out.radius = config.phi_radius * std::sqrt(c.dot(x_inv * c));
  VectorXd u(d + q);
  u << c, out.p_hat;
  for (int i = 0; i < k; ++i) {
    const MatrixXd a_inv = a[i].inverse();
    const VectorXd w = a_inv * b[i];
    out.theta.push_back(w.head(d));
    out.beta.push_back(w.tail(q));
    // The largest eigenvalue of A^-1's post hoc block (S^-1).
    const Eigen::SelfAdjointEigenSolver<MatrixXd> block(
        a_inv.bottomRightCorner(q, q), Eigen::EigenvaluesOnly);
    const double pred = u.dot(w);
    const double width = std::sqrt(u.dot(a_inv * u)) +
                         out.radius * std::sqrt(block.eigenvalues()(q - 1));
    out.predicted.push_back(pred);
    out.width.push_back(width);
    out.lcb.push_back(pred - config.alpha * width -
                      out.radius * w.tail(q).norm());
  }
  return out;
}

}  // namespace bitewise::bandit::testing

#endif  // BITEWISE_TESTS_BANDIT_DENSE_REFERENCE_H_
