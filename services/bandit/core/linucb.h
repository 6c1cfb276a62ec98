// LinUcbModel: the learning core of bitewise. One user's context-only LinUCB
// or post hoc augmented LinUCB (Gordon et al., ICRA 2021), exactly as in
// docs/algorithms.md, updated incrementally without O(d^3) work per round.
//
// Representation. Every action keeps A_a = lambda I + sum w c c^T (lambda =
// lambda_c, plus kappa_c with a population prior; see PopulationPrior) in
// the cheaper of two forms:
//  - dual, while the action has few rounds (n_a below about d/2): the whitened
//  rows
//    W_a = L_a^-1 C_a (n x d), where C_a holds the rows sqrt(w) c and L_a is
//    the Cholesky factor of K_a = lambda I + C_a C_a^T. Then
//    A_a^-1 x = (x - W_a^T W_a x) / lambda, so a Select costs one pass over
//    the action's rows (n d), an appended row costs two, and nothing of size
//    n^2 is stored. Earlier rows of W never change when a row is appended,
//    so the rows live in blocks that never move (no doubling copies);
//  - primal: A_a^-1 itself (d x d, lower triangle), kept by Sherman-Morrison.
// The switch is amortised, and one action converts at a time: the action
// that has passed 2/3 of the threshold with the most rounds first has
// its d x d matrix written a slice per Update (kPrepareUpdates Updates), then
// every Update, of any action, folds up to kConversionRowsPerUpdate of its
// rows into one of kFoldSlices column slices of A_a^-1 = (I - sum_i w_i
// w_i^T) / lambda (slices of equal area, taken in turn, each with its own
// count of rows folded in), while the dual form keeps answering; the Update
// after which every slice holds every row turns it primal. So no Update
// carries more than one of these steps, and none a pass over the whole d x d
// matrix, whatever the actions' counts, and at most one action holds both
// forms. (An action whose every Update brings it a row, as a model of one
// action, can never have every slice current: after kMaxChaseUpdates
// Updates of chasing its last rows, they are folded into the whole matrix
// at once and it turns primal.)
// The post hoc term H^T M_a H is folded in by Woodbury with R_a^T R_a = M_a,
// so N_a^-1 = A_a^-1 - A_a^-1 G^T (I + G A_a^-1 G^T)^-1 G A_a^-1 with
// G = R_a H, and only products with S_pc^T (n x q dual, d x q primal) and
// q x q quantities are cached per action; each is updated by a rank-one
// term per round, not recomputed.
//
// A Select's per-action products (W_a c or A_a^-1 c) are what the Update of
// the same context needs: Estimate can hand them out (SelectProducts) and
// Update reuses them when the model has not changed since, so an Update
// costs one d x d rank-one update (primal) or one pass over the taken
// action's rows (dual), plus O(K (n or d) q^2).
//
// Thread-compatible: const methods may run concurrently; Update needs
// exclusive access.
#ifndef BITEWISE_SERVICES_BANDIT_CORE_LINUCB_H_
#define BITEWISE_SERVICES_BANDIT_CORE_LINUCB_H_

#include <array>
#include <cstdint>
#include <functional>
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
#include "services/bandit/core/learner_model.h"
#include "services/bandit/core/rounds.h"

namespace bitewise::bandit {

// Rows of a matrix with a fixed number of columns in blocks that never move:
// appending copies nothing already stored, and spare capacity stays within
// an eighth of the rows (or one block of 8 rows while the matrix is small).
class RowBlocks {
 public:
  explicit RowBlocks(int cols = 0) : cols_(cols) {}
  RowBlocks(RowBlocks&&) = default;
  RowBlocks& operator=(RowBlocks&&) = default;

  int rows() const { return rows_; }
  // Room for `n` more rows, contiguous; they count once written.
  double* Append(int n);
  const double* Row(int i) const;
  double* MutableRow(int i) { return const_cast<double*>(Row(i)); }
  // Frees up to `n` blocks from the end (rows in them are gone).
  void ReleaseBlocks(int n);
  size_t CapacityDoubles() const;
  void Clear();
  // Calls f(first_row, rows, data) for each block's contiguous rows.
  template <typename F>
  void ForEachBlock(F f) const {
    for (const Block& block : blocks_) {
      if (block.used > 0) f(block.first, block.used, block.data.get());
    }
  }

 private:
  struct Block {
    std::unique_ptr<double[]> data;
    int first = 0;
    int capacity = 0;
    int used = 0;
  };
  int cols_ = 0;
  int rows_ = 0;
  std::vector<Block> blocks_;
};

class LinUcbModel final : public LearnerModel {
 public:
  using LearnerModel::Estimate;
  using LearnerModel::SaveState;
  using LearnerModel::Update;

