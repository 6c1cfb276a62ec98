// Smoke and property tests of the simulated-meals experiment on tiny meals:
// the world is what the experiment says it is (every food the right number
// of times, one crop per item, traces classified), runs are reproducible
// from the seed and paired across learners, and the failure counts follow
// the outcome draws; the actions' force limits cut the traces they should.
#include "experiments/sim_meals.h"

#include <cmath>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "services/domain/skewering_actions.h"
#include "services/perception/default_featurizer.h"
#include "services/sim/food_catalog.h"

namespace bitewise::experiments {
namespace {

class SimMealsTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    auto simulator = SimMealsSimulator::Create("");
    ASSERT_TRUE(simulator.ok()) << simulator.status();
    simulator_ = simulator->release();
  }
  static void TearDownTestSuite() {
    delete simulator_;
    simulator_ = nullptr;
  }

  static SimMealsConfig TinyConfig() {
    SimMealsConfig config;
    config.attempts_per_food = 3;
    config.plates_per_trial = 2;
    return config;
  }

  static SimMealsSimulator* simulator_;
};

SimMealsSimulator* SimMealsTest::simulator_ = nullptr;

TEST_F(SimMealsTest, WorldVisitsEveryFoodWithOneCropPerItem) {
  const SimMealsConfig config = TinyConfig();
  auto world = simulator_->DrawWorld(config, 11);
  ASSERT_TRUE(world.ok()) << world.status();
  const auto foods = sim::UnseenFoods();
  ASSERT_EQ(world->attempts.size(), foods.size() * config.attempts_per_food);
  std::vector<int> per_food(foods.size(), 0);
  int haptic_correct = 0;
  for (const SimAttempt& a : world->attempts) {
    ASSERT_GE(a.food, 0);
    ASSERT_LT(a.food, static_cast<int>(foods.size()));
    // The a-th attempt on a food lies on plate a mod plates_per_trial.
    EXPECT_EQ(a.plate, per_food[a.food] % config.plates_per_trial);
    ++per_food[a.food];
    ASSERT_EQ(a.context.size(), 64u);
    for (double v : a.context) ASSERT_TRUE(std::isfinite(v));
    EXPECT_EQ(a.context[63], 1.0);  // the featurizer's intercept
    EXPECT_GE(a.coin, 0.0);
    EXPECT_LT(a.coin, 1.0);
    double total = 0.0;
    for (double p : a.haptic.probabilities) total += p;
    EXPECT_NEAR(total, 1.0, 1e-9);
    haptic_correct += static_cast<int>(a.haptic.category) ==
                      static_cast<int>(foods[a.food]->category);
  }
  for (int n : per_food) EXPECT_EQ(n, config.attempts_per_food);
  // HapticNet is about 99.8% accurate on these traces (docs/haptic.md).
  EXPECT_GE(haptic_correct, static_cast<int>(world->attempts.size()) - 2);

  // The same item gives the same crop; the other plate's item another one.
  for (const SimAttempt& a : world->attempts) {
    for (const SimAttempt& b : world->attempts) {
      if (a.food != b.food) continue;
      if (a.plate == b.plate) {
        EXPECT_EQ(a.context, b.context);
      } else {
        EXPECT_NE(a.context, b.context);
      }
    }
  }
}

TEST_F(SimMealsTest, BlockedOrderKeepsEachFoodsAttemptsTogether) {
  SimMealsConfig config = TinyConfig();
  config.order = MealOrder::kBlocked;
  auto world = simulator_->DrawWorld(config, 12);
  ASSERT_TRUE(world.ok()) << world.status();
  for (size_t t = 0; t < world->attempts.size(); ++t) {
    EXPECT_EQ(world->attempts[t].food,
              world->attempts[t - t % config.attempts_per_food].food);
  }
}

