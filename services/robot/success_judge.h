// Who decides whether an acquisition picked the food up. In simulation the
// world knows (sim::SimWorld draws from the food's per-action success
// probability); on hardware the static load on the fork after extraction is
// compared with a threshold, or the operator is asked by the orchestrator.
#ifndef BITEWISE_SERVICES_ROBOT_SUCCESS_JUDGE_H_
#define BITEWISE_SERVICES_ROBOT_SUCCESS_JUDGE_H_

#include <optional>
#include <string>

#include "services/domain/haptic_class.h"
#include "services/robot/actions.h"

namespace bitewise::robot {

struct AttemptOutcome {
  bool success = false;
  // True when nobody on the robot side could tell; `success` is then false
  // and the orchestrator asks the operator.
  bool decided_by_operator = false;
  // Simulation only: the food the fork actually touched ("" for none).
  std::string true_food_type;
  // Simulation only: that food's haptic category.
  std::optional<domain::HapticClass> true_haptic_class;
};

// Called by the acquisition loop, one attempt at a time.
class SuccessJudge {
 public:
  virtual ~SuccessJudge() = default;
  // Before the arm moves `action`.
  virtual void BeginAttempt(const ActionSpec& action) = 0;
  // After extraction and settling; `static_load_n` is the weight the fork
  // carries (N, positive down), measured against the pre-approach baseline.
  virtual AttemptOutcome EndAttempt(double static_load_n) = 0;
  // The attempt ended early (Stop, watchdog, force fault).
  virtual void AbortAttempt() = 0;
};

// Hardware: success when the static load reaches `threshold_n`.
class StaticLoadJudge final : public SuccessJudge {
 public:
  explicit StaticLoadJudge(double threshold_n) : threshold_n_(threshold_n) {}
  void BeginAttempt(const ActionSpec&) override {}
  AttemptOutcome EndAttempt(double static_load_n) override {
    AttemptOutcome outcome;
    outcome.success = static_load_n >= threshold_n_;
    return outcome;
  }
  void AbortAttempt() override {}

 private:
  const double threshold_n_;
};

// Hardware without a trusted load threshold: the operator decides.
class OperatorJudge final : public SuccessJudge {
 public:
  void BeginAttempt(const ActionSpec&) override {}
  AttemptOutcome EndAttempt(double) override {
    AttemptOutcome outcome;
    outcome.decided_by_operator = true;
    return outcome;
  }
  void AbortAttempt() override {}
};

}  // namespace bitewise::robot

#endif  // BITEWISE_SERVICES_ROBOT_SUCCESS_JUDGE_H_
