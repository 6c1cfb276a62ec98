// The simulated-meals experiment of docs/experiments.md (Gordon et al. 2021,
// Sec. VI): a user's bandit meets the eight unseen foods of the paper
// (docs/robot.md), eight attempts each, and we count how many attempts fail
// with context-only LinUCB and with post hoc LinUCB fed three forms of the
// haptic context.
//
// Everything comes from the project's own components, in-process and without
// gRPC: the foods and their per-action success probabilities from
// services/sim/food_catalog.h; the visual context from a rendered
// plate (services/sim/scene.h) through the PerceptionService's
// weight-free DefaultFeaturizer on each item's ground-truth box; the post hoc
// context from a simulated force trace of the item's category
// (services/sim/force_trace.h) through the HapticService's
// HapticClassifier; the learners and LinUCB selection from
// services/bandit/core.
//
// A trial is drawn once (SimMealWorld) and then played by every learner, so
// all of them see the same plates, crops, traces and outcome draws and their
// failure counts can be compared pair by pair.
#ifndef BITEWISE_EXPERIMENTS_SIM_MEALS_H_
#define BITEWISE_EXPERIMENTS_SIM_MEALS_H_

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "services/bandit/core/config.h"
#include "services/bandit/core/learner_model.h"
#include "services/domain/posthoc_context.h"
#include "services/haptic/core/haptic_classifier.h"
#include "services/perception/default_featurizer.h"
#include "services/perception/featurizer.h"
#include "services/sim/food_catalog.h"
#include "services/sim/scene.h"

