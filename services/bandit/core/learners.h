// The learners: one table maps each Learner (whose number is also the
// API's LEARNER_* value), its name and the class that serves it. Everything
// outside services/bandit/core makes, rebuilds and loads models through
// CreateModel, RebuildModel and LoadModel, and holds them as LearnerModel.
//
// Adding a learner: its class (a LearnerModel) in one source file, its row
// in learners.cc, a Learner value in config.h and its tests
// (docs/architecture.md lists the files).
#ifndef BITEWISE_SERVICES_BANDIT_CORE_LEARNERS_H_
#define BITEWISE_SERVICES_BANDIT_CORE_LEARNERS_H_

#include <memory>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "absl/types/span.h"
#include "services/bandit/core/config.h"
#include "services/bandit/core/learner_model.h"

namespace bitewise::bandit {

struct LearnerSpec {
  Learner learner;
  const char* name;       // as in flags, logs and CSV columns
  const char* described;  // one line for --help and the docs
  bool uses_posthoc;      // needs posthoc_dim >= 1 and p in every Update
  // `primal_threshold`: where an action's context matrix turns primal
  // (LinUcbModel; 0 for its default).
  absl::StatusOr<std::unique_ptr<LearnerModel>> (*create)(
      const BanditConfig& config, int primal_threshold);
  absl::StatusOr<std::unique_ptr<LearnerModel>> (*rebuild)(
      const BanditConfig& config, const std::vector<Round>& rounds,
      int primal_threshold);
  absl::StatusOr<std::unique_ptr<LearnerModel>> (*load)(
      const BanditConfig& config, absl::string_view state,
      int primal_threshold);
};

// Every learner, in the order of their numbers.
absl::Span<const LearnerSpec> Learners();
// Null for a number no learner has.
const LearnerSpec* FindLearner(Learner learner);
const LearnerSpec* FindLearnerByName(absl::string_view name);
// "posthoc, context_only, polinucb": for messages and --help.
std::string LearnerNames();

// INVALID_ARGUMENT naming the field and the ridge when a request's input
// is larger than a model of `config` can keep exact: ||context||^2 over
// kMaxSquaredNormPerRidge * lambda_c, or ||posthoc||^2 over that times
// lambda_p (learners with a post hoc part). For requests only (Select's
// and Estimate's context, a new Update's post hoc context): events already
// stored were accepted under the rules of their day, and the models'
// floors keep them finite, so a rebuild never applies it. An importance
// weight (1/propensity, up to a few thousand) is not held to it: an
// Update refused for the weight of a Select already answered would leave
// its event pending for good, and the floors keep the model finite.
absl::Status ValidateInputScale(const BanditConfig& config,
                                absl::Span<const double> context,
                                absl::Span<const double> posthoc);

// The model of `config.learner` (INVALID_ARGUMENT for an unknown one, or
// ValidateConfig's error).
absl::StatusOr<std::unique_ptr<LearnerModel>> CreateModel(
    const BanditConfig& config, int primal_threshold = 0);
// From a log, in batch (each round must pass ValidateRound).
absl::StatusOr<std::unique_ptr<LearnerModel>> RebuildModel(
    const BanditConfig& config, const std::vector<Round>& rounds,
    int primal_threshold = 0);
// From a saved state: FAILED_PRECONDITION for a state of another
// configuration, DATA_LOSS naming what is wrong for one that is not whole.
absl::StatusOr<std::unique_ptr<LearnerModel>> LoadModel(
    const BanditConfig& config, absl::string_view state,
    int primal_threshold = 0);

}  // namespace bitewise::bandit

#endif  // BITEWISE_SERVICES_BANDIT_CORE_LEARNERS_H_