TEST_F(SimMealsTest, SameSeedGivesTheSameWorldAndRuns) {
  const SimMealsConfig config = TinyConfig();
  auto a = simulator_->DrawWorld(config, 13);
  auto b = simulator_->DrawWorld(config, 13);
  auto other = simulator_->DrawWorld(config, 14);
  ASSERT_TRUE(a.ok() && b.ok() && other.ok());
  ASSERT_EQ(a->attempts.size(), b->attempts.size());
  bool differs = false;
  for (size_t t = 0; t < a->attempts.size(); ++t) {
    EXPECT_EQ(a->attempts[t].food, b->attempts[t].food);
    EXPECT_EQ(a->attempts[t].context, b->attempts[t].context);
    EXPECT_EQ(a->attempts[t].coin, b->attempts[t].coin);
    EXPECT_EQ(a->attempts[t].haptic.log_probabilities,
              b->attempts[t].haptic.log_probabilities);
    differs |= a->attempts[t].coin != other->attempts[t].coin;
  }
  EXPECT_TRUE(differs);

  for (bandit::Learner learner :
       {bandit::Learner::kContextOnly, bandit::Learner::kPostHoc}) {
    auto first = RunSimMealTrial(config, *a, learner,
                                 HapticContext::kLogProbabilities, 13);
    auto second = RunSimMealTrial(config, *b, learner,
                                  HapticContext::kLogProbabilities, 13);
    ASSERT_TRUE(first.ok() && second.ok());
    EXPECT_EQ(first->actions, second->actions);
    EXPECT_EQ(first->cumulative_failures, second->cumulative_failures);
  }
}

TEST_F(SimMealsTest, FailuresFollowTheSharedOutcomeDraws) {
  const SimMealsConfig config = TinyConfig();
  auto world = simulator_->DrawWorld(config, 15);
  ASSERT_TRUE(world.ok()) << world.status();
  const auto foods = sim::UnseenFoods();
  std::vector<std::vector<int>> all_actions;
  for (auto [learner, kind] :
       {std::pair{bandit::Learner::kContextOnly, HapticContext::kOneHot},
        std::pair{bandit::Learner::kPostHoc, HapticContext::kLogProbabilities},
        std::pair{bandit::Learner::kPostHoc, HapticContext::kProbabilities},
        std::pair{bandit::Learner::kPostHoc, HapticContext::kOneHot}}) {
    auto run = RunSimMealTrial(config, *world, learner, kind, 15);
    ASSERT_TRUE(run.ok()) << run.status();
    ASSERT_EQ(run->actions.size(), world->attempts.size());
    double previous = 0.0;
    for (size_t t = 0; t < run->actions.size(); ++t) {
      const int action = run->actions[t];
      ASSERT_GE(action, 0);
      ASSERT_LT(action, sim::kNumActions);
      const SimAttempt& attempt = world->attempts[t];
      // The action is an index into the default action names (the domain's).
      const absl::StatusOr<double> p = sim::SuccessProbability(
          *foods[attempt.food], domain::kSkeweringActions[action].name);
      ASSERT_TRUE(p.ok()) << p.status();
      EXPECT_EQ(run->failed[t], attempt.coin < *p ? 0 : 1);
      EXPECT_EQ(run->cumulative_failures[t], previous + run->failed[t]);
      EXPECT_GE(run->cumulative_failures[t], previous);  // nondecreasing
      previous = run->cumulative_failures[t];
    }
    // Untrained LinUCB ties everywhere and plays action 0 first.
    EXPECT_EQ(run->actions.front(), 0);
    all_actions.push_back(run->actions);
  }
  // The learners do learn something different from each other.
  bool any_difference = false;
  for (const auto& actions : all_actions) {
    any_difference |= actions != all_actions.front();
  }
  EXPECT_TRUE(any_difference);
}

TEST_F(SimMealsTest, OracleAndUniformBaselines) {
  const SimMealsConfig config = TinyConfig();
  auto world = simulator_->DrawWorld(config, 16);
  ASSERT_TRUE(world.ok()) << world.status();
  const std::vector<double> oracle = OracleExpectedFailures(*world);
  const std::vector<double> uniform = UniformExpectedFailures(*world);
  ASSERT_EQ(oracle.size(), world->attempts.size());
  // Every unseen food's best action succeeds with probability 0.9 or 0.85
  // and its average action well below that (food_catalog.cc).
  EXPECT_GT(oracle.back(), 0.10 * oracle.size() - 1e-9);
  EXPECT_LT(oracle.back(), 0.15 * oracle.size() + 1e-9);
  EXPECT_GT(uniform.back(), 2 * oracle.back());
}

