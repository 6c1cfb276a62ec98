// PoLinUcbModel: poLinUCB (Wang, Ye, Feng, Badanidiyuru, Xu, "Follow-ups
// Also Matter: Improving Contextual Bandits via Post-serving Contexts",
// NeurIPS 2023, Algorithm 1), for the bite: the visual context c is the
// pre-serving context x, the haptic post hoc context p the post-serving z,
// and losses are minimised. docs/algorithms.md ("poLinUCB") has the
// formulas with the paper's equation numbers and the choices the paper
// leaves open.
//
// Per action a the loss is modelled as theta_a^T c + beta_a^T p (the
// paper's Section 3.1) and fitted by ridge regression on the observed
// u = [c; p] (Eqs. 3-4): A_a = diag(lambda_c I, lambda_p I) + sum w u u^T,
// [theta_a; beta_a] = A_a^-1 sum w l u. The post hoc context a Select cannot
// see is predicted from c by a ridge regression over every round (the
// paper's phi, linear: Observation 2): X = lambda_c I + sum c c^T,
// p_hat(c) = (sum p c^T) X^-1 c, trusted to a ball of radius
// e = phi_radius * sqrt(c^T X^-1 c) (Assumption 1 with alpha = 1/2, Eq. 5).
//
// Computed without any (d+q) x (d+q) matrix: A_a is split into its blocks,
// C_a = lambda_c I + sum w c c^T (a context-only LinUcbModel keeps C_a^-1
// in its dual or primal form), E_a = sum w c p^T and P_a = lambda_p I +
// sum w p p^T, and A_a^-1 follows from the Schur complement
// S_a = P_a - E_a^T C_a^-1 E_a (q x q). Per action the model keeps
// G_a = C_a^-1 E_a (d x q) and C_a^-1 b_c (d), each updated by a rank-one
// term per round; X^-1 lives in a second context-only model with one
// action that every round feeds.
//
// While that pooled model and every action's C_a are in dual form, a
// Select does not pass over the pooled model's rows: with R the rounds'
// raw contexts (weight 1, in arrival order) and L_X the Cholesky factor of
// lambda_c I + R R^T, c^T X^-1 c = (|c|^2 - |u|^2) / lambda_c with
// u = L_X^-1 R c, and R c comes from the per-action passes the Select
// makes anyway: action a's rows sqrt(w) c_i = (L_a W_a)_i, so its part of
// R c is D_a^-1/2 L_a (W_a c), with L_a the Cholesky factor of
// lambda I + C_a C_a^T (the dual form's, which LinUcbModel does not keep).
// The model keeps L_X and every L_a (n x n triangles, grown a row per
// round from the Select's products) and which pooled row each action's
// row is; u is also the pooled model's own Select product W_X c, so its
// Update reuses it. Once any of the context models turns primal, they go.
//
// Thread-compatible: const methods may run concurrently; Update needs
// exclusive access.
#ifndef BITEWISE_SERVICES_BANDIT_CORE_POLINUCB_H_
#define BITEWISE_SERVICES_BANDIT_CORE_POLINUCB_H_

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "Eigen/Core"
#include "Eigen/Dense"
#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "absl/types/span.h"
#include "services/bandit/core/config.h"
#include "services/bandit/core/linucb.h"

namespace bitewise::bandit {

// A lower-triangular matrix grown a row at a time, in blocks of kBlockRows
// rows that never move: the block of rows [s, s + B) is a row-major
// B x (s + B) rectangle (its entries right of the diagonal unused), so the
// part left of the block's diagonal is read as one matrix.
class GrowingLower {
 public:
  static constexpr int kBlockRows = 64;

  GrowingLower() = default;
  GrowingLower(GrowingLower&&) = default;
  GrowingLower& operator=(GrowingLower&&) = default;