  // Rows folded into one column slice of the primal form per Update while
  // an action converts, and the slices (of equal area) taken in turn. Four
  // slices since 2026-12-03 (two before): half the fold per Update, and with
  // the earlier start below the conversions still end by about 11,500
  // events at d = 2048, K = 6 (docs/benchmarks.md).
  static constexpr int kConversionRowsPerUpdate = 7;
  static constexpr int kFoldSlices = 4;
  // Updates an action may chase its newest rows (every slice within
  // kConversionRowsPerUpdate rows of its count, none yet holding all)
  // before they go into the whole matrix at once.
  static constexpr int kMaxChaseUpdates = 8;
  // Updates over which the conversion's d x d matrix is first written (at
  // large d; a d x d matrix under 256 KB is written at once).
  static constexpr int kPrepareUpdates = 32;
  // An action may start converting at ceil(T * 2/3) rounds (d/2 at the
  // default T = 3d/4). Converting later (7/8 of T, to 2026-12-03) made the
  // actions that wait their turn meanwhile grow past 1,800 rows at d = 2048,
  // and a dual Update of one of them plus a fold was the slowest Update of a
  // model's life (docs/benchmarks.md, "The switch from dual to primal form").
  static constexpr int kConversionStartNumerator = 2;
  static constexpr int kConversionStartDenominator = 3;

  // `primal_threshold` T: an action may start converting to primal form at
  // ceil(T * 2/3) rounds, when no other action is converting (the one with
  // the most rounds first); it then takes about kPrepareUpdates +
  // kFoldSlices n / 7 Updates of any actions. 0 means 3d/4: a Select reads
  // n d numbers in dual form and d^2/2 in primal form (the lower triangle),
  // so primal reads less from n = d/2, while the dual form is smaller until
  // n = d. T is part of a saved state (LoadState refuses another); the start
  // is not.
  static absl::StatusOr<LinUcbModel> Create(const BanditConfig& config,
                                            int primal_threshold = 0);

  // Rebuilds a model from its log, in log order, in batch (one
  // factorisation per action rather than one update per round).
  static absl::StatusOr<LinUcbModel> Rebuild(const BanditConfig& config,
                                             const std::vector<Round>& rounds,
                                             int primal_threshold = 0);

  LinUcbModel(LinUcbModel&&) = default;
  LinUcbModel& operator=(LinUcbModel&&) = default;

  const BanditConfig& config() const override { return config_; }
  int context_dim() const { return d_; }
  int posthoc_dim() const { return q_; }

  // INVALID_ARGUMENT naming the field if `context` has the wrong length, a
  // non-finite value, or a value beyond kMaxInputMagnitude.
  absl::Status ValidateContext(absl::Span<const double> context) const override;
  // INVALID_ARGUMENT naming the field for a loss outside [0, 1], a post hoc
  // context of the wrong length or with a non-finite value. The
  // context-only learner also accepts an empty post hoc context.
  absl::Status ValidateOutcome(double loss,
                               absl::Span<const double> posthoc) const override;
  // Everything Update needs, plus the action index and a positive weight.
  absl::Status ValidateRound(const Round& round) const override;

  // Estimates for every action at context `c` (already validated). With
  // `products`, also leaves there what Update can reuse for this context.
  std::vector<ActionEstimate> Estimate(absl::Span<const double> c,
                                       SelectProducts* products) const override;

  // Estimate, with `also` (reading about `also_cost` numbers) run as one
  // more task beside the actions' passes, on the same two threads when
  // they split (split_run.h): poLinUCB's pooled model in primal form.
  std::vector<ActionEstimate> EstimateAlongside(
      absl::Span<const double> c, SelectProducts* products,
      const std::function<void()>& also, double also_cost) const;
  // The numbers a Select reads for `action`: n_a d in dual form, d(d+1)/2
  // in primal form.
  double SelectCost(int action) const;

  // Adds one round. The round must pass ValidateRound. `products` from an
  // Estimate of the same context are used if the model has not changed
  // since (otherwise they are ignored and recomputed): the result is the
  // same either way.
  void Update(const Round& round, const SelectProducts* products) override;