TEST(HapticContextTest, Forms) {
  haptic::HapticClassification c;
  c.probabilities = {0.1, 0.2, 0.6, 0.1};
  for (int k = 0; k < 4; ++k)
    c.log_probabilities[k] = std::log(c.probabilities[k]);
  c.category = haptic::HapticClass::kSoft;
  EXPECT_EQ(PosthocContext(c, HapticContext::kOneHot),
            (std::vector<double>{0, 0, 1, 0}));
  EXPECT_EQ(PosthocContext(c, HapticContext::kProbabilities),
            (std::vector<double>{0.1, 0.2, 0.6, 0.1}));
  EXPECT_DOUBLE_EQ(PosthocContext(c, HapticContext::kLogProbabilities)[2],
                   std::log(0.6));
  EXPECT_STREQ(HapticContextName(HapticContext::kLogProbabilities), "logprob");
}

// An attempt the familiarity model calls unfamiliar gets what the rule
// says, in every form; a familiar one (or one with no score) keeps
// HapticNet's answer.
TEST(HapticContextTest, UnfamiliarAttemptsFollowTheRule) {
  haptic::HapticClassification c;
  c.probabilities = {0.1, 0.2, 0.6, 0.1};
  c.log_probabilities = {std::log(0.1), std::log(0.2), std::log(0.6),
                         std::log(0.1)};
  c.category = haptic::HapticClass::kSoft;
  using domain::UnfamiliarPosthoc;
  for (HapticContext kind :
       {HapticContext::kLogProbabilities, HapticContext::kProbabilities,
        HapticContext::kOneHot}) {
    const std::vector<double> as_is = PosthocContext(c, kind);
    // No score: nothing is unfamiliar.
    EXPECT_EQ(PosthocContext(c, kind, UnfamiliarPosthoc::kUniform), as_is);
    c.has_familiarity = true;
    c.familiarity.unfamiliar = false;
    EXPECT_EQ(PosthocContext(c, kind, UnfamiliarPosthoc::kUniform), as_is);
    c.familiarity.unfamiliar = true;
    EXPECT_EQ(PosthocContext(c, kind, UnfamiliarPosthoc::kAsIs), as_is);
    const double flat =
        kind == HapticContext::kLogProbabilities ? std::log(0.25) : 0.25;
    EXPECT_EQ(PosthocContext(c, kind, UnfamiliarPosthoc::kUniform),
              std::vector<double>(4, flat));
    EXPECT_EQ(PosthocContext(c, kind, UnfamiliarPosthoc::kZero),
              std::vector<double>(4, 0.0));
    c.has_familiarity = false;
  }
}

// The simulator scores every attempt with the shipped familiarity model,
// as the service does.
TEST_F(SimMealsTest, AttemptsCarryTheShippedFamiliarityScore) {
  auto world = simulator_->DrawWorld(TinyConfig(), 11);
  ASSERT_TRUE(world.ok()) << world.status();
  for (const SimAttempt& a : world->attempts) {
    EXPECT_TRUE(a.haptic.has_familiarity);
    EXPECT_GE(a.haptic.familiarity.familiarity, 0.0);
    EXPECT_LE(a.haptic.familiarity.familiarity, 1.0);
  }
  EXPECT_EQ(SimMealsConfig().unfamiliar_posthoc,
            domain::kDefaultUnfamiliarPosthoc);
}

