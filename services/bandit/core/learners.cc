#include "services/bandit/core/learners.h"

#include <utility>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "services/bandit/core/linucb.h"
#include "services/bandit/core/polinucb.h"
#include "services/common/status_macros.h"

namespace bitewise::bandit {
namespace {

// The three entry points of a model class M, as the table's functions.
template <typename M>
absl::StatusOr<std::unique_ptr<LearnerModel>> Owned(absl::StatusOr<M> made) {
  if (!made.ok()) return made.status();
  return std::unique_ptr<LearnerModel>(std::make_unique<M>(*std::move(made)));
}

template <typename M>
absl::StatusOr<std::unique_ptr<LearnerModel>> Create(const BanditConfig& config,
                                                     int primal_threshold) {
  return Owned<M>(M::Create(config, primal_threshold));
}

template <typename M>
absl::StatusOr<std::unique_ptr<LearnerModel>> Rebuild(
    const BanditConfig& config, const std::vector<Round>& rounds,
    int primal_threshold) {
  return Owned<M>(M::Rebuild(config, rounds, primal_threshold));
}

template <typename M>
absl::StatusOr<std::unique_ptr<LearnerModel>> Load(const BanditConfig& config,
                                                   absl::string_view state,
                                                   int primal_threshold) {
  return Owned<M>(M::LoadState(config, state, primal_threshold));
}

constexpr LearnerSpec kLearners[] = {
    {Learner::kPostHoc, "posthoc",
     "post hoc augmented LinUCB (Gordon et al. 2021)", true,
     &Create<LinUcbModel>, &Rebuild<LinUcbModel>, &Load<LinUcbModel>},
    {Learner::kContextOnly, "context_only",
     "LinUCB on the visual context alone", false, &Create<LinUcbModel>,
     &Rebuild<LinUcbModel>, &Load<LinUcbModel>},
    {Learner::kPoLinUcb, "polinucb",
     "poLinUCB, post-serving contexts (Wang et al. 2023)", true,
     &Create<PoLinUcbModel>, &Rebuild<PoLinUcbModel>, &Load<PoLinUcbModel>},
};

absl::StatusOr<const LearnerSpec*> Spec(Learner learner) {
  const LearnerSpec* spec = FindLearner(learner);
  if (spec == nullptr) {
    return absl::InvalidArgumentError(
        absl::StrCat("learner: unknown value ", static_cast<int>(learner),
                     " (known: ", LearnerNames(), ")"));
  }
  return spec;
}

}  // namespace

absl::Span<const LearnerSpec> Learners() { return kLearners; }

const LearnerSpec* FindLearner(Learner learner) {
  for (const LearnerSpec& spec : kLearners) {
    if (spec.learner == learner) return &spec;
  }
  return nullptr;
}

const LearnerSpec* FindLearnerByName(absl::string_view name) {
  for (const LearnerSpec& spec : kLearners) {
    if (name == spec.name) return &spec;
  }
  return nullptr;
}

std::string LearnerNames() {
  return absl::StrJoin(kLearners, ", ",
                       [](std::string* out, const LearnerSpec& spec) {
                         out->append(spec.name);
                       });
}

absl::StatusOr<std::unique_ptr<LearnerModel>> CreateModel(
    const BanditConfig& config, int primal_threshold) {
  ASSIGN_OR_RETURN(const LearnerSpec* spec, Spec(config.learner));
  return spec->create(config, primal_threshold);
}

absl::StatusOr<std::unique_ptr<LearnerModel>> RebuildModel(
    const BanditConfig& config, const std::vector<Round>& rounds,
    int primal_threshold) {
  ASSIGN_OR_RETURN(const LearnerSpec* spec, Spec(config.learner));
  return spec->rebuild(config, rounds, primal_threshold);
}

absl::StatusOr<std::unique_ptr<LearnerModel>> LoadModel(
    const BanditConfig& config, absl::string_view state, int primal_threshold) {
  ASSIGN_OR_RETURN(const LearnerSpec* spec, Spec(config.learner));
  return spec->load(config, state, primal_threshold);
}

namespace {

absl::Status RidgeScale(const char* field, absl::Span<const double> v,
                        const char* ridge_name, double ridge) {
  double squared = 0.0;
  for (double x : v) squared += x * x;
  if (squared <= kMaxSquaredNormPerRidge * ridge) return absl::OkStatus();
  return absl::InvalidArgumentError(absl::StrCat(
      field, ": squared norm ", squared, " is over ", kMaxSquaredNormPerRidge,
      " times ", ridge_name, " (", ridge,
      "), beyond what double precision keeps exact in the model; scale the "
      "values down or create the user with a larger ",
      ridge_name));
}

}  // namespace

absl::Status ValidateInputScale(const BanditConfig& config,
                                absl::Span<const double> context,
                                absl::Span<const double> posthoc) {
  RETURN_IF_ERROR(RidgeScale("context", context, "lambda_c", config.lambda_c));
  if (!UsesPosthoc(config.learner) || posthoc.empty()) {
    return absl::OkStatus();
  }
  return RidgeScale("posthoc", posthoc, "lambda_p", config.lambda_p);
}

}  // namespace bitewise::bandit