  // Adds rounds in order, as many Updates would, but refreshes the caches
  // every action keeps only once at the end: a replay of the events after
  // a checkpoint costs one pass over the taken action's form per round
  // instead of a Select's. When no conversion is under way or would begin,
  // each action's rounds are added at once (primal: Woodbury; dual: a block
  // of the Cholesky factor): matrix products instead of one pass per round,
  // equal to rounding. Every round must pass ValidateRound.
  void Replay(const std::vector<Round>& rounds) override;

  // A_a^-1 x for a d-vector x (one pass over the action's form), or, with
  // `products` of an Estimate at x of this model state, from them (one
  // pass less). The same result either way.
  Eigen::VectorXd SolveA(int action, const Eigen::VectorXd& x,
                         const SelectProducts* products = nullptr) const;

  // theta_a (length d) and phi_a = H theta_a (length q; empty for the
  // context-only learner).
  Eigen::VectorXd Theta(int action) const override;
  Eigen::VectorXd Phi(int action) const override;
  int64_t Count(int action) const override { return actions_[action].count; }
  double LossSum(int action) const override {
    return actions_[action].loss_sum;
  }
  int64_t TotalRounds() const override { return total_rounds_; }
  bool IsPrimal(int action) const { return actions_[action].primal; }
  // The diagonal of A_a (lambda_c, plus kappa_c with a population prior)
  // and the primal threshold T in use.
  double ridge() const { return lambda_a_; }
  int primal_threshold() const { return primal_threshold_; }
  // W_a X for an action in dual form (not IsPrimal) and a d x k matrix X:
  // the products of its whitened rows with X's columns (n_a x k), the
  // Select's product when k = 1; one pass over the rows.
  Eigen::MatrixXd DualProducts(
      int action, const Eigen::Ref<const Eigen::MatrixXd>& x) const;
  bool IsConverting(int action) const { return actions_[action].converting; }
  const InputScale& input_scale() const override { return scale_; }

  // Bytes held by the model's matrices and buffers.
  size_t MemoryBytes() const override;

  // The model's whole state (every sum, form and factor; not the config)
  // as bytes in this host's float64 layout: a checkpoint from which
  // LoadState restores exactly this model, bit for bit, without its log
  // (later rounds then agree to rounding: the restored rows sit in one
  // block, and passes over them sum block by block).
  // The same into `*state`'s storage: with capacity for StateBytesBound()
  // already there (allocated and touched before), saving is only copying,
  // which is what a caller holding the user's lock wants.
  void SaveState(std::string* state) const override;
  size_t StateBytesBound() const override;
  // FAILED_PRECONDITION if `state` was saved for another configuration or
  // primal threshold; DATA_LOSS naming what is wrong if it is not a whole
  // state of this format.
  static absl::StatusOr<LinUcbModel> LoadState(const BanditConfig& config,
                                               absl::string_view state,
                                               int primal_threshold = 0);

 private:
  using RowMatrix =
      Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  using ConstRowMap = Eigen::Map<const RowMatrix>;

  struct ActionState {
    int64_t count = 0;
    double loss_sum = 0.0;
    bool primal = false;
    Eigen::VectorXd b;  // sum w l c (plus the prior's kappa_c theta0)
    Eigen::MatrixXd M;  // lambda_p I + sum w p p^T (q x q)
    Eigen::VectorXd r;  // sum w l p

    // Dual form: W = L^-1 C (count rows of d), W b, Y = W S_pc^T (n x q).
    RowBlocks w;
    Eigen::VectorXd wb;
    Eigen::MatrixXd y;

    // Conversion to primal. First the lower triangle of `candidate` is set
    // to I / lambda, `prepared` columns at a time; then (`converting`) its
    // column slice i holds (I - sum w_j w_j^T) / lambda over the rows
    // [0, folded[i]); `next_slice` is the slice the next fold goes into, and
    // `chase` counts the Updates since every slice came within
    // kConversionRowsPerUpdate rows of the count.
    int prepared = 0;
    bool converting = false;
    std::array<int, kFoldSlices> folded{};
    int next_slice = 0;
    int chase = 0;
    Eigen::MatrixXd candidate;
    // W's blocks after the switch, released a few per Update so that no
    // single call pays for unmapping them all.
    RowBlocks retired;

    // Primal form: A^-1 (lower triangle) and, post hoc, S_pc A^-1 S_pc^T
    // (q x q) and S_pc A^-1 b (q), each kept by rank-one terms in A^-1 c,
    // so the switch needs no pass over A^-1 to start them.
    Eigen::MatrixXd a_inv;
    Eigen::MatrixXd spq;
    Eigen::VectorXd spb;