namespace bitewise::experiments {

// A view of `rendered` as perception's frame; `rendered` must outlive it.
perception::DecodedFrame ToDecodedFrame(sim::RenderedFrame& rendered);

// Renders `scene` (noise from `render_seed`) and featurizes every visible
// item on its ground-truth box (location: isolated) with `featurizer`.
// Returns one context per scene item, empty for items with no visible
// pixel. INTERNAL naming the food if featurizing fails.
absl::StatusOr<std::vector<std::vector<double>>> FeaturizeScene(
    const sim::PlateScene& scene, uint64_t render_seed,
    const perception::Featurizer& featurizer);

// What the post hoc learner is told about the haptic classification.
enum class HapticContext {
  kLogProbabilities,  // HapticNet's log-softmax (what the orchestrator sends)
  kProbabilities,     // its softmax
  kOneHot,            // 1 at the predicted class, 0 elsewhere
};
// "logprob", "prob", "onehot".
const char* HapticContextName(HapticContext kind);
// The 4-vector p for `classification` in the form `kind`. When the trace was
// scored unfamiliar, `unfamiliar` decides what is sent instead, as the
// orchestrator does (domain::PosthocContext; the one-hot form flattens to
// 1/4 each, or 0).
std::vector<double> PosthocContext(
    const haptic::HapticClassification& classification, HapticContext kind,
    domain::UnfamiliarPosthoc unfamiliar = domain::UnfamiliarPosthoc::kAsIs);

// In which order a trial's attempts visit the foods.
enum class MealOrder {
  // Every food attempts_per_food times, in a random order (a meal in which
  // the user asks for any item at any time).
  kShuffled,
  // One food after another, attempts_per_food consecutive attempts each,
  // foods in a random order.
  kBlocked,
};

struct SimMealsConfig {
  int attempts_per_food = 8;
  // Rendered plates per trial. Each plate holds every unseen food once; the
  // j-th attempt on a food uses its item on plate j mod plates_per_trial, so
  // the learner sees plates_per_trial appearances of each food per trial.
  // 0 (the default) means attempts_per_food: a new piece, with its own
  // size, shape, orientation, shade and force profile, at every attempt, as
  // on a real plate.
  int plates_per_trial = 0;
  MealOrder order = MealOrder::kShuffled;
  // Whether neighbouring items on a plate may touch (touching items widen
  // each other's ground-truth box context ring).
  bool allow_touching = false;
  // Learner hyperparameters: the product's defaults. lambda_c 0 means
  // rho_c times the default featurizer's E||c||^2 on seen foods, as the
  // orchestrator gives new users; a positive lambda_c is used as given.
  double alpha = 0.01;
  double rho_c = 1.0;
  double lambda_c = 0.0;
  // E||c||^2 of the featurizer in use on seen foods (what it declares); 0:
  // the default featurizer's.
  double context_msn = 0.0;
  double lambda_p = 1.0;
  // Thompson sampling's scale v (theta ~ N(theta_a, v^2 Sigma_a)): 0.03,
  // the best of 0.01-0.5 for post hoc TS on tuning seeds (seed 1001;
  // docs/experiments.md).
  double thompson_v = 0.03;
  // poLinUCB's phi_radius (BanditConfig::phi_radius).
  double phi_radius = bandit::BanditConfig().phi_radius;
  // The foods of the meal (catalog names), each attempts_per_food times;
  // empty means the eight unseen foods.
  std::vector<std::string> food_names;
  // HapticNet accuracy for sensitivity runs: 0 uses the shipped model's
  // answers as they are; a value in (0, 1) makes each attempt's
  // classification wrong with probability 1 - haptic_accuracy (a confident
  // wrong answer: the top probability moves to a random other class), on
  // a random stream of its own.
  double haptic_accuracy = 0.0;
  // Where the attempts' force/torque traces come from: "world" (the
  // simulated world's force-trace model, as the simulated robot streams it:
  // one force profile per item), or an independent trace story that
  // HapticNet may never have seen ("piecewise", "mechanics", "compliant",
  // "puncture"; services/sim/trace_stories.h: a new item of the food's
  // category per attempt). A story trace the haptic pipeline rejects (a soft
  // item too weak to register contact) is drawn again, unless
  // keep_no_contact.
  std::string trace_story = "world";
  // Keep a story's contact-less attempt as it is, as the product meets it:
  // no haptic class, and the post hoc learners get no post hoc context
  // (p = 0), as the orchestrator's meal sends (clients/meal/meal.h). False:
  // the trace is drawn again (up to 200 times), so every attempt has
  // contact.
  bool keep_no_contact = false;
  // What the post hoc learners are given for an attempt whose trace the
  // familiarity model calls unfamiliar (as the orchestrator:
  // domain::kDefaultUnfamiliarPosthoc). Without a familiarity model no
  // trace is unfamiliar.
  domain::UnfamiliarPosthoc unfamiliar_posthoc =
      domain::kDefaultUnfamiliarPosthoc;
  // The robot's force limits halt the fork on the world's traces as the
  // acquisition does (sim::ForceLimitStop; 10 N for TA0/TA90, 20 N for TV,
  // 25 N for VS: domain/skewering_actions.h), so each attempt's haptic
  // answer depends on the action chosen: the trace its limit leaves. Off:
  // every action sees the whole trace (earlier results reproduce). The
  // world's traces only, without haptic_accuracy.
  bool force_limit = false;
  // What a halted attempt sends, for every learner without a rule of its
  // own: no post hoc context, the rule the rows were written with (since
  // 2026-12-06 the orchestrator's default for poLinUCB only; its default
  // for post hoc LinUCB is asis, the row "post hoc, halted asis":
  // domain::DefaultLimitReachedPosthoc). As in the orchestrator, the answer
  // is replaced as the rule says, whatever its familiarity.
  domain::UnfamiliarPosthoc limit_reached_posthoc =
      domain::UnfamiliarPosthoc::kZero;
  // poLinUCB only: an attempt whose post hoc context is missing (no
  // contact, or halted under the zero rule) sends the model's own
  // prediction p_hat(c), made before the update, instead of p = 0. The
  // product does this for halted attempts only (a poLinUCB person's cut
  // trace); contact-less ones send p = 0 (docs/experiments.md, "A missing
  // post hoc context for poLinUCB").
  bool impute_missing_posthoc = false;
};

// The lambda_c the learners use under `config` (see SimMealsConfig).
double ResolvedLambdaC(const SimMealsConfig& config);
// The meal's foods under `config`: food_names from the catalogue, or the
// eight unseen foods. INVALID_ARGUMENT naming an unknown food.
absl::StatusOr<std::vector<const sim::FoodType*>> MealFoods(
    const SimMealsConfig& config);
// The plates per trial under `config` (see SimMealsConfig).
int ResolvedPlatesPerTrial(const SimMealsConfig& config);

// INVALID_ARGUMENT naming the field when a count is not positive.
absl::Status ValidateSimMealsConfig(const SimMealsConfig& config);

// One attempt of a trial as every learner sees it.
struct SimAttempt {
  int food = 0;   // index into SimMealWorld::foods
  int plate = 0;  // which of the trial's plates the item lies on
  // DefaultFeaturizer's 64 numbers for the item's ground-truth box on that
  // plate (location: isolated). Identical for all attempts on the same item.
  std::vector<double> context;
  // HapticClassifier's answer for this attempt's simulated force trace,
  // when it found contact (otherwise `contact` is false and this is empty).
  haptic::HapticClassification haptic;
  bool contact = true;
  // Outcome draw: the attempt succeeds iff coin < success[action], whatever
  // learner chose the action.
  double coin = 0.0;
  // With SimMealsConfig::force_limit, one entry per distinct action force
  // limit: whether the limit halted the fork on this attempt's trace, and
  // the answer on the trace it left (`haptic` itself when it did not).
  struct Limited {
    double limit_n = 0.0;
    bool reached = false;
    haptic::HapticClassification haptic;
  };
  std::vector<Limited> limited;
};

// What the post hoc learners get for `attempt`: PosthocContext of its
// classification, or no post hoc context (p = 0) when it had no contact.
std::vector<double> AttemptPosthoc(
    const SimAttempt& attempt, HapticContext kind,
    domain::UnfamiliarPosthoc unfamiliar = domain::UnfamiliarPosthoc::kAsIs);

// What the post hoc learners get when they chose an action with force limit
// `limit_n` (0: none): as AttemptPosthoc, but on the trace that limit left
// (attempt.limited), and p = 0 for a halted one when `rule` says so.
std::vector<double> ActionPosthoc(const SimAttempt& attempt, double limit_n,
                                  HapticContext kind,
                                  domain::UnfamiliarPosthoc unfamiliar,
                                  domain::UnfamiliarPosthoc rule);

struct SimMealWorld {
  // The meal's foods; SimAttempt::food indexes this.
  std::vector<const sim::FoodType*> foods;
  std::vector<SimAttempt> attempts;  // in the order they are made
  // Plates drawn again because an item did not fit or was not visible.
  int plate_redraws = 0;
  // Story traces drawn again because the pipeline found no contact.
  int story_redraws = 0;
  // Attempts kept without contact (keep_no_contact).
  int no_contact = 0;
};

// The project's components the experiment runs on. Thread-compatible (the
// classifier and featurizer are thread-safe; the world draws are not).
class SimMealsSimulator {
 public:
  // `classifier` is used as the HapticService would use it.
  // `featurizer` null: the PerceptionService's default featurizer.
  explicit SimMealsSimulator(
      std::unique_ptr<haptic::HapticClassifier> classifier,
      std::unique_ptr<perception::Featurizer> featurizer = nullptr);

