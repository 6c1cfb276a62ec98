// The post hoc context p the bandit learns from for one classified bite,
// and what an unfamiliar bite sends instead (docs/experiments.md,
// "Unfamiliar traces"). One definition for the orchestrator's meal (which
// sends it in Update) and the simulated meals (which measure the choice).
#ifndef BITEWISE_SERVICES_DOMAIN_POSTHOC_CONTEXT_H_
#define BITEWISE_SERVICES_DOMAIN_POSTHOC_CONTEXT_H_

#include <cmath>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"
#include "absl/types/span.h"

namespace bitewise::domain {

// What a bite whose trace the HapticService calls unfamiliar sends.
enum class UnfamiliarPosthoc {
  // HapticNet's answer as it is (familiarity ignored).
  kAsIs,
  // Flattened: the uniform distribution over the classes, as if HapticNet
  // had said nothing (log-probabilities log(1/K), probabilities 1/K).
  kUniform,
  // No post hoc context: p = 0, so the post hoc part of the model learns
  // nothing from the bite (the visual part still does).
  kZero,
};

// The measured choice (docs/experiments.md, "Unfamiliar traces"): on the
// tuning seed (2) of the simulated meals with compliant-story traces, post
// hoc LinUCB failed least when unfamiliar bites kept HapticNet's answer
// (+0.86 fewer failures per meal than context-only, against +0.63 flattened
// and +0.28 with no post hoc context), so the answer is sent as it is.
// poLinUCB (the default learner from 2026-12-03 to 2026-12-06) chose the
// same on the same seed and
// story (400 trials, 2026-12-06: +0.40, against +0.34 flattened and -0.54
// with none).
inline constexpr UnfamiliarPosthoc kDefaultUnfamiliarPosthoc =
    UnfamiliarPosthoc::kAsIs;

// What a bite sends when the robot's force limit stopped the descent and
// cut its trace short (AcquireResult.force_limit_reached; the rules above,
// applied to every such bite), by the person's learner. The measured choice
// (docs/experiments.md, "A trace the robot cut short"; rule: keep "no post
// hoc context" unless it fails more in the mean), on the tuning seed (2) of
// the simulated meals with the actions' force limits:
// - post hoc LinUCB failed 0.44 more times per meal with no post hoc context
//   for such bites than with HapticNet's answer on the cut trace, so it gets
//   the answer as it is (kAsIs; 0.32 on report seed 1, 0.23 on seed 3);
// - poLinUCB failed 1.37 fewer times with none, so it gets kZero, which for
//   a cut bite means "no post hoc context of its own": the meal sends its
//   predicted p_hat(c) (SelectResponse.predicted_posthoc).
// `learner_predicts_posthoc`: the person's learner is poLinUCB.
inline constexpr UnfamiliarPosthoc DefaultLimitReachedPosthoc(
    bool learner_predicts_posthoc) {
  return learner_predicts_posthoc ? UnfamiliarPosthoc::kZero
                                  : UnfamiliarPosthoc::kAsIs;
}

// "asis", "uniform", "zero".
inline const char* UnfamiliarPosthocName(UnfamiliarPosthoc rule) {
  switch (rule) {
    case UnfamiliarPosthoc::kAsIs:
      return "asis";
    case UnfamiliarPosthoc::kUniform:
      return "uniform";
    case UnfamiliarPosthoc::kZero:
      return "zero";
  }
  return "unknown";
}

// The inverse of UnfamiliarPosthocName; INVALID_ARGUMENT naming the choices.
inline absl::StatusOr<UnfamiliarPosthoc> ParseUnfamiliarPosthoc(
    absl::string_view name) {
  for (UnfamiliarPosthoc rule :
       {UnfamiliarPosthoc::kAsIs, UnfamiliarPosthoc::kUniform,
        UnfamiliarPosthoc::kZero}) {
    if (name == UnfamiliarPosthocName(rule)) return rule;
  }
  return absl::InvalidArgumentError(
      absl::StrCat("post hoc rule \"", std::string(name),
                   "\": expected asis, uniform or zero"));
}

// The post hoc context of a bite: `answer` (HapticNet's probabilities, or
// its log-probabilities when `log_form`) when the trace is familiar or the
// rule is kAsIs; otherwise what `rule` sends, with answer.size() entries.
inline std::vector<double> PosthocContext(absl::Span<const double> answer,
                                          bool log_form, bool unfamiliar,
                                          UnfamiliarPosthoc rule) {
  if (!unfamiliar || rule == UnfamiliarPosthoc::kAsIs || answer.empty()) {
    return std::vector<double>(answer.begin(), answer.end());
  }
  if (rule == UnfamiliarPosthoc::kZero) {
    return std::vector<double>(answer.size(), 0.0);
  }
  const double uniform = 1.0 / static_cast<double>(answer.size());
  return std::vector<double>(answer.size(),
                             log_form ? std::log(uniform) : uniform);
}

}  // namespace bitewise::domain

#endif  // BITEWISE_SERVICES_DOMAIN_POSTHOC_CONTEXT_H_