    // Post hoc caches, refreshed after every update.
    Eigen::MatrixXd z;                // dual: Y S_pp^-1 = W H^T (n x q)
    Eigen::MatrixXd r_factor;         // R with R^T R = M
    Eigen::LLT<Eigen::MatrixXd> cap;  // I + R H A^-1 H^T R^T
    Eigen::VectorXd h;                // cap^-1 R H A^-1 (b + H^T r)
  };

  LinUcbModel(const BanditConfig& config, int primal_threshold);

  // One round; with `caches` false, the per-action caches (W b, W S_pc^T,
  // S_pc A^-1 [S_pc^T b], H and the post hoc terms) are left for Replay to
  // refresh.
  void Apply(const Round& round, const SelectProducts* products, bool caches);
  // Whether Replay may add each action's rounds at once: no conversion is
  // under way and none would begin within `rounds`.
  bool CanReplayInBatch(const std::vector<Round>& rounds) const;
  void ReplayBatch(const std::vector<Round>& rounds);
  // W b and W S_pc^T, or S_pc A^-1 [S_pc^T b], from scratch (one pass over
  // A^-1).
  void RefreshDualSums(ActionState& s);
  void RefreshPrimalSums(ActionState& s);
  // S_pc A^-1 [S_pc^T b] from the dual caches, which must be current.
  void PrimalSumsFromDual(ActionState& s);
  bool posthoc() const { return config_.learner == Learner::kPostHoc; }
  // W x (dual) or A^-1 x (primal) for a d-vector x: the Select product.
  Eigen::VectorXd Product(const ActionState& s,
                          const Eigen::Ref<const Eigen::VectorXd>& x) const;
  // A_a^-1 x for a d-vector x.
  Eigen::VectorXd ApplyAInverse(const ActionState& s,
                                const Eigen::VectorXd& x) const;
  // W^T v for an n-vector v.
  Eigen::VectorXd WTranspose(const ActionState& s,
                             const Eigen::VectorXd& v) const;
  // One Update's share of the conversion: nothing, a slice of the
  // candidate's preparation, a fold of rows, or the switch.
  struct ConversionWork {
    enum Kind { kNone, kPrepare, kFold, kSwitch };
    Kind kind = kNone;
    int action = -1;
    int prepare_from = 0;  // kPrepare: columns [prepare_from, prepare_to)
    int prepare_to = 0;
    int first = 0;  // kFold: rows [first, first + count)
    int count = 0;
    int slice = 0;  // kFold: into this column slice
    // kFold: and then the switch, every slice now holding every row.
    bool then_switch = false;
    // kSwitch: slice i lacks rows [from[i], count), folded in first.
    std::array<int, kFoldSlices> from{};
  };
  // Advances the conversion bookkeeping of `actions` (counts already include
  // this Update's round) by one Update and says what work goes with it.
  // Reads and writes only count, primal, prepared, converting, folded,
  // next_slice and chase, so Rebuild can run it on bookkeeping alone.
  ConversionWork PlanConversion(std::vector<ActionState>& actions) const;
  // Slices in which the candidate is prepared, and the column where
  // preparation step k ends (about as many pages per step).
  int PrepareSteps() const;
  int PreparedEnd(int step) const;
  void PrepareColumns(ActionState& s, int from, int to);
  // The first column of fold slice i (i = kFoldSlices: d): the slices of
  // the lower triangle hold equal numbers of entries.
  int SliceBegin(int slice) const;
  // Rows [first, first + count) of W folded into the candidate's columns
  // [col_begin, col_end) (of its lower triangle).
  void FoldRows(ActionState& s, int first, int count, int col_begin,
                int col_end);
  // Rows [first, first + count) of W folded into every slice.
  void FoldRowsEverywhere(ActionState& s, int first, int count) {
    FoldRows(s, first, count, 0, d_);
  }
  void SwitchToPrimal(ActionState& s);
  // The candidate becomes A^-1; W and its caches go.
  void TakePrimal(ActionState& s);
  void RecomputeH();
  // Refreshes the H-dependent caches (after every post hoc update).
  void RefreshPostHocCache(ActionState& s);
  void AddScale(const Round& round);
  // Rounds from which an action may start converting.
  int ConversionStart() const;

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
  Eigen::LLT<Eigen::MatrixXd> s_pp_llt_;
  Eigen::MatrixXd s_pc_;  // sum w p c^T (q x d)
  Eigen::MatrixXd h_;     // S_pp^-1 S_pc (q x d)
  Eigen::MatrixXd hht_;   // H H^T
};

}  // namespace bitewise::bandit

#endif  // BITEWISE_SERVICES_BANDIT_CORE_LINUCB_H_
