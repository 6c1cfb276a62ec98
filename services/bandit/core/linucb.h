// LinUcbModel: the learning core of bitewise. One user's context-only LinUCB
// or post hoc augmented LinUCB (Gordon et al., ICRA 2021), exactly as in
// docs/algorithms.md, updated incrementally without O(d^3) work per round.
//
// Representation. Every action keeps A_a = lambda_c I + sum w c c^T (with a
// population prior, lambda_c + kappa_c; see PopulationPrior) in one of two
// forms:
//  - dual (while the action has fewer rounds than its primal threshold,
//    by default d): the weighted contexts C_a (n x d) and the Cholesky
//    factor of the kernel K_a = lambda_c I + C_a C_a^T (n x n), so that
//    A_a^-1 x = (x - C_a^T K_a^-1 C_a x) / lambda_c in O(n d);
//  - primal: A_a^-1 itself (d x d), kept by Sherman-Morrison updates.
// The post hoc term H^T M_a H is folded in by Woodbury with R_a^T R_a = M_a,
// so N_a^-1 = A_a^-1 - A_a^-1 G^T (I + G A_a^-1 G^T)^-1 G A_a^-1 with
// G = R_a H costs O(q) extra applications of A_a^-1, and only q x q
// quantities are cached per action. Memory grows with rounds x d while
// rounds < d, not with K x d^2.
//
// Thread-compatible: const methods may run concurrently; Update needs
// exclusive access.
#ifndef BITEWISE_SERVICES_BANDIT_CORE_LINUCB_H_
#define BITEWISE_SERVICES_BANDIT_CORE_LINUCB_H_

#include <cstdint>
#include <vector>

#include "Eigen/Core"
#include "Eigen/Dense"
#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/types/span.h"
#include "services/bandit/core/config.h"

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

class LinUcbModel {
 public:
  // `primal_threshold`: an action switches from dual to primal form when
  // its round count reaches this; 0 means d (the cost crossover).
  static absl::StatusOr<LinUcbModel> Create(const BanditConfig& config,
                                            int primal_threshold = 0);

  // Rebuilds a model from its log, in log order, in batch (one
  // factorisation per action rather than one update per round).
  static absl::StatusOr<LinUcbModel> Rebuild(const BanditConfig& config,
                                             const std::vector<Round>& rounds,
                                             int primal_threshold = 0);

  LinUcbModel(LinUcbModel&&) = default;
  LinUcbModel& operator=(LinUcbModel&&) = default;

  const BanditConfig& config() const { return config_; }
  int num_actions() const { return config_.num_actions(); }
  int context_dim() const { return d_; }
  int posthoc_dim() const { return q_; }

  // INVALID_ARGUMENT naming the field if `context` has the wrong length, a
  // non-finite value, or a value beyond kMaxInputMagnitude.
  absl::Status ValidateContext(absl::Span<const double> context) const;
  // INVALID_ARGUMENT naming the field for a loss outside [0, 1], a post hoc
  // context of the wrong length or with a non-finite value. The
  // context-only learner also accepts an empty post hoc context.
  absl::Status ValidateOutcome(double loss,
                               absl::Span<const double> posthoc) const;
  // Everything Update needs, plus the action index and a positive weight.
  absl::Status ValidateRound(const Round& round) const;

  // Estimates for every action at context `c` (already validated).
  std::vector<ActionEstimate> Estimate(absl::Span<const double> c) const;

  // Adds one round. The round must pass ValidateRound.
  void Update(const Round& round);

  // theta_a (length d) and phi_a = H theta_a (length q; empty for the
  // context-only learner).
  Eigen::VectorXd Theta(int action) const;
  Eigen::VectorXd Phi(int action) const;
  int64_t Count(int action) const { return actions_[action].count; }
  double LossSum(int action) const { return actions_[action].loss_sum; }
  int64_t TotalRounds() const { return total_rounds_; }
  bool IsPrimal(int action) const { return actions_[action].primal; }
  const InputScale& input_scale() const { return scale_; }

  // Bytes held by the model's matrices and buffers.
  size_t MemoryBytes() const;

 private:
  using RowMatrix =
      Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  using ConstRowMap = Eigen::Map<const RowMatrix>;

  struct ActionState {
    int64_t count = 0;
    double loss_sum = 0.0;
    bool primal = false;
    Eigen::VectorXd b;  // sum w l c
    Eigen::MatrixXd M;  // lambda_p I + sum w p p^T (q x q)
    Eigen::VectorXd r;  // sum w l p

    // Dual form: n = count rows of sqrt(w) c, row-major, with spare
    // capacity; the lower Cholesky factor of K in the top-left n x n of
    // `chol`; E = C S_pc^T (n x q) in the top n rows of `e`.
    std::vector<double> rows;
    Eigen::MatrixXd chol;
    Eigen::MatrixXd e;

    // Primal form.
    Eigen::MatrixXd a_inv;  // A^-1 (d x d)

    // Caches refreshed after every update.
    Eigen::VectorXd zb;               // dual: L^-1 C b
    Eigen::MatrixXd z;                // dual: L^-1 C H^T (n x q)
    Eigen::VectorXd beta;             // primal: A^-1 b
    Eigen::MatrixXd a_inv_ht;         // primal: A^-1 H^T (d x q)
    Eigen::MatrixXd r_factor;         // R with R^T R = M
    Eigen::LLT<Eigen::MatrixXd> cap;  // I + R H A^-1 H^T R^T
    Eigen::VectorXd h;                // cap^-1 R H A^-1 (b + H^T r)
  };

  LinUcbModel(const BanditConfig& config, int primal_threshold);

  bool posthoc() const { return config_.learner == Learner::kPostHoc; }
  int n(const ActionState& s) const { return s.primal ? 0 : s.count; }
  ConstRowMap Rows(const ActionState& s) const;
  // A_a^-1 x for a d-vector x.
  Eigen::VectorXd ApplyAInverse(const ActionState& s,
                                const Eigen::VectorXd& x) const;
  void AppendDualRow(ActionState& s, const Eigen::VectorXd& x);
  void SwitchToPrimal(ActionState& s);
  void RecomputeH();
  // Refreshes b-dependent caches (only needed when the action changed).
  void RefreshLossCache(ActionState& s);
  // Refreshes H-dependent caches (after every post hoc update).
  void RefreshPostHocCache(ActionState& s);
  void AddScale(const Round& round);

  BanditConfig config_;
  int d_ = 0;
  int q_ = 0;
  int primal_threshold_ = 0;
  // The diagonal of A_a: lambda_c plus the population prior's kappa_c.
  double lambda_a_ = 0.0;
  int64_t total_rounds_ = 0;
  InputScale scale_;
  std::vector<ActionState> actions_;
  Eigen::MatrixXd s_pp_;  // lambda_p I + sum w p p^T (q x q)
  Eigen::MatrixXd s_pc_;  // sum w p c^T (q x d)
  Eigen::MatrixXd h_;     // S_pp^-1 S_pc (q x d)
  Eigen::MatrixXd hht_;   // H H^T
};

}  // namespace bitewise::bandit

#endif  // BITEWISE_SERVICES_BANDIT_CORE_LINUCB_H_