  int rows() const { return rows_; }
  // Room for row rows() (its rows() + 1 entries up to the diagonal), which
  // counts from now on.
  double* AppendRow();
  const double* Row(int i) const;
  // L x for x of rows() values, and for rows() x k.
  Eigen::VectorXd Times(const Eigen::Ref<const Eigen::VectorXd>& x) const;
  Eigen::MatrixXd TimesMatrix(const Eigen::Ref<const Eigen::MatrixXd>& x) const;
  // L^-1 k (forward substitution), and for rows() x k.
  Eigen::VectorXd Solve(const Eigen::Ref<const Eigen::VectorXd>& k) const;
  Eigen::MatrixXd SolveMatrix(const Eigen::Ref<const Eigen::MatrixXd>& k) const;
  size_t CapacityDoubles() const;

 private:
  using Block = Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic,
                                               Eigen::Dynamic, Eigen::RowMajor>,
                           0, Eigen::OuterStride<>>;
  // Block b's rows in use.
  Block BlockAt(int b) const;
  std::vector<std::unique_ptr<double[]>> blocks_;
  int rows_ = 0;
};

class PoLinUcbModel final : public LearnerModel {
 public:
  using LearnerModel::Estimate;
  using LearnerModel::SaveState;
  using LearnerModel::Update;

  // `primal_threshold` as for LinUcbModel (its context models use it).
  static absl::StatusOr<PoLinUcbModel> Create(const BanditConfig& config,
                                              int primal_threshold = 0);
  // From the log, in batch.
  static absl::StatusOr<PoLinUcbModel> Rebuild(const BanditConfig& config,
                                               const std::vector<Round>& rounds,
                                               int primal_threshold = 0);

  PoLinUcbModel(PoLinUcbModel&&) = default;
  PoLinUcbModel& operator=(PoLinUcbModel&&) = default;

  const BanditConfig& config() const override { return config_; }

  absl::Status ValidateContext(absl::Span<const double> context) const override;
  // A post hoc context of posthoc_dim values is required.
  absl::Status ValidateOutcome(double loss,
                               absl::Span<const double> posthoc) const override;
  absl::Status ValidateRound(const Round& round) const override;

  // Per action: predicted_loss = [c; p_hat]^T [theta_a; beta_a];
  // width = ||[c; p_hat]||_{A_a^-1} + e sqrt(lambda_max(S_a^-1)), the
  // model's confidence over the ball of post hoc contexts; lcb =
  // predicted_loss - alpha width - e ||beta_a||. `products` as for
  // LinUcbModel::Estimate (the context models' products).
  std::vector<ActionEstimate> Estimate(absl::Span<const double> c,
                                       SelectProducts* products) const override;
  // The predicted post hoc context p_hat(c) and the radius e of its ball.
  Eigen::VectorXd PredictPosthoc(absl::Span<const double> c) const;
  std::vector<double> PredictedPosthoc(
      absl::Span<const double> c) const override {
    const Eigen::VectorXd p = PredictPosthoc(c);
    return std::vector<double>(p.data(), p.data() + p.size());
  }
  double PosthocRadius(absl::Span<const double> c) const;

  // One round (it must pass ValidateRound); `products` from an Estimate of
  // the same context are reused when the model has not changed since.
  void Update(const Round& round, const SelectProducts* products) override;
  // Rounds in order; the per-action caches are recomputed once at the end.
  void Replay(const std::vector<Round>& rounds) override;

  // theta_a (length d) and beta_a (length q).
  Eigen::VectorXd Theta(int action) const override;
  Eigen::VectorXd Phi(int action) const override;
  int64_t Count(int action) const override { return contexts_.Count(action); }
  double LossSum(int action) const override {
    return contexts_.LossSum(action);
  }
  int64_t TotalRounds() const override { return contexts_.TotalRounds(); }
  const InputScale& input_scale() const override { return scale_; }
  size_t MemoryBytes() const override;
  // Whether the pooled radius comes from the factors (see the top of this
  // file) rather than from a pass over the pooled model's form.
  bool UsesPooledFactors() const { return factors_.on; }

