#include "experiments/sim_meals.h"

#include <algorithm>
#include <random>
#include <utility>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "opencv2/core.hpp"
#include "services/bandit/core/learners.h"
#include "services/bandit/core/policy.h"
#include "services/bandit/core/polinucb.h"
#include "services/common/status_macros.h"
#include "services/domain/context_ridge.h"
#include "services/domain/random.h"
#include "services/domain/skewering_actions.h"
#include "services/haptic/default_model.h"
#include "services/haptic/training/labelled_traces.h"
#include "services/perception/spanet_featurizer.h"
#include "services/sim/force_trace.h"
#include "services/sim/scene.h"

namespace bitewise::experiments {
namespace {

// Independent random streams of one trial, so that changing how one part
// draws (say, more plates) leaves the others' draws alone.
enum Stream : uint64_t {
  kPlateStream = 1,
  kOrderStream = 2,
  kProfileStream = 3,
  kTraceStream = 4,
  kCoinStream = 5,
  kHapticErrorStream = 6,
  kRenderNoiseStream = 100,  // + plate index
};

// Draws of a plate before giving up on fitting every food on it.
constexpr int kMaxPlateDraws = 20;
// Redraws of a story trace the haptic pipeline rejects, before giving up.
// Generous: in the poroelastic story only about one soft item in five
// presses hard enough to be found as a contact, so 20 draws failed about
// once in 50 attempts at a soft food. Each attempt's trace is conditional
// on contact, whatever the cap, as long as it is not reached.
constexpr int kMaxStoryDraws = 200;

// Fisher-Yates through our own UniformIndex (std::shuffle's algorithm is
// left to the library).
void Shuffle(std::vector<int>& values, std::mt19937_64& rng) {
  for (int i = static_cast<int>(values.size()) - 1; i > 0; --i) {
    std::swap(values[i], values[random::UniformIndex(rng, i + 1)]);
  }
}

int FoodIndex(const std::vector<const sim::FoodType*>& foods,
              const sim::FoodType* food) {
  for (size_t i = 0; i < foods.size(); ++i) {
    if (foods[i] == food) return static_cast<int>(i);
  }
  return -1;
}

}  // namespace

perception::DecodedFrame ToDecodedFrame(sim::RenderedFrame& rendered) {
  return perception::ViewFrame(rendered.intrinsics, rendered.rgb,
                               rendered.depth_mm);
}

absl::StatusOr<std::vector<std::vector<double>>> FeaturizeScene(
    const sim::PlateScene& scene, uint64_t render_seed,
    const perception::Featurizer& featurizer) {
  sim::RenderedFrame rendered =
      sim::RenderPlate(scene, sim::D415Intrinsics(), render_seed);
  const perception::DecodedFrame frame = ToDecodedFrame(rendered);
  std::vector<std::vector<double>> contexts(scene.items.size());
  for (size_t i = 0; i < scene.items.size(); ++i) {
    const sim::SceneItem& item = scene.items[i];
    const auto truth =
        std::find_if(rendered.truth.begin(), rendered.truth.end(),
                     [&](const sim::ItemTruth& t) { return t.id == item.id; });
    if (truth == rendered.truth.end() || truth->visible_pixels == 0) continue;
    const perception::PixelBox box{truth->x, truth->y, truth->width,
                                   truth->height};
    absl::StatusOr<perception::Features> features =
        featurizer.Featurize(frame, box, perception::FoodLocation::kIsolated);
    if (!features.ok()) {
      return absl::InternalError(absl::StrCat(
          "featurizing ", item.food->name, ": ", features.status().ToString()));
    }
    contexts[i] = std::move(features->context);
  }
  return contexts;
}

const char* HapticContextName(HapticContext kind) {
  switch (kind) {
    case HapticContext::kLogProbabilities:
      return "logprob";
    case HapticContext::kProbabilities:
      return "prob";
    case HapticContext::kOneHot:
      return "onehot";
  }
  return "unknown";
}

std::vector<double> PosthocContext(
    const haptic::HapticClassification& classification, HapticContext kind,
    domain::UnfamiliarPosthoc unfamiliar) {
  const bool flagged =
      classification.has_familiarity && classification.familiarity.unfamiliar;
  switch (kind) {
    case HapticContext::kLogProbabilities:
      return domain::PosthocContext(classification.log_probabilities,
                                    /*log_form=*/true, flagged, unfamiliar);
    case HapticContext::kProbabilities:
      return domain::PosthocContext(classification.probabilities,
                                    /*log_form=*/false, flagged, unfamiliar);
    case HapticContext::kOneHot:
      break;
  }
  std::vector<double> one_hot(haptic::kHapticClasses, 0.0);
  one_hot[static_cast<int>(classification.category)] = 1.0;
  return domain::PosthocContext(one_hot, /*log_form=*/false, flagged,
                                unfamiliar);
}

std::vector<double> AttemptPosthoc(const SimAttempt& attempt,
                                   HapticContext kind,
                                   domain::UnfamiliarPosthoc unfamiliar) {
  if (!attempt.contact) return std::vector<double>(haptic::kHapticClasses, 0.0);
  return PosthocContext(attempt.haptic, kind, unfamiliar);
}

std::vector<double> ActionPosthoc(const SimAttempt& attempt, double limit_n,
                                  HapticContext kind,
                                  domain::UnfamiliarPosthoc unfamiliar,
                                  domain::UnfamiliarPosthoc rule) {
  if (attempt.contact) {
    for (const SimAttempt::Limited& limited : attempt.limited) {
      if (limited.limit_n != limit_n || !limited.reached) continue;
      // As the meal: the cut answer is replaced as `rule` says, whatever
      // its familiarity.
      haptic::HapticClassification flagged = limited.haptic;
      flagged.has_familiarity = true;
      flagged.familiarity.unfamiliar = true;
      return PosthocContext(flagged, kind, rule);
    }
  }
  return AttemptPosthoc(attempt, kind, unfamiliar);
}

absl::Status ValidateSimMealsConfig(const SimMealsConfig& config) {
  if (config.attempts_per_food < 1) {
    return absl::InvalidArgumentError(absl::StrCat(
        "attempts_per_food must be positive, got ", config.attempts_per_food));
  }
  if (config.plates_per_trial < 0) {
    return absl::InvalidArgumentError(
        absl::StrCat("plates_per_trial must be positive (or 0: one per "
                     "attempt), got ",
                     config.plates_per_trial));
  }
  if (config.haptic_accuracy < 0.0 || config.haptic_accuracy >= 1.0 ||
      !(config.thompson_v > 0.0)) {
    return absl::InvalidArgumentError(absl::StrCat(
        "haptic_accuracy must be in [0, 1) and thompson_v positive, got ",
        config.haptic_accuracy, " and ", config.thompson_v));
  }
  const auto stories = haptic::ParseTraceStories(config.trace_story);
  if (!stories.ok() || stories->size() != 1) {
    return absl::InvalidArgumentError(
        absl::StrCat("trace_story must be one of ", haptic::TraceStoryNames(),
                     "; got \"", config.trace_story, "\""));
  }
  if (config.lambda_c < 0.0 || !(config.rho_c > 0.0)) {
    return absl::InvalidArgumentError(
        absl::StrCat("lambda_c must be >= 0 and rho_c positive, got ",
                     config.lambda_c, " and ", config.rho_c));
  }
  if (config.force_limit &&
      (config.trace_story != "world" || config.haptic_accuracy > 0.0)) {
    return absl::InvalidArgumentError(absl::StrCat(
        "force_limit needs the world's traces (trace_story world, got \"",
        config.trace_story, "\") and haptic_accuracy 0 (got ",
        config.haptic_accuracy, ")"));
  }
  return absl::OkStatus();
}

double ResolvedLambdaC(const SimMealsConfig& config) {
  const double msn =
      config.context_msn > 0.0
          ? config.context_msn
          : perception::DefaultFeaturizer().context_mean_squared_norm();
  return domain::NewUserContextRidge(config.lambda_c, config.rho_c, msn);
}

absl::StatusOr<std::vector<const sim::FoodType*>> MealFoods(
    const SimMealsConfig& config) {
  if (config.food_names.empty()) return sim::UnseenFoods();
  std::vector<const sim::FoodType*> foods;
  for (const std::string& name : config.food_names) {
    const sim::FoodType* food = sim::FindFood(name);
    if (food == nullptr) {
      return absl::InvalidArgumentError(
          absl::StrCat("food_names: unknown food \"", name, "\""));
    }
    foods.push_back(food);
  }
  return foods;
}

int ResolvedPlatesPerTrial(const SimMealsConfig& config) {
  return config.plates_per_trial > 0 ? config.plates_per_trial
                                     : config.attempts_per_food;
}

SimMealsSimulator::SimMealsSimulator(
    std::unique_ptr<haptic::HapticClassifier> classifier,
    std::unique_ptr<perception::Featurizer> featurizer)
    : classifier_(std::move(classifier)),
      featurizer_(featurizer != nullptr
                      ? std::move(featurizer)
                      : std::make_unique<perception::DefaultFeaturizer>()) {}

absl::StatusOr<std::unique_ptr<SimMealsSimulator>> SimMealsSimulator::Create(
    const std::string& onnx_path, const std::string& spanet_model) {
  std::unique_ptr<perception::Featurizer> featurizer;
  if (!spanet_model.empty()) {
    ASSIGN_OR_RETURN(featurizer,
                     perception::SpanetFeaturizer::Load(spanet_model));
  }
  ASSIGN_OR_RETURN(
      std::unique_ptr<haptic::HapticNet> net,
      onnx_path.empty()
          ? haptic::HapticNet::FromOnnxBytes(haptic::DefaultHapticNetOnnx(),
                                             haptic::kDefaultHapticNetSource)
          : haptic::HapticNet::FromOnnxFile(onnx_path));
  const haptic::HapticPipelineOptions options;  // the service's defaults
  RETURN_IF_ERROR(haptic::ValidatePipelineOptions(options));
  std::unique_ptr<haptic::FamiliarityModel> familiarity;
  if (onnx_path.empty()) {
    ASSIGN_OR_RETURN(haptic::FamiliarityModel model,
                     haptic::FamiliarityModel::FromText(
                         haptic::DefaultHapticFamiliarity(),
                         haptic::kDefaultHapticFamiliaritySource));
    familiarity = std::make_unique<haptic::FamiliarityModel>(std::move(model));
  } else {
    absl::StatusOr<haptic::FamiliarityModel> model =
        haptic::FamiliarityModel::FromFile(
            haptic::FamiliarityPathFor(onnx_path));
    if (model.ok()) {
      familiarity =
          std::make_unique<haptic::FamiliarityModel>(std::move(model).value());
    } else if (!absl::IsNotFound(model.status())) {
      return model.status();
    }
  }
  return std::make_unique<SimMealsSimulator>(
      std::make_unique<haptic::HapticClassifier>(std::move(net), options,
                                                 std::move(familiarity)),
      std::move(featurizer));
}

absl::StatusOr<SimMealWorld> SimMealsSimulator::DrawWorld(
    const SimMealsConfig& config, uint64_t seed) const {
  RETURN_IF_ERROR(ValidateSimMealsConfig(config));
  ASSIGN_OR_RETURN(const std::vector<const sim::FoodType*> foods,
                   MealFoods(config));
  const int num_foods = static_cast<int>(foods.size());
  const int plates_per_trial = ResolvedPlatesPerTrial(config);

  // Plates: render each once and featurize every item's ground-truth box;
  // each food's force profile is drawn per item, as the simulated robot
  // does (the same item feels the same on every attempt).
  std::mt19937_64 plate_rng(random::MixSeed(seed, kPlateStream));
  std::mt19937_64 profile_rng(random::MixSeed(seed, kProfileStream));
  // [plate][food]
  std::vector<std::vector<std::vector<double>>> contexts(
      plates_per_trial, std::vector<std::vector<double>>(num_foods));
  std::vector<std::vector<sim::ForceProfile>> profiles(plates_per_trial);
  SimMealWorld world;
  world.foods = foods;
  for (int plate = 0; plate < plates_per_trial; ++plate) {
    // RandomPlate leaves an item off a plate it cannot fit on, and an item
    // can end up with no visible pixel; such plates are drawn again (from
    // the same stream) so that every food is on every plate.
    for (int draw = 0;; ++draw) {
      if (draw == kMaxPlateDraws) {
        return absl::InternalError(
            absl::StrCat("no plate with all ", num_foods, " foods visible in ",
                         kMaxPlateDraws, " draws (plate ", plate, ")"));
      }
      const sim::PlateScene scene =
          sim::RandomPlate(foods, config.allow_touching, plate_rng);
      ASSIGN_OR_RETURN(
          std::vector<std::vector<double>> item_contexts,
          FeaturizeScene(scene,
                         random::MixSeed(seed, kRenderNoiseStream + plate),
                         *featurizer_));
      std::vector<std::vector<double>> plate_contexts(num_foods);
      for (size_t i = 0; i < scene.items.size(); ++i) {
        const int food = FoodIndex(foods, scene.items[i].food);
        if (food >= 0) plate_contexts[food] = std::move(item_contexts[i]);
      }
      if (std::all_of(plate_contexts.begin(), plate_contexts.end(),
                      [](const auto& c) { return !c.empty(); })) {
        contexts[plate] = std::move(plate_contexts);
        break;
      }
      ++world.plate_redraws;
    }
    for (int food = 0; food < num_foods; ++food) {
      profiles[plate].push_back(
          sim::ForceProfile::Sample(foods[food]->category, profile_rng));
    }
  }

  // The meal's order of foods.
  std::mt19937_64 order_rng(random::MixSeed(seed, kOrderStream));
  std::vector<int> order;
  if (config.order == MealOrder::kShuffled) {
    for (int food = 0; food < num_foods; ++food) {
      order.insert(order.end(), config.attempts_per_food, food);
    }
    Shuffle(order, order_rng);
  } else {
    std::vector<int> food_order(num_foods);
    for (int food = 0; food < num_foods; ++food) food_order[food] = food;
    Shuffle(food_order, order_rng);
    for (int food : food_order) {
      order.insert(order.end(), config.attempts_per_food, food);
    }
  }

  // Attempts: a fresh trace of the item per attempt (sensor noise and bias
  // differ), classified by the HapticService's pipeline; one outcome coin.
  std::mt19937_64 trace_rng(random::MixSeed(seed, kTraceStream));
  std::mt19937_64 coin_rng(random::MixSeed(seed, kCoinStream));
  std::mt19937_64 haptic_error_rng(random::MixSeed(seed, kHapticErrorStream));
  std::vector<int> attempts_so_far(num_foods, 0);
  world.attempts.reserve(order.size());
  const sim::TraceOptions trace_options;  // 1 kHz, as the simulated Net F/T
  // An independent story's draw, or nullptr for the world's own traces
  // (the config was validated above, so the name parses).
  const haptic::StoryTraceFunction story = haptic::StoryTraceDraw(
      haptic::ParseTraceStories(config.trace_story)->front());
  // The actions' distinct force limits, for force_limit.
  std::vector<double> limits_n;
  for (const domain::SkeweringAction& action : domain::kSkeweringActions) {
    if (std::find(limits_n.begin(), limits_n.end(), action.max_force_n) ==
        limits_n.end()) {
      limits_n.push_back(action.max_force_n);
    }
  }
  for (int food : order) {
    SimAttempt attempt;
    attempt.food = food;
    attempt.plate = attempts_so_far[food]++ % plates_per_trial;
    attempt.context = contexts[attempt.plate][food];
    absl::StatusOr<haptic::HapticClassification> classified;
    if (story == nullptr) {
      if (config.force_limit) {
        // Each limit's trace from the same generator state as the whole
        // trace, so they share the bias; the whole trace's draw then moves
        // the generator on as without limits.
        for (double limit_n : limits_n) {
          std::mt19937_64 limit_rng = trace_rng;
          sim::TraceOptions limited_options = trace_options;
          limited_options.stop.limit_n = limit_n;
          SimAttempt::Limited limited;
          limited.limit_n = limit_n;
          const std::vector<sim::TimedWrench> trace =
              sim::SimulateTrace(profiles[attempt.plate][food], limited_options,
                                 limit_rng, &limited.reached);
          if (limited.reached) {
            absl::StatusOr<haptic::HapticClassification> cut =
                classifier_->Classify(trace);
            if (!cut.ok()) {
              return absl::InternalError(absl::StrCat(
                  "classifying the ", limit_n, " N limit's trace of attempt ",
                  world.attempts.size(), " (", foods[food]->name,
                  "): ", cut.status().ToString()));
            }
            limited.haptic = *cut;
          }
          attempt.limited.push_back(std::move(limited));
        }
      }
      classified = classifier_->Classify(sim::SimulateTrace(
          profiles[attempt.plate][food], trace_options, trace_rng));
    } else {
      const int draws = config.keep_no_contact ? 1 : kMaxStoryDraws;
      for (int draw = 0; draw < draws; ++draw) {
        classified =
            classifier_->Classify(story(foods[food]->category, trace_rng));
        if (classified.ok() ||
            !absl::IsFailedPrecondition(classified.status())) {
          break;
        }
        if (draw + 1 < draws) ++world.story_redraws;
      }
    }
    if (config.keep_no_contact &&
        absl::IsFailedPrecondition(classified.status())) {
      attempt.contact = false;
      ++world.no_contact;
    } else if (!classified.ok()) {
      return absl::InternalError(absl::StrCat(
          "classifying the trace of attempt ", world.attempts.size(), " (",
          foods[food]->name, "): ", classified.status().ToString()));
    }
    if (attempt.contact) attempt.haptic = *classified;
    for (SimAttempt::Limited& limited : attempt.limited) {
      if (!limited.reached) limited.haptic = attempt.haptic;
    }
    if (attempt.contact && config.haptic_accuracy > 0.0 &&
        random::Uniform01(haptic_error_rng) >= config.haptic_accuracy) {
      // A confident wrong answer: the top probability moves to another
      // class, drawn uniformly.
      const int top = static_cast<int>(attempt.haptic.category);
      int wrong =
          random::UniformIndex(haptic_error_rng, haptic::kHapticClasses - 1);
      if (wrong >= top) ++wrong;
      std::swap(attempt.haptic.probabilities[top],
                attempt.haptic.probabilities[wrong]);
      std::swap(attempt.haptic.log_probabilities[top],
                attempt.haptic.log_probabilities[wrong]);
      attempt.haptic.category = static_cast<haptic::HapticClass>(wrong);
    }
    attempt.coin = random::Uniform01(coin_rng);
    world.attempts.push_back(std::move(attempt));
  }
  return world;
}

bandit::BanditConfig SimUserConfig(const SimMealsConfig& config,
                                   bandit::Learner learner,
                                   bandit::Strategy strategy, int context_dim,
                                   uint64_t seed,
                                   const bandit::PopulationPrior& prior) {
  bandit::BanditConfig bandit_config;
  bandit_config.learner = learner;
  bandit_config.strategy = strategy;
  bandit_config.alpha = strategy == bandit::Strategy::kThompson
                            ? config.thompson_v
                            : config.alpha;
  bandit_config.lambda_c = ResolvedLambdaC(config);
  bandit_config.lambda_p = config.lambda_p;
  bandit_config.phi_radius = config.phi_radius;
  bandit_config.context_dim = context_dim;
  bandit_config.posthoc_dim = haptic::kHapticClasses;
  bandit_config.seed = seed;
  bandit_config.prior = prior;
  return bandit_config;
}

absl::StatusOr<SimMealRun> PlaySimMeal(const SimMealWorld& world,
                                       HapticContext kind, uint64_t seed,
                                       int64_t first_round,
                                       bandit::LearnerModel& model,
                                       domain::UnfamiliarPosthoc unfamiliar,
                                       domain::UnfamiliarPosthoc limit_rule,
                                       bool impute_missing) {
  const auto* polinucb =
      impute_missing ? dynamic_cast<const bandit::PoLinUcbModel*>(&model)
                     : nullptr;
  const bandit::BanditConfig& bandit_config = model.config();
  SimMealRun run;
  double failures = 0.0;
  for (size_t t = 0; t < world.attempts.size(); ++t) {
    const SimAttempt& attempt = world.attempts[t];
    RETURN_IF_ERROR(model.ValidateContext(attempt.context));
    std::mt19937_64 rng =
        bandit::SelectRng(seed, first_round + static_cast<int64_t>(t));
    const bandit::Choice choice = bandit::ChooseAction(
        bandit_config, model.Estimate(attempt.context), rng);
    ASSIGN_OR_RETURN(
        const double p,
        sim::SuccessProbability(*world.foods[attempt.food],
                                bandit_config.action_names[choice.action]));
    const bool failed = !(attempt.coin < p);
    bandit::Round round;
    round.context = attempt.context;
    round.action = choice.action;
    round.loss = failed ? 1.0 : 0.0;
    const domain::SkeweringAction* action =
        domain::FindSkeweringAction(bandit_config.action_names[choice.action]);
    const double limit_n = action == nullptr ? 0.0 : action->max_force_n;
    bool halted = false;
    for (const SimAttempt::Limited& limited : attempt.limited) {
      halted = halted || (limited.limit_n == limit_n && limited.reached);
    }
    run.limit_reached += halted;
    if (bandit::UsesPosthoc(bandit_config.learner)) {
      const bool missing =
          !attempt.contact ||
          (halted && limit_rule == domain::UnfamiliarPosthoc::kZero);
      if (polinucb != nullptr && missing) {
        const Eigen::VectorXd predicted =
            polinucb->PredictPosthoc(attempt.context);
        round.posthoc.assign(predicted.data(),
                             predicted.data() + predicted.size());
      } else {
        round.posthoc =
            ActionPosthoc(attempt, limit_n, kind, unfamiliar, limit_rule);
      }
    }
    RETURN_IF_ERROR(model.ValidateRound(round));
    model.Update(round);
    failures += round.loss;
    run.actions.push_back(choice.action);
    run.failed.push_back(failed ? 1 : 0);
    run.cumulative_failures.push_back(failures);
  }
  return run;
}

absl::StatusOr<SimMealRun> RunSimMealTrial(const SimMealsConfig& config,
                                           const SimMealWorld& world,
                                           bandit::Learner learner,
                                           HapticContext kind, uint64_t seed,
                                           bandit::Strategy strategy) {
  if (world.attempts.empty()) {
    return absl::InvalidArgumentError("the world has no attempts");
  }
  ASSIGN_OR_RETURN(
      std::unique_ptr<bandit::LearnerModel> model,
      bandit::CreateModel(SimUserConfig(
          config, learner, strategy,
          static_cast<int>(world.attempts.front().context.size()), seed)));
  return PlaySimMeal(world, kind, seed, /*first_round=*/0, *model,
                     config.unfamiliar_posthoc, config.limit_reached_posthoc,
                     config.impute_missing_posthoc);
}

std::vector<double> OracleExpectedFailures(const SimMealWorld& world) {
  const std::vector<const sim::FoodType*>& foods = world.foods;
  std::vector<double> out;
  double sum = 0.0;
  for (const SimAttempt& attempt : world.attempts) {
    double best = 0.0;
    for (const sim::ActionSuccess& entry : foods[attempt.food]->success) {
      best = std::max(best, entry.probability);
    }
    sum += 1.0 - best;
    out.push_back(sum);
  }
  return out;
}

std::vector<double> UniformExpectedFailures(const SimMealWorld& world) {
  const std::vector<const sim::FoodType*>& foods = world.foods;
  std::vector<double> out;
  double sum = 0.0;
  for (const SimAttempt& attempt : world.attempts) {
    for (const sim::ActionSuccess& entry : foods[attempt.food]->success) {
      sum += (1.0 - entry.probability) / sim::kNumActions;
    }
    out.push_back(sum);
  }
  return out;
}

}  // namespace bitewise::experiments