// Every independent trace story can stand in for the world's traces; a
// name that is not one story is refused, naming the choices.
TEST_F(SimMealsTest, DrawsAttemptsFromEveryTraceStory) {
  for (const char* story : {"piecewise", "mechanics", "compliant", "puncture",
                            "poroelastic", "lattice"}) {
    SimMealsConfig config = TinyConfig();
    config.trace_story = story;
    ASSERT_TRUE(ValidateSimMealsConfig(config).ok()) << story;
    auto world = simulator_->DrawWorld(config, 11);
    ASSERT_TRUE(world.ok()) << story << ": " << world.status();
    EXPECT_EQ(world->attempts.size(),
              sim::UnseenFoods().size() * config.attempts_per_food);
  }
  // Another story draws other traces for the same attempts.
  SimMealsConfig config = TinyConfig();
  auto world = simulator_->DrawWorld(config, 11);
  config.trace_story = "puncture";
  auto puncture = simulator_->DrawWorld(config, 11);
  ASSERT_TRUE(world.ok() && puncture.ok());
  int differ = 0;
  for (size_t i = 0; i < world->attempts.size(); ++i) {
    differ += world->attempts[i].haptic.probabilities !=
              puncture->attempts[i].haptic.probabilities;
  }
  EXPECT_GT(differ, 0);
  for (const char* bad : {"recorded", "world,puncture", ""}) {
    config.trace_story = bad;
    const absl::Status status = ValidateSimMealsConfig(config);
    EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument) << bad;
    EXPECT_NE(status.message().find("puncture"), std::string::npos)
        << status.message();
  }
}

// A contact-less story trace, kept as the product meets it: the attempt has
// no classification, the post hoc learners get p = 0, and every learner
// still plays it. Drawn again otherwise, every attempt has contact.
TEST_F(SimMealsTest, KeepsContactlessAttemptsWithNoPosthocContext) {
  SimMealsConfig config = TinyConfig();
  config.trace_story = "poroelastic";  // most soft items stay under 1 N
  auto redrawn = simulator_->DrawWorld(config, 11);
  ASSERT_TRUE(redrawn.ok()) << redrawn.status();
  EXPECT_EQ(redrawn->no_contact, 0);
  EXPECT_GT(redrawn->story_redraws, 0);
  for (const SimAttempt& a : redrawn->attempts) EXPECT_TRUE(a.contact);

  config.keep_no_contact = true;
  auto kept = simulator_->DrawWorld(config, 11);
  ASSERT_TRUE(kept.ok()) << kept.status();
  ASSERT_EQ(kept->attempts.size(), redrawn->attempts.size());
  EXPECT_EQ(kept->story_redraws, 0);
  int contactless = 0;
  for (const SimAttempt& a : kept->attempts) {
    if (a.contact) continue;
    ++contactless;
    EXPECT_THAT(a.haptic.probabilities, ::testing::Each(0.0));
    EXPECT_FALSE(a.haptic.has_familiarity);
    for (HapticContext kind :
         {HapticContext::kLogProbabilities, HapticContext::kProbabilities,
          HapticContext::kOneHot}) {
      EXPECT_EQ(AttemptPosthoc(a, kind), std::vector<double>(4, 0.0));
    }
  }
  EXPECT_GT(contactless, 0);
  EXPECT_EQ(contactless, kept->no_contact);
  auto run = RunSimMealTrial(config, *kept, bandit::Learner::kPostHoc,
                             HapticContext::kLogProbabilities, 11);
  ASSERT_TRUE(run.ok()) << run.status();
  EXPECT_EQ(run->failed.size(), kept->attempts.size());
}