  // The whole state, as LinUcbModel's: LoadState restores this model bit
  // for bit. FAILED_PRECONDITION for a state of another configuration,
  // DATA_LOSS naming what is wrong for one that is not whole.
  void SaveState(std::string* state) const override;
  size_t StateBytesBound() const override;
  static absl::StatusOr<PoLinUcbModel> LoadState(const BanditConfig& config,
                                                 absl::string_view state,
                                                 int primal_threshold = 0);

 private:
  struct ActionState {
    Eigen::MatrixXd e;        // E_a = sum w c p^T (d x q)
    Eigen::MatrixXd g;        // C_a^-1 E_a (d x q)
    Eigen::VectorXd theta_c;  // C_a^-1 b_c (d)
    Eigen::MatrixXd p;        // P_a (q x q), its ridge included
    Eigen::VectorXd bp;       // sum w l p (plus the prior's term)
    // From the above after every change of the action.
    Eigen::LLT<Eigen::MatrixXd> s_llt;  // S_a = P_a - E_a^T G_a
    Eigen::VectorXd beta;               // S_a^-1 (bp - E_a^T theta_c)
    double s_inv_max = 0.0;             // lambda_max(S_a^-1)
  };

  PoLinUcbModel(const BanditConfig& config, LinUcbModel contexts,
                LinUcbModel pooled);
  // The two context models' configurations.
  static BanditConfig ContextsConfig(const BanditConfig& config);
  static BanditConfig PooledConfig(const BanditConfig& config);
  void Refresh(ActionState& s);
  // G_a, C_a^-1 b_c and Q from the context models (solves, no rank-one
  // history).
  void Recompute();
  // Adds a round's sums (E, P, bp, the pooled sums and the scale).
  void AddSums(const Round& round);
  // sqrt(c^T X^-1 c). With `context_products` (the context models' Select
  // products at c, of this state) the factors need no pass over any rows;
  // with `pooled_products`, the pooled model's Select products go there.
  double PooledWidth(const Eigen::Ref<const Eigen::VectorXd>& c,
                     const SelectProducts* context_products,
                     SelectProducts* pooled_products) const;
  // Whether every context model's action is in dual form.
  bool AllDual() const;
  // R c from the per-action products W_a c (`v`, one per action).
  Eigen::VectorXd PooledKernel(const std::vector<Eigen::VectorXd>& v) const;
  // The factors gain `rounds`, before the context models do: from the
  // context models' rows as they are (none read when the factors are
  // empty, as in Rebuild).
  void ExtendFactors(const std::vector<Round>& rounds);
  // The factors gain one round from W_a c (`v`, before the round, of the
  // round's action) and u = L_X^-1 R c.
  void GrowFactors(const Round& round, const Eigen::VectorXd& v,
                   const Eigen::VectorXd& u);
  void DropFactors() { factors_ = PooledFactors(); }
  size_t FactorBytes() const;

  // L_X, every L_a and the map between them (see the top of this file);
  // `on` while every context model's action is dual (and from Create).
  struct PooledFactors {
    bool on = false;
    GrowingLower pooled;                     // L_X, rows in arrival order
    std::vector<GrowingLower> per_action;    // L_a
    std::vector<std::vector<int>> row;       // per action: its pooled rows
    std::vector<std::vector<double>> scale;  // per action: 1 / sqrt(w)
  };

  BanditConfig config_;
  int d_ = 0;
  int q_ = 0;
  LinUcbModel contexts_;  // C_a and b_c per action (context-only)
  LinUcbModel pooled_;    // X: one action, every round, weight 1
  std::vector<ActionState> actions_;
  Eigen::MatrixXd s_cp_;   // sum c p^T over every round (d x q)
  Eigen::MatrixXd q_map_;  // X^-1 s_cp (d x q): p_hat(c) = q_map^T c
  PooledFactors factors_;
  InputScale scale_;
};

}  // namespace bitewise::bandit

#endif  // BITEWISE_SERVICES_BANDIT_CORE_POLINUCB_H_