  // The HapticService's classifier with its default pipeline options and the
  // model in `onnx_path`, or the embedded models/hapticnet/hapticnet.onnx
  // when `onnx_path` is empty, with its familiarity model as the service
  // loads it (the embedded one, or "<onnx_path>.familiarity" when that file
  // exists); the SPANet featurizer from `spanet_model`
  // (with its "<model>.stats" context scale), or the default featurizer when
  // empty. Errors from loading either model.
  static absl::StatusOr<std::unique_ptr<SimMealsSimulator>> Create(
      const std::string& onnx_path, const std::string& spanet_model = "");

  const perception::Featurizer& featurizer() const { return *featurizer_; }

  // Draws trial `seed`: the plates (rendered and featurized; a plate on
  // which some food is missing or invisible is drawn again), the meal's
  // order, one force profile per item and one trace per attempt (classified),
  // and the outcome coins. Errors: INVALID_ARGUMENT for a bad config;
  // INTERNAL when featurizing or classifying fails (the message names the
  // food and the attempt) or no full plate comes up in 20 draws.
  absl::StatusOr<SimMealWorld> DrawWorld(const SimMealsConfig& config,
                                         uint64_t seed) const;

  const haptic::HapticClassifier& classifier() const { return *classifier_; }

 private:
  std::unique_ptr<haptic::HapticClassifier> classifier_;
  std::unique_ptr<perception::Featurizer> featurizer_;
};

// One learner's play of a world.
struct SimMealRun {
  std::vector<int> actions;  // chosen action per attempt
  std::vector<int> failed;   // 1 if the attempt failed
  // failed summed up to and including each attempt.
  std::vector<double> cumulative_failures;
  // Attempts whose chosen action's force limit halted the fork.
  int limit_reached = 0;
};

// Plays `world` with `strategy` (LinUCB with config.alpha, or Thompson
// sampling with v = config.thompson_v) on `learner` (the post hoc learner is
// given the haptic context as `kind`; the context-only learner ignores it),
// updating after every attempt with loss 1 for a failure. `seed` seeds the
// user's Select generator as the BanditService does (Thompson draws from it;
// LinUCB is deterministic). Errors: from the bandit core if a round is
// invalid.
// The bandit configuration a simulated user gets: the product's defaults
// under `config` (resolved lambda_c), `learner` and `strategy`, context
// dimension `context_dim`, 4 haptic classes, seed `seed`, and `prior`.
bandit::BanditConfig SimUserConfig(const SimMealsConfig& config,
                                   bandit::Learner learner,
                                   bandit::Strategy strategy, int context_dim,
                                   uint64_t seed,
                                   const bandit::PopulationPrior& prior = {});

// Plays `world` on an existing user's `model` (which keeps learning across
// meals), as RunSimMealTrial does. `seed` and `first_round` seed the
// Select generator per round.
// `unfamiliar`: what an unfamiliar attempt's post hoc context becomes.
absl::StatusOr<SimMealRun> PlaySimMeal(
    const SimMealWorld& world, HapticContext kind, uint64_t seed,
    int64_t first_round, bandit::LearnerModel& model,
    domain::UnfamiliarPosthoc unfamiliar = domain::UnfamiliarPosthoc::kAsIs,
    domain::UnfamiliarPosthoc limit_rule = domain::UnfamiliarPosthoc::kAsIs,
    bool impute_missing = false);

// Post hoc learners treat unfamiliar attempts as config.unfamiliar_posthoc
// says, halted ones as config.limit_reached_posthoc, and missing ones as
// config.impute_missing_posthoc.
absl::StatusOr<SimMealRun> RunSimMealTrial(
    const SimMealsConfig& config, const SimMealWorld& world,
    bandit::Learner learner, HapticContext kind, uint64_t seed,
    bandit::Strategy strategy = bandit::Strategy::kLinUcb);

// Expected cumulative failures of an oracle that always plays each food's
// best action, and of uniformly random actions, per attempt of `world`.
std::vector<double> OracleExpectedFailures(const SimMealWorld& world);
std::vector<double> UniformExpectedFailures(const SimMealWorld& world);

}  // namespace bitewise::experiments

#endif  // BITEWISE_EXPERIMENTS_SIM_MEALS_H_
