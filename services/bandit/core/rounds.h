// The values every learner reads and writes: a completed round, an
// action's estimate, the scale of a model's inputs, and the products a
// Select leaves for the Update of the same context.
#ifndef BITEWISE_SERVICES_BANDIT_CORE_ROUNDS_H_
#define BITEWISE_SERVICES_BANDIT_CORE_ROUNDS_H_

#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "Eigen/Core"
#include "absl/types/span.h"

namespace bitewise::bandit {

// One completed round: what was seen, done, and felt.
struct Round {
  std::vector<double> context;  // c, length d
  int action = 0;               // a
  double loss = 0.0;            // l in [0, 1]
  std::vector<double> posthoc;  // p, length q (may be empty: context-only)
  double weight = 1.0;          // w: 1, or 1/propensity
};

// Why an action would be chosen: losses are minimised.
struct ActionEstimate {
  double predicted_loss = 0.0;  // theta_a^T c
  double width = 0.0;           // sqrt(c^T A_a^-1 c) or sqrt(2 c^T N_a^-1 c)
  double lcb = 0.0;             // predicted_loss - alpha * width
};

// Sums over a model's rounds that describe the scale of its inputs, for
// pooling (see population_prior.h).
struct InputScale {
  double weight_sum = 0.0;      // sum w
  double context_sq_sum = 0.0;  // sum w ||c||^2
  double posthoc_sq_sum = 0.0;  // sum w ||p||^2 (post hoc learner)
};

// Largest |value| accepted in a context or post hoc context. Features are
// of order 1 to 100 (SPANet's ReLU activations, standardised features,
// log-probabilities); a value of 1e160 is finite but squares to infinity in
// c c^T and would turn every later estimate into NaN for good.
inline constexpr double kMaxInputMagnitude = 1e6;

// Largest ||x||^2 / lambda accepted for a context against lambda_c, or a
// post hoc context against lambda_p. A Cholesky pivot lambda + |x|^2 - |l|^2
// is at least lambda exactly, but in double precision it cancels to noise
// when lambda is below |x|^2 times the rounding error (1e-16): with
// lambda_c = 1e-6 and values of 1e6 the model turned to NaN within ten
// rounds. 1e10 keeps about six digits of every pivot. Defaults: lambda_c
// 1000, lambda_p 1, and features of order 1 to 100, far inside.
inline constexpr double kMaxSquaredNormPerRidge = 1e10;

// A vector of doubles (a context, a post hoc context) seen as an Eigen
// vector, without a copy.
inline Eigen::Map<const Eigen::VectorXd> AsVector(absl::Span<const double> v) {
  return Eigen::Map<const Eigen::VectorXd>(v.data(),
                                           static_cast<Eigen::Index>(v.size()));
}

class LinUcbModel;
class PoLinUcbModel;

// What one Estimate computed per action (W_a c in dual form, A_a^-1 c in
// primal form) for one context, tagged with the model state it belongs to.
// Update reuses it for the same context if the model has not changed since.
class SelectProducts {
 public:
  size_t Bytes() const;

 private:
  friend class LinUcbModel;
  friend class PoLinUcbModel;
  int64_t total_rounds = -1;
  std::vector<double> context;
  std::vector<Eigen::VectorXd> per_action;
  // The products of a model inside the learner (poLinUCB's pooled model).
  std::shared_ptr<SelectProducts> nested;
};

}  // namespace bitewise::bandit

#endif  // BITEWISE_SERVICES_BANDIT_CORE_ROUNDS_H_
