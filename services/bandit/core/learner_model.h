// LearnerModel: one user's learner as the rest of the service sees it. The
// engine, the stores' tools, the population prior, checkpoints and the
// experiments hold a LearnerModel and never a concrete learner; which class
// serves a configuration is decided by the table in learners.h.
//
// Every learner estimates each action's loss at a context (Estimate, which
// the strategies of policy.h turn into a choice), learns from completed
// rounds one at a time (Update) or in order (Replay), and saves and loads
// its whole state bit for bit (SaveState, and the table's load). Thompson
// sampling and the other strategies work on any learner's estimates.
//
// Thread-compatible: const methods may run concurrently; Update and Replay
// need exclusive access.
#ifndef BITEWISE_SERVICES_BANDIT_CORE_LEARNER_MODEL_H_
#define BITEWISE_SERVICES_BANDIT_CORE_LEARNER_MODEL_H_

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "Eigen/Core"
#include "absl/status/status.h"
#include "absl/types/span.h"
#include "services/bandit/core/config.h"
#include "services/bandit/core/rounds.h"

namespace bitewise::bandit {

class LearnerModel {
 public:
  virtual ~LearnerModel() = default;

  virtual const BanditConfig& config() const = 0;
  int num_actions() const { return config().num_actions(); }

  // INVALID_ARGUMENT naming the field: a context of the wrong length, a
  // non-finite value or one beyond kMaxInputMagnitude.
  virtual absl::Status ValidateContext(
      absl::Span<const double> context) const = 0;
  // INVALID_ARGUMENT naming the field: a loss outside [0, 1], a post hoc
  // context this learner cannot take.
  virtual absl::Status ValidateOutcome(
      double loss, absl::Span<const double> posthoc) const = 0;
  // Everything Update needs, plus the action index and a positive weight.
  virtual absl::Status ValidateRound(const Round& round) const = 0;

  // Estimates for every action at a validated context. With `products`,
  // also leaves there what an Update of the same context can reuse.
  virtual std::vector<ActionEstimate> Estimate(
      absl::Span<const double> context, SelectProducts* products) const = 0;
  std::vector<ActionEstimate> Estimate(absl::Span<const double> context) const {
    return Estimate(context, nullptr);
  }
  // The post hoc context this learner predicts at a validated context, for
  // a client that gets none for the bite to send in its place (poLinUCB's
  // p_hat(c)); empty for learners that make no such prediction.
  virtual std::vector<double> PredictedPosthoc(
      absl::Span<const double> context) const {
    return {};
  }
  // Adds one round (it must pass ValidateRound); `products` from an
  // Estimate of the same context are used when the model has not changed
  // since, with the same result either way.
  virtual void Update(const Round& round, const SelectProducts* products) = 0;
  void Update(const Round& round) { Update(round, nullptr); }
  // Adds rounds in order, as many Updates would (the same result to
  // rounding), in less time.
  virtual void Replay(const std::vector<Round>& rounds) = 0;

  // The action's model of the loss: theta_a over the context (length d)
  // and its post hoc part (length q; empty for a learner without one).
  virtual Eigen::VectorXd Theta(int action) const = 0;
  virtual Eigen::VectorXd Phi(int action) const = 0;
  virtual int64_t Count(int action) const = 0;
  virtual double LossSum(int action) const = 0;
  virtual int64_t TotalRounds() const = 0;
  virtual const InputScale& input_scale() const = 0;

  // Bytes held by the model's matrices and buffers.
  virtual size_t MemoryBytes() const = 0;
  // The whole state into `*state`'s storage (see LinUcbModel::SaveState);
  // with capacity for StateBytesBound() there already, saving only copies.
  virtual void SaveState(std::string* state) const = 0;
  virtual size_t StateBytesBound() const = 0;
  std::string SaveState() const {
    std::string state;
    SaveState(&state);
    return state;
  }

 protected:
  LearnerModel() = default;
  LearnerModel(const LearnerModel&) = default;
  LearnerModel(LearnerModel&&) = default;
  LearnerModel& operator=(const LearnerModel&) = default;
  LearnerModel& operator=(LearnerModel&&) = default;
};

}  // namespace bitewise::bandit

#endif  // BITEWISE_SERVICES_BANDIT_CORE_LEARNER_MODEL_H_