// With the actions' force limits, a hard item's trace is cut at TA's 10 N
// (the world's hard items push back 10-18 N) and never at TV's 20 N or VS's
// 25 N; no other category reaches 10 N. The whole traces, and so every
// answer without limits, are those of the same world drawn without them. A
// learner that chose TA gets the cut trace's answer, or p = 0 under the zero
// rule; one that chose VS gets the whole trace's.
TEST_F(SimMealsTest, ForceLimitsCutHardTracesAtTaLimitOnly) {
  SimMealsConfig config = TinyConfig();
  auto whole = simulator_->DrawWorld(config, 5);
  ASSERT_TRUE(whole.ok()) << whole.status();
  config.force_limit = true;
  auto limited = simulator_->DrawWorld(config, 5);
  ASSERT_TRUE(limited.ok()) << limited.status();
  ASSERT_EQ(limited->attempts.size(), whole->attempts.size());
  int cut = 0;
  for (size_t t = 0; t < limited->attempts.size(); ++t) {
    const SimAttempt& a = limited->attempts[t];
    EXPECT_EQ(a.haptic.probabilities, whole->attempts[t].haptic.probabilities);
    EXPECT_TRUE(whole->attempts[t].limited.empty());
    ASSERT_EQ(a.limited.size(), 3u);  // 25, 20 and 10 N
    const bool hard =
        limited->foods[a.food]->category == sim::HapticCategory::kHard;
    for (const SimAttempt::Limited& l : a.limited) {
      EXPECT_EQ(l.reached, hard && l.limit_n == 10.0)
          << limited->foods[a.food]->name << " " << l.limit_n;
      if (!l.reached) {
        EXPECT_EQ(l.haptic.probabilities, a.haptic.probabilities);
        continue;
      }
      ++cut;
      const auto kind = HapticContext::kLogProbabilities;
      const auto as_is = domain::UnfamiliarPosthoc::kAsIs;
      EXPECT_EQ(
          ActionPosthoc(a, 10.0, kind, as_is, domain::UnfamiliarPosthoc::kZero),
          std::vector<double>(4, 0.0));
      EXPECT_EQ(
          ActionPosthoc(a, 10.0, kind, as_is, domain::UnfamiliarPosthoc::kAsIs),
          PosthocContext(l.haptic, kind));
      EXPECT_NE(PosthocContext(l.haptic, kind), AttemptPosthoc(a, kind));
      EXPECT_EQ(
          ActionPosthoc(a, 25.0, kind, as_is, domain::UnfamiliarPosthoc::kZero),
          AttemptPosthoc(a, kind));
    }
  }
  EXPECT_EQ(cut, 2 * config.attempts_per_food);  // carrot and celery
  // Learners count the cut attempts they chose.
  auto run = RunSimMealTrial(config, *limited, bandit::Learner::kPoLinUcb,
                             HapticContext::kLogProbabilities, 5);
  ASSERT_TRUE(run.ok()) << run.status();
  int chose_ta_on_hard = 0;
  for (size_t t = 0; t < run->actions.size(); ++t) {
    const std::string name = domain::kSkeweringActions[run->actions[t]].name;
    chose_ta_on_hard += (name == "TA0" || name == "TA90") &&
                        limited->foods[limited->attempts[t].food]->category ==
                            sim::HapticCategory::kHard;
  }
  EXPECT_EQ(run->limit_reached, chose_ta_on_hard);

  config.trace_story = "mechanics";
  EXPECT_EQ(ValidateSimMealsConfig(config).code(),
            absl::StatusCode::kInvalidArgument);
}

// The imputation study: poLinUCB sends its own prediction where a post hoc
// context is missing. Without missing contexts the runs are the same as
// with p = 0; with contact-less attempts they part, and the first attempt
// where they do is at or after the first contact-less one.
TEST_F(SimMealsTest, ImputingMissingPosthocChangesOnlyRunsWithMissingOnes) {
  SimMealsConfig config = TinyConfig();
  auto whole = simulator_->DrawWorld(config, 3);
  ASSERT_TRUE(whole.ok()) << whole.status();
  SimMealsConfig imputing = config;
  imputing.impute_missing_posthoc = true;
  auto plain = RunSimMealTrial(config, *whole, bandit::Learner::kPoLinUcb,
                               HapticContext::kLogProbabilities, 3);
  auto imputed = RunSimMealTrial(imputing, *whole, bandit::Learner::kPoLinUcb,
                                 HapticContext::kLogProbabilities, 3);
  ASSERT_TRUE(plain.ok() && imputed.ok());
  EXPECT_EQ(plain->actions, imputed->actions);

  config.trace_story = "poroelastic";
  config.keep_no_contact = true;
  imputing.trace_story = "poroelastic";
  imputing.keep_no_contact = true;
  auto missing = simulator_->DrawWorld(config, 3);
  ASSERT_TRUE(missing.ok()) << missing.status();
  ASSERT_GT(missing->no_contact, 0);
  plain = RunSimMealTrial(config, *missing, bandit::Learner::kPoLinUcb,
                          HapticContext::kLogProbabilities, 3);
  imputed = RunSimMealTrial(imputing, *missing, bandit::Learner::kPoLinUcb,
                            HapticContext::kLogProbabilities, 3);
  ASSERT_TRUE(plain.ok() && imputed.ok());
  size_t first_missing = 0;
  while (missing->attempts[first_missing].contact) ++first_missing;
  size_t first_apart = 0;
  while (first_apart < plain->actions.size() &&
         plain->actions[first_apart] == imputed->actions[first_apart]) {
    ++first_apart;
  }
  EXPECT_LT(first_apart, plain->actions.size());
  EXPECT_GT(first_apart, first_missing);
}

TEST(SimMealsConfigTest, RejectsNonPositiveCounts) {
  SimMealsConfig config;
  config.attempts_per_food = 0;
  EXPECT_EQ(ValidateSimMealsConfig(config).code(),
            absl::StatusCode::kInvalidArgument);
  config.attempts_per_food = 1;
  config.plates_per_trial = -1;
  EXPECT_EQ(ValidateSimMealsConfig(config).code(),
            absl::StatusCode::kInvalidArgument);
  config.plates_per_trial = 0;  // one per attempt
  EXPECT_TRUE(ValidateSimMealsConfig(config).ok());
  config.attempts_per_food = 5;
  EXPECT_EQ(ResolvedPlatesPerTrial(config), 5);
  config.rho_c = 0.0;
  EXPECT_EQ(ValidateSimMealsConfig(config).code(),
            absl::StatusCode::kInvalidArgument);
}

// The shipped statistics must describe what the featurizer computes now:
// on fresh seen-food plates (seeds apart from the file's), standardised
// features are centred and E||c||^2 is near the declared value. Fails when
// the featurizer changes without bitewise-featurizer-stats being rerun.
TEST(SimMealsConfigTest, ShippedFeaturizerStatisticsMatchTheFeaturizer) {
  const perception::DefaultFeaturizer featurizer;
  std::mt19937_64 rng(424242);
  std::vector<double> mean(perception::kDefaultFeatureDim, 0.0);
  double msn = 0.0;
  int n = 0;
  for (int plate = 0; plate < 30; ++plate) {
    const sim::PlateScene scene =
        sim::RandomPlate(sim::SeenFoods(), /*allow_touching=*/false, rng);
    auto contexts = FeaturizeScene(scene, 5000 + plate, featurizer);
    ASSERT_TRUE(contexts.ok()) << contexts.status();
    for (const std::vector<double>& c : *contexts) {
      if (c.empty()) continue;
      for (size_t k = 0; k < c.size(); ++k) {
        mean[k] += c[k];
        msn += c[k] * c[k];
      }
      ++n;
    }
  }
  ASSERT_GT(n, 200);
  for (int k = 0; k < 60; ++k) EXPECT_NEAR(mean[k] / n, 0.0, 0.35) << k;
  EXPECT_NEAR(msn / n / featurizer.context_mean_squared_norm(), 1.0, 0.2);
}

TEST(SimMealsConfigTest, TheContextRidgeFollowsTheFeatureScale) {
  SimMealsConfig config;  // the shipped defaults
  const double msn =
      perception::DefaultFeaturizer().context_mean_squared_norm();
  ASSERT_GT(msn, 0.0);
  EXPECT_EQ(ResolvedLambdaC(config), msn);
  config.rho_c = 3.0;
  EXPECT_EQ(ResolvedLambdaC(config), 3.0 * msn);
  config.lambda_c = 1000.0;  // explicit: honoured exactly
  EXPECT_EQ(ResolvedLambdaC(config), 1000.0);
}

}  // namespace
}  // namespace bitewise::experiments
