#include "services/bandit/core/linucb.h"

#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "services/bandit/core/learners.h"
#include "services/bandit/core/policy.h"
#include "services/bandit/core/population_prior.h"
#include "tests/bandit/dense_reference.h"
#include "tests/bandit/reference_checks.h"
#include "tests/bandit/state_fixture.h"
#include "tests/common/near.h"

namespace bitewise::bandit {
namespace {

using testing::DenseActionModel;
using testing::DenseReference;
using testing::ExpectMatchesReference;
using testing::RandomVector;

struct Problem {
  int d;
  int q;
  int k;
  int rounds;
  Learner learner;
  bool weighted;
  int primal_threshold;  // 0: d
  bool prior = false;    // a random population prior
};

std::string Name(const ::testing::TestParamInfo<Problem>& info) {
  const Problem& p = info.param;
  return std::string(LearnerName(p.learner)) + "_d" + std::to_string(p.d) +
         "_q" + std::to_string(p.q) + "_k" + std::to_string(p.k) + "_T" +
         std::to_string(p.rounds) + (p.weighted ? "_weighted" : "") +
         (p.primal_threshold ? "_primal" + std::to_string(p.primal_threshold)
                             : "") +
         (p.prior ? "_prior" : "");
}

BanditConfig MakeConfig(const Problem& p, std::mt19937_64& rng) {
  BanditConfig config;
  config.learner = p.learner;
  config.context_dim = p.d;
  config.posthoc_dim = p.q;
  config.action_names.clear();
  for (int a = 0; a < p.k; ++a)
    config.action_names.push_back("a" + std::to_string(a));
  // Vary the hyperparameters so the test is not tuned to the defaults.
  std::uniform_real_distribution<double> u(0.0, 1.0);
  config.alpha = 0.05 + u(rng);
  config.lambda_c = 0.5 + 3.0 * u(rng);
  config.lambda_p = 0.5 + 2.0 * u(rng);
  if (p.prior) {
    PopulationPrior& prior = config.prior;
    prior.pool_version = 3;
    prior.rounds = 0.5 + 3.0 * u(rng);
    prior.context_msn = 0.2 + u(rng);
    prior.posthoc_msn = p.learner == Learner::kPostHoc ? 0.2 + u(rng) : 0.0;
    for (int a = 0; a < p.k; ++a) {
      std::vector<double> theta0(p.d), phi0(p.q);
      for (double& v : theta0) v = u(rng) - 0.5;
      for (double& v : phi0) v = u(rng) - 0.5;
      prior.theta0.push_back(theta0);
      if (p.learner == Learner::kPostHoc) prior.phi0.push_back(phi0);
    }
  }
  return config;
}

class LinUcbReferenceTest : public ::testing::TestWithParam<Problem> {};

TEST_P(LinUcbReferenceTest, MatchesDenseReferenceThroughout) {
  const Problem& p = GetParam();
  std::mt19937_64 rng(1234 + p.d * 7 + p.rounds);
  const BanditConfig config = MakeConfig(p, rng);
  absl::StatusOr<LinUcbModel> created =
      LinUcbModel::Create(config, p.primal_threshold);
  ASSERT_TRUE(created.ok()) << created.status();
  LinUcbModel model = std::move(created).value();

  // Losses follow a hidden linear map of the post hoc context, as in the
  // paper's synthetic experiment, so the post hoc model has signal.
  const std::vector<double> hidden = RandomVector(p.q * p.k, rng);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<Round> rounds;
  const int checkpoints[] = {0, 1, 2, p.rounds / 3, p.rounds - 1};
  for (int t = 0; t < p.rounds; ++t) {
    Round round;
    round.context = RandomVector(p.d, rng);
    const std::vector<ActionEstimate> est = model.Estimate(round.context);
    std::vector<double> lcb;
    for (const ActionEstimate& e : est) lcb.push_back(e.lcb);
    // Mix LinUCB choices with random ones so every action gets data.
    round.action =
        u(rng) < 0.5 ? ArgMin(lcb) : static_cast<int>(u(rng) * p.k) % p.k;
    round.posthoc.assign(round.context.begin(), round.context.begin() + p.q);
    double mean = 0.0;
    for (int j = 0; j < p.q; ++j)
      mean += hidden[round.action * p.q + j] * round.posthoc[j];
    round.loss = u(rng) < mean / p.q ? 1.0 : 0.0;
    round.weight = p.weighted ? 1.0 + 5.0 * u(rng) : 1.0;
    ASSERT_TRUE(model.ValidateRound(round).ok());
    model.Update(round);
    rounds.push_back(round);
    for (int check : checkpoints) {
      if (t == check) {
        ExpectMatchesReference(model, rounds, RandomVector(p.d, rng),
                               "after round " + std::to_string(t));
      }
    }
  }
  // A batch rebuild from the log equals the incremental model, up to the
  // rounding that the problem's conditioning allows (these random
  // hyperparameters use lambda_c of a few units, far below the default).
  absl::StatusOr<LinUcbModel> rebuilt =
      LinUcbModel::Rebuild(config, rounds, p.primal_threshold);
  ASSERT_TRUE(rebuilt.ok()) << rebuilt.status();
  const std::vector<double> probe = RandomVector(p.d, rng);
  const std::vector<ActionEstimate> a = model.Estimate(probe);
  const std::vector<ActionEstimate> b = rebuilt->Estimate(probe);
  for (int i = 0; i < p.k; ++i) {
    EXPECT_TRUE(bitewise::testing::RelNear(b[i].predicted_loss,
                                           a[i].predicted_loss, 1e-10));
    EXPECT_TRUE(bitewise::testing::RelNear(b[i].width, a[i].width, 1e-10));
    EXPECT_TRUE(
        bitewise::testing::RelNear(rebuilt->Theta(i), model.Theta(i), 1e-10));
    EXPECT_EQ(rebuilt->Count(i), model.Count(i));
    EXPECT_EQ(rebuilt->IsPrimal(i), model.IsPrimal(i));
  }
}

INSTANTIATE_TEST_SUITE_P(
    RandomProblems, LinUcbReferenceTest,
    ::testing::Values(
        Problem{8, 3, 4, 300, Learner::kPostHoc, false, 0},
        Problem{8, 3, 4, 300, Learner::kPostHoc, true, 0},
        Problem{8, 3, 4, 300, Learner::kContextOnly, false, 0},
        Problem{8, 3, 4, 300, Learner::kContextOnly, true, 0},
        Problem{32, 4, 6, 200, Learner::kPostHoc, false, 0},
        Problem{32, 4, 6, 200, Learner::kPostHoc, true, 0},
        Problem{64, 4, 6, 300, Learner::kPostHoc, false, 0},
        Problem{64, 4, 6, 300, Learner::kPostHoc, true, 0},
        Problem{64, 4, 6, 300, Learner::kContextOnly, false, 0},
        Problem{64, 4, 6, 300, Learner::kContextOnly, true, 0},
        Problem{64, 10, 10, 200, Learner::kPostHoc, false, 0},
        Problem{16, 4, 6, 200, Learner::kPostHoc, false, 5},
        Problem{64, 1, 2, 150, Learner::kPostHoc, true, 0},
        Problem{64, 4, 6, 300, Learner::kPostHoc, true, 100000},
        // Through the amortised switch to primal form (d = 64: conversion
        // from 56 rounds of an action, primal from 63), several updates in.
        Problem{64, 4, 2, 300, Learner::kPostHoc, true, 0},
        Problem{64, 4, 2, 300, Learner::kContextOnly, false, 0},
        Problem{48, 3, 3, 300, Learner::kPostHoc, false, 40},
        // With a population prior: dual, primal, both learners.
        Problem{8, 3, 4, 300, Learner::kPostHoc, true, 0, true},
        Problem{8, 3, 4, 300, Learner::kContextOnly, true, 0, true},
        Problem{32, 4, 6, 200, Learner::kPostHoc, false, 0, true},
        Problem{16, 4, 6, 200, Learner::kPostHoc, true, 5, true},
        Problem{64, 4, 6, 300, Learner::kPostHoc, false, 100000, true}),
    Name);

// With the default hyperparameters a model rebuilt from its log (what a
// restart does) equals the live model within 1e-12, in both regimes.
TEST(LinUcbTest, RebuildEqualsIncrementalWithDefaults) {
  for (const int d : {16, 256}) {
    for (const Learner learner : {Learner::kPostHoc, Learner::kContextOnly}) {
      BanditConfig config;
      config.learner = learner;
      config.context_dim = d;
      absl::StatusOr<LinUcbModel> model = LinUcbModel::Create(config);
      ASSERT_TRUE(model.ok());
      std::mt19937_64 rng(d);
      std::uniform_real_distribution<double> u(0.0, 1.0);
      std::vector<Round> rounds;
      for (int t = 0; t < 400; ++t) {
        Round round;
        round.context = RandomVector(d, rng);
        round.action = static_cast<int>(u(rng) * 6) % 6;
        round.posthoc = RandomVector(4, rng);
        round.loss = u(rng) < 0.4 ? 1.0 : 0.0;
        model->Update(round);
        rounds.push_back(round);
      }
      absl::StatusOr<LinUcbModel> rebuilt =
          LinUcbModel::Rebuild(config, rounds);
      ASSERT_TRUE(rebuilt.ok());
      const std::vector<double> probe = RandomVector(d, rng);
      const std::vector<ActionEstimate> a = model->Estimate(probe);
      const std::vector<ActionEstimate> b = rebuilt->Estimate(probe);
      for (int i = 0; i < 6; ++i) {
        EXPECT_EQ(model->IsPrimal(i), d == 16);
        EXPECT_TRUE(bitewise::testing::RelNear(b[i].predicted_loss,
                                               a[i].predicted_loss, 1e-12));
        EXPECT_TRUE(bitewise::testing::RelNear(b[i].width, a[i].width, 1e-12));
        EXPECT_TRUE(bitewise::testing::RelNear(b[i].lcb, a[i].lcb, 1e-12));
        EXPECT_TRUE(bitewise::testing::RelNear(rebuilt->Theta(i),
                                               model->Theta(i), 1e-12));
        if (learner == Learner::kPostHoc) {
          EXPECT_TRUE(bitewise::testing::RelNear(rebuilt->Phi(i), model->Phi(i),
                                                 1e-12));
        }
      }
    }
  }
}

// Three actions, q = 3: the small problems of the tests below.
BanditConfig ThreeActions(Learner learner, int d, double lambda_c) {
  BanditConfig config;
  config.learner = learner;
  config.context_dim = d;
  config.posthoc_dim = 3;
  config.lambda_c = lambda_c;
  config.action_names = {"a", "b", "c"};
  return config;
}

Round RandomRound(int d, int q, int k, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  Round round;
  round.context = RandomVector(d, rng);
  round.posthoc = RandomVector(q, rng);
  round.action = static_cast<int>(u(rng) * k) % k;
  round.loss = u(rng) < 0.4 ? 1.0 : 0.0;
  round.weight = 1.0 + u(rng);
  return round;
}

void ExpectSameEstimates(const LinUcbModel& a, const LinUcbModel& b,
                         const std::vector<double>& probe) {
  const std::vector<ActionEstimate> ea = a.Estimate(probe);
  const std::vector<ActionEstimate> eb = b.Estimate(probe);
  for (size_t i = 0; i < ea.size(); ++i) {
    EXPECT_EQ(ea[i].predicted_loss, eb[i].predicted_loss) << i;
    EXPECT_EQ(ea[i].width, eb[i].width) << i;
    EXPECT_EQ(a.IsPrimal(i), b.IsPrimal(i)) << i;
  }
}

// An Update handed its Select's products computes exactly what it would
// compute on its own, bit for bit, in both forms and through the switch;
// products from another model state or another context are ignored.
TEST(LinUcbTest, UpdateReusesSelectProductsWithoutChangingTheResult) {
  for (const Learner learner : {Learner::kPostHoc, Learner::kContextOnly}) {
    const BanditConfig config = ThreeActions(learner, 24, 2.0);
    LinUcbModel reusing = *LinUcbModel::Create(config);
    LinUcbModel plain = *LinUcbModel::Create(config);
    std::mt19937_64 rng(11);
    for (int t = 0; t < 120; ++t) {
      const Round round = RandomRound(24, 3, 3, rng);
      SelectProducts products;
      reusing.Estimate(round.context, &products);
      if (t % 10 == 3) {
        // Stale: the model changes between the Select and this Update.
        const Round other = RandomRound(24, 3, 3, rng);
        reusing.Update(other);
        plain.Update(other);
      }
      if (t % 10 == 7) {
        // Another context's products.
        SelectProducts wrong;
        reusing.Estimate(RandomVector(24, rng), &wrong);
        reusing.Update(round, &wrong);
      } else {
        reusing.Update(round, &products);
      }
      plain.Update(round);
      ExpectSameEstimates(reusing, plain, RandomVector(24, rng));
    }
    for (int a = 0; a < 3; ++a) EXPECT_TRUE(plain.IsPrimal(a)) << a;
  }
}

// While an action converts, it is still in dual form and exact; a model
// rebuilt at any point of the conversion is in the same state (same form,
// same progress) and equal to the incremental one.
TEST(LinUcbTest, ConversionIsAmortisedAndRebuildResumesIt) {
  BanditConfig config;
  config.context_dim = 64;
  config.lambda_c = 3.0;
  config.action_names = {"only"};
  LinUcbModel model = *LinUcbModel::Create(config);
  std::mt19937_64 rng(5);
  std::vector<Round> rounds;
  int converting_updates = 0;
  for (int t = 0; t < 85; ++t) {
    Round round = RandomRound(64, 4, 1, rng);
    model.Update(round);
    rounds.push_back(round);
    converting_updates += model.IsConverting(0);
    // The default threshold is 3/4 of d = 48 rounds. At 32 = ceil(48 * 2/3)
    // rounds the candidate is prepared (one step at d = 64), at 33 the
    // folding begins: 7 rows per update into one of the four column slices
    // in turn, each slice 7 rows on every fourth update while the count
    // grows by 4. At 69 every slice is within 7 rows of the count, and as
    // every update brings this one action a row, the slices cannot all hold
    // them at once: after 8 updates of chasing (updates with every slice
    // that close), at 79, the last rows go into the whole matrix and the
    // action turns primal.
    EXPECT_EQ(model.IsConverting(0), t + 1 >= 33 && t + 1 < 79) << t;
    EXPECT_EQ(model.IsPrimal(0), t + 1 >= 79) << t;
    if (t + 1 >= 30) {
      ExpectMatchesReference(model, rounds, RandomVector(64, rng),
                             "round " + std::to_string(t + 1));
      LinUcbModel rebuilt = *LinUcbModel::Rebuild(config, rounds);
      EXPECT_EQ(rebuilt.IsConverting(0), model.IsConverting(0)) << t;
      EXPECT_EQ(rebuilt.IsPrimal(0), model.IsPrimal(0)) << t;
      // The rebuilt one, one round on: still the reference.
      const Round next = RandomRound(64, 4, 1, rng);
      rebuilt.Update(next);
      std::vector<Round> more = rounds;
      more.push_back(next);
      ExpectMatchesReference(rebuilt, more, RandomVector(64, rng),
                             "rebuilt then updated at " + std::to_string(t));
    }
  }
  EXPECT_EQ(converting_updates, 46);
}

// Actions that reach the conversion together convert one after another:
// never two at once, each in turn, and the model stays exact; a rebuild at
// any point resumes the same schedule.
TEST(LinUcbTest, ActionsConvertOneAtATime) {
  const BanditConfig config = ThreeActions(Learner::kPostHoc, 64, 3.0);
  LinUcbModel model = *LinUcbModel::Create(config);
  std::mt19937_64 rng(8);
  std::vector<Round> rounds;
  std::vector<int> order;  // actions in the order they turned primal
  int most_converting = 0;
  // Models rebuilt along the way, then fed the same rounds as the live one:
  // a rebuild that resumed the schedule wrongly would part from it.
  std::vector<LinUcbModel> followers;
  for (int t = 0; t < 300; ++t) {
    const Round round = RandomRound(64, 3, 3, rng);
    const bool was_primal[3] = {model.IsPrimal(0), model.IsPrimal(1),
                                model.IsPrimal(2)};
    model.Update(round);
    rounds.push_back(round);
    for (LinUcbModel& f : followers) f.Update(round);
    int converting = 0;
    bool switched = false;
    for (int a = 0; a < 3; ++a) {
      converting += model.IsConverting(a);
      if (model.IsPrimal(a) && !was_primal[a]) {
        order.push_back(a);
        switched = true;
        EXPECT_GE(model.Count(a), 32) << a;  // ceil(48 * 2/3)
      }
    }
    most_converting = std::max(most_converting, converting);
    // At every switch (the primal caches taken from the dual ones), and now
    // and then.
    if (switched || t % 37 == 5 || t == 299) {
      ExpectMatchesReference(model, rounds, RandomVector(64, rng),
                             "round " + std::to_string(t + 1));
      LinUcbModel rebuilt = *LinUcbModel::Rebuild(config, rounds);
      followers.push_back(*LinUcbModel::Rebuild(config, rounds));
      for (int a = 0; a < 3; ++a) {
        EXPECT_EQ(rebuilt.IsConverting(a), model.IsConverting(a)) << t;
        EXPECT_EQ(rebuilt.IsPrimal(a), model.IsPrimal(a)) << t;
      }
      const std::vector<double> probe = RandomVector(64, rng);
      const std::vector<ActionEstimate> ea = rebuilt.Estimate(probe);
      const std::vector<ActionEstimate> eb = model.Estimate(probe);
      for (int a = 0; a < 3; ++a) {
        EXPECT_TRUE(bitewise::testing::RelNear(ea[a].predicted_loss,
                                               eb[a].predicted_loss, 1e-10));
        EXPECT_TRUE(
            bitewise::testing::RelNear(ea[a].width, eb[a].width, 1e-10));
      }
    }
  }
  EXPECT_EQ(most_converting, 1);
  EXPECT_EQ(order.size(), 3u);
  for (const LinUcbModel& f : followers) {
    const std::vector<double> probe = RandomVector(64, rng);
    const std::vector<ActionEstimate> ea = f.Estimate(probe);
    const std::vector<ActionEstimate> eb = model.Estimate(probe);
    for (int a = 0; a < 3; ++a) {
      EXPECT_EQ(f.IsPrimal(a), model.IsPrimal(a));
      EXPECT_TRUE(bitewise::testing::RelNear(ea[a].predicted_loss,
                                             eb[a].predicted_loss, 1e-10));
      EXPECT_TRUE(bitewise::testing::RelNear(ea[a].width, eb[a].width, 1e-10));
    }
    ExpectMatchesReference(f, rounds, probe, "follower");
  }
}

// A saved state whose conversion fields no schedule could leave is refused
// before anything is built from it: a primal action still converting, a
// fold before its matrix is prepared, two actions converting at once.
TEST(LinUcbTest, SavedStateWithImpossibleConversionIsRefused) {
  BanditConfig config;
  config.learner = Learner::kContextOnly;
  config.context_dim = 8;
  config.action_names = {"a", "b", "c"};
  LinUcbModel model = *LinUcbModel::Create(config);
  std::mt19937_64 rng(4);
  // Action 0 alone, until it converts (threshold 6: folding from 5 rounds).
  while (!model.IsConverting(0)) {
    Round round = RandomRound(8, 0, 1, rng);
    round.posthoc.clear();
    model.Update(round);
  }
  const std::string state = model.SaveState();
  ASSERT_TRUE(LinUcbModel::LoadState(config, state).ok());
  // Actions 1 and 2 have no rounds: each is count, loss sum, five int32
  // fields and one per fold slice, b (d doubles) and its row count (0), at
  // the end of the state.
  const size_t action_bytes =
      8 + 8 + (5 + LinUcbModel::kFoldSlices) * 4 + 8 * 8 + 4;
  const size_t action1 = state.size() - 2 * action_bytes;
  auto patched = [&](size_t at, int32_t value, size_t at2 = 0,
                     int32_t value2 = 0) {
    std::string bad = state;
    std::memcpy(&bad[at], &value, sizeof(value));
    if (at2 != 0) std::memcpy(&bad[at2], &value2, sizeof(value2));
    return LinUcbModel::LoadState(config, bad).status();
  };
  const size_t primal = action1 + 16, converting = action1 + 20,
               prepared = action1 + 24;
  // As saved, action 1 is dual and idle: zeroes.
  EXPECT_EQ(patched(primal, 0).code(), absl::StatusCode::kOk);
  const absl::Status both = patched(primal, 1, converting, 1);
  EXPECT_EQ(both.code(), absl::StatusCode::kDataLoss);
  EXPECT_THAT(both.message(), ::testing::HasSubstr("form and conversion"));
  const absl::Status early = patched(converting, 1, prepared, 3);
  EXPECT_EQ(early.code(), absl::StatusCode::kDataLoss);
  EXPECT_THAT(early.message(), ::testing::HasSubstr("form and conversion"));
  const absl::Status two = patched(prepared, 2);
  EXPECT_EQ(two.code(), absl::StatusCode::kDataLoss);
  EXPECT_THAT(two.message(), ::testing::HasSubstr("more than one action"));
}

// A saved state restores the model bit for bit, in every form and in the
// middle of a conversion, and keeps learning as the original does; a state
// for another configuration or a damaged one is refused, naming why.
TEST(LinUcbTest, SavedStateRestoresTheModelExactly) {
  for (const Learner learner : {Learner::kPostHoc, Learner::kContextOnly}) {
    const BanditConfig config = ThreeActions(learner, 64, 3.0);
    LinUcbModel model = *LinUcbModel::Create(config);
    std::mt19937_64 rng(21);
    bool saw_converting = false, saw_mixed = false;
    for (int t = 0; t < 220; ++t) {
      model.Update(RandomRound(64, 3, 3, rng));
      bool any_primal = false, any_dual = false;
      for (int a = 0; a < 3; ++a) {
        saw_converting |= model.IsConverting(a);
        (model.IsPrimal(a) ? any_primal : any_dual) = true;
      }
      saw_mixed |= any_primal && any_dual;
      if (t % 23 != 0 && t != 219) continue;
      const std::string state = model.SaveState();
      absl::StatusOr<LinUcbModel> loaded =
          LinUcbModel::LoadState(config, state);
      ASSERT_TRUE(loaded.ok()) << loaded.status();
      EXPECT_EQ(loaded->SaveState(), state);
      ExpectSameEstimates(*loaded, model, RandomVector(64, rng));
      for (int a = 0; a < 3; ++a) {
        EXPECT_EQ(loaded->IsConverting(a), model.IsConverting(a));
        EXPECT_EQ(loaded->Count(a), model.Count(a));
      }
      // The restored copy and the live model go on learning alike: to
      // rounding, not bit for bit (the copy holds its rows in one block, the
      // live model in several, and a pass over them sums block by block).
      LinUcbModel copy = *LinUcbModel::LoadState(config, state);
      const Round next = RandomRound(64, 3, 3, rng);
      copy.Update(next);
      model.Update(next);
      const std::vector<double> probe = RandomVector(64, rng);
      const std::vector<ActionEstimate> ec = copy.Estimate(probe);
      const std::vector<ActionEstimate> em = model.Estimate(probe);
      for (int a = 0; a < 3; ++a) {
        EXPECT_EQ(copy.IsPrimal(a), model.IsPrimal(a));
        EXPECT_EQ(copy.IsConverting(a), model.IsConverting(a));
        EXPECT_TRUE(bitewise::testing::RelNear(ec[a].predicted_loss,
                                               em[a].predicted_loss, 1e-12));
        EXPECT_TRUE(
            bitewise::testing::RelNear(ec[a].width, em[a].width, 1e-12));
      }
    }
    EXPECT_TRUE(saw_converting);
    EXPECT_TRUE(saw_mixed);

    const std::string state = model.SaveState();
    BanditConfig other = config;
    other.lambda_c = 4.0;
    absl::StatusOr<LinUcbModel> refused = LinUcbModel::LoadState(other, state);
    EXPECT_EQ(refused.status().code(), absl::StatusCode::kFailedPrecondition);
    EXPECT_THAT(refused.status().message(), ::testing::HasSubstr("lambda"));
    EXPECT_EQ(LinUcbModel::LoadState(config, state, 10).status().code(),
              absl::StatusCode::kFailedPrecondition);
    for (size_t cut : {size_t{0}, size_t{3}, size_t{40}, state.size() / 2,
                       state.size() - 1}) {
      absl::StatusOr<LinUcbModel> truncated =
          LinUcbModel::LoadState(config, state.substr(0, cut));
      EXPECT_EQ(truncated.status().code(), absl::StatusCode::kDataLoss) << cut;
      EXPECT_THAT(truncated.status().message(),
                  ::testing::HasSubstr("model state"));
    }
    EXPECT_EQ(LinUcbModel::LoadState(config, state + "x").status().code(),
              absl::StatusCode::kDataLoss);
    std::string bad_magic = state;
    bad_magic[0] = 'X';
    EXPECT_EQ(LinUcbModel::LoadState(config, bad_magic).status().code(),
              absl::StatusCode::kDataLoss);
  }
}

// A checkpoint plus the rounds after it, replayed in one batch, is the model
// that saw every round: in the same forms, equal to 1e-10 and to the dense
// reference, from checkpoints taken before, during and after conversions.
TEST(LinUcbTest, CheckpointPlusReplayEqualsTheWholeLog) {
  for (const Learner learner : {Learner::kPostHoc, Learner::kContextOnly}) {
    const BanditConfig config = ThreeActions(learner, 64, 3.0);
    std::mt19937_64 rng(33);
    std::vector<Round> rounds;
    for (int t = 0; t < 260; ++t) rounds.push_back(RandomRound(64, 3, 3, rng));
    LinUcbModel whole = *LinUcbModel::Create(config);
    for (const Round& r : rounds) whole.Update(r);
    for (const int cut : {1, 60, 150, 175, 190, 259}) {
      SCOPED_TRACE(cut);
      LinUcbModel head = *LinUcbModel::Create(config);
      for (int t = 0; t < cut; ++t) head.Update(rounds[t]);
      LinUcbModel resumed = *LinUcbModel::LoadState(config, head.SaveState());
      resumed.Replay(std::vector<Round>(rounds.begin() + cut, rounds.end()));
      EXPECT_EQ(resumed.TotalRounds(), whole.TotalRounds());
      const std::vector<double> probe = RandomVector(64, rng);
      const std::vector<ActionEstimate> a = whole.Estimate(probe);
      const std::vector<ActionEstimate> b = resumed.Estimate(probe);
      for (int i = 0; i < 3; ++i) {
        EXPECT_EQ(resumed.IsPrimal(i), whole.IsPrimal(i));
        EXPECT_EQ(resumed.IsConverting(i), whole.IsConverting(i));
        EXPECT_TRUE(bitewise::testing::RelNear(b[i].predicted_loss,
                                               a[i].predicted_loss, 1e-10));
        EXPECT_TRUE(bitewise::testing::RelNear(b[i].width, a[i].width, 1e-10));
        EXPECT_TRUE(bitewise::testing::RelNear(resumed.Theta(i), whole.Theta(i),
                                               1e-10));
      }
      ExpectMatchesReference(resumed, rounds, probe, "resumed");
      // And it keeps learning like the whole one.
      LinUcbModel next = std::move(resumed);
      const Round more = RandomRound(64, 3, 3, rng);
      next.Update(more);
      std::vector<Round> longer = rounds;
      longer.push_back(more);
      ExpectMatchesReference(next, longer, RandomVector(64, rng),
                             "then updated");
    }
  }
}

// tests/bandit/testdata/linucb_format3_converting_2026-12-03.state: a state
// of format 3 (two fold slices), saved by the code of commit e94968f after
// the first 17 of these rounds, action 0 converting (folds under way). It
// loads (the conversion starts again from the whole dual form), equals the
// dense reference, and learns on through the switch.
std::vector<Round> Format3FixtureRounds(int count) {
  std::vector<Round> rounds(count);
  for (int t = 0; t < count; ++t) {
    Round& r = rounds[t];
    r.action = t % 5 == 4 ? 1 + (t / 5) % 2 : 0;
    r.context.resize(16);
    r.posthoc.resize(3);
    for (int i = 0; i < 16; ++i) r.context[i] = ((t * 31 + i * 17) % 97) / 97.0;
    for (int i = 0; i < 3; ++i) r.posthoc[i] = ((t * 13 + i * 7) % 89) / 89.0;
    r.loss = (t % 7) / 6.0;
    r.weight = 1.0 + (t % 3) * 0.5;
  }
  return rounds;
}

TEST(LinUcbTest, Format3StateConvertingLoadsAndLearnsOn) {
  BanditConfig config;
  config.learner = Learner::kPostHoc;
  config.context_dim = 16;
  config.posthoc_dim = 3;
  config.lambda_c = 2.0;
  config.action_names = {"a", "b", "c"};
  int32_t format = 0;
  const std::string state = testing::ReadStateFixture(
      BITEWISE_TESTDATA "/linucb_format3_converting_2026-12-03.state", &format);
  ASSERT_FALSE(state.empty());
  ASSERT_EQ(format, 3);
  absl::StatusOr<LinUcbModel> loaded = LinUcbModel::LoadState(config, state);
  ASSERT_TRUE(loaded.ok()) << loaded.status();
  const std::vector<Round> rounds = Format3FixtureRounds(60);
  std::vector<Round> seen(rounds.begin(), rounds.begin() + 17);
  ASSERT_EQ(loaded->TotalRounds(), 17);
  EXPECT_FALSE(loaded->IsPrimal(0));
  ExpectMatchesReference(*loaded, seen, rounds[17].context, "loaded");
  for (int t = 17; t < 60; ++t) {
    loaded->Update(rounds[t]);
    seen.push_back(rounds[t]);
    if (t % 7 == 0 || t == 59) {
      ExpectMatchesReference(*loaded, seen, rounds[t % 17].context,
                             absl::StrCat("loaded, then ", t + 1, " rounds"));
    }
  }
  EXPECT_TRUE(loaded->IsPrimal(0));
  // Saved again in format 4, and loaded bit for bit.
  const std::string again = loaded->SaveState();
  std::memcpy(&format, again.data() + 4, sizeof(format));
  EXPECT_EQ(format, 4);
  EXPECT_EQ(LinUcbModel::LoadState(config, again)->SaveState(), again);
}

// With no conversion under way or beginning, Replay adds each action's
// rounds in one step (primal: Woodbury; dual: a block of the Cholesky
// factor) instead of one update each: the same model to 1e-10 and to the
// dense reference, importance weights included, in both forms.
TEST(LinUcbTest, ReplayInOneStepEqualsRoundByRound) {
  struct Case {
    const char* name;
    int d, rounds, cut;
    bool primal;  // the form of every action at the cut
  };
  // d 64: actions start converting at 2/3 of 3d/4 = 32 rows, so 80 rounds
  // over three actions stay dual (none converting); d 16: primal past 12, so
  // 250 rounds are all primal.
  for (const Case& c :
       {Case{"dual", 64, 80, 20, false}, Case{"primal", 16, 400, 250, true}}) {
    for (const Learner learner : {Learner::kPostHoc, Learner::kContextOnly}) {
      SCOPED_TRACE(absl::StrCat(c.name, " ", static_cast<int>(learner)));
      const BanditConfig config = ThreeActions(learner, c.d, 3.0);
      std::mt19937_64 rng(71);
      std::uniform_real_distribution<double> weight(0.5, 3.0);
      std::vector<Round> rounds;
      for (int t = 0; t < c.rounds; ++t) {
        rounds.push_back(RandomRound(c.d, 3, 3, rng));
        if (t % 3 == 0) rounds.back().weight = weight(rng);
      }
      LinUcbModel whole = *LinUcbModel::Create(config);
      for (const Round& r : rounds) whole.Update(r);
      LinUcbModel head = *LinUcbModel::Create(config);
      for (int t = 0; t < c.cut; ++t) head.Update(rounds[t]);
      for (int i = 0; i < 3; ++i) {
        ASSERT_EQ(head.IsPrimal(i), c.primal) << i;
        ASSERT_EQ(whole.IsPrimal(i), c.primal) << i;
        ASSERT_FALSE(whole.IsConverting(i)) << i;
      }
      LinUcbModel resumed = *LinUcbModel::LoadState(config, head.SaveState());
      resumed.Replay(std::vector<Round>(rounds.begin() + c.cut, rounds.end()));
      EXPECT_EQ(resumed.TotalRounds(), whole.TotalRounds());
      for (int probe_index = 0; probe_index < 3; ++probe_index) {
        const std::vector<double> probe = RandomVector(c.d, rng);
        const std::vector<ActionEstimate> a = whole.Estimate(probe);
        const std::vector<ActionEstimate> b = resumed.Estimate(probe);
        for (int i = 0; i < 3; ++i) {
          EXPECT_TRUE(bitewise::testing::RelNear(b[i].predicted_loss,
                                                 a[i].predicted_loss, 1e-10));
          EXPECT_TRUE(
              bitewise::testing::RelNear(b[i].width, a[i].width, 1e-10));
          EXPECT_TRUE(bitewise::testing::RelNear(resumed.Theta(i),
                                                 whole.Theta(i), 1e-10));
        }
        ExpectMatchesReference(resumed, rounds, probe, "replayed in one step");
      }
      // And it learns on like the whole one.
      const Round more = RandomRound(c.d, 3, 3, rng);
      resumed.Update(more);
      std::vector<Round> longer = rounds;
      longer.push_back(more);
      ExpectMatchesReference(resumed, longer, RandomVector(c.d, rng),
                             "then updated");
    }
  }
}

TEST(LinUcbTest, FreshModelPredictsZeroWithPriorWidth) {
  BanditConfig config;
  config.context_dim = 5;
  absl::StatusOr<LinUcbModel> model = LinUcbModel::Create(config);
  ASSERT_TRUE(model.ok());
  const std::vector<double> c = {1, 2, 3, 4, 5};
  for (const ActionEstimate& e : model->Estimate(c)) {
    EXPECT_DOUBLE_EQ(e.predicted_loss, 0.0);
    // N = lambda_c I + H^T M H with H = 0, so width = sqrt(2 |c|^2 / 1000).
    EXPECT_NEAR(e.width, std::sqrt(2.0 * 55.0 / 1000.0), 1e-15);
  }
}

TEST(LinUcbTest, DefaultsMatchTheResearchers) {
  const BanditConfig config;
  EXPECT_EQ(config.learner, Learner::kPostHoc);
  EXPECT_EQ(config.strategy, Strategy::kLinUcb);
  EXPECT_EQ(config.alpha, 0.01);
  EXPECT_EQ(config.lambda_c, 1000.0);
  EXPECT_EQ(config.lambda_p, 1.0);
  EXPECT_EQ(config.epsilon, 0.1);
  EXPECT_FALSE(config.importance_weighting);
  EXPECT_EQ(config.num_actions(), 6);
}

// A finite but huge value would make every later estimate NaN, forever
// (it is replayed at every rebuild): it is refused, naming the field.
TEST(LinUcbTest, HugeFiniteInputsAreRefusedAndChangeNothing) {
  BanditConfig config;
  config.context_dim = 4;
  LinUcbModel model = *LinUcbModel::Create(config);
  const std::vector<double> ok = {0.1, 0.2, 0.3, 0.4};
  const std::vector<ActionEstimate> before = model.Estimate(ok);
  Round round;
  round.context = {0.1, 1e160, 0.3, 0.4};
  round.posthoc = {0.0, 0.0, 1.0, 0.0};
  absl::Status status = model.ValidateRound(round);
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(status.message(),
            "context[1]: magnitude must be at most 1e+06, got 1e+160");
  round.context = ok;
  round.posthoc = {0.0, -1e155, 1.0, 0.0};
  EXPECT_EQ(model.ValidateRound(round).message(),
            "posthoc[1]: magnitude must be at most 1e+06, got -1e+155");
  // Within the magnitude bound, the squared norm is held to 1e10 times the
  // ridge (lambda_p = 1 here): beyond, the model's pivots would cancel to
  // rounding noise.
  round.posthoc = {0.0, -1e6, 1.0, 0.0};
  EXPECT_TRUE(model.ValidateRound(round).ok());  // a stored event's rule
  EXPECT_EQ(ValidateInputScale(config, round.context, round.posthoc).message(),
            "posthoc: squared norm 1e+12 is over 1e+10 times lambda_p (1), "
            "beyond what double precision keeps exact in the model; scale "
            "the values down or create the user with a larger lambda_p");
  round.posthoc = {0.0, -9e4, 1.0, 0.0};
  EXPECT_TRUE(ValidateInputScale(config, round.context, round.posthoc).ok());
  EXPECT_EQ(model.Estimate(ok)[0].lcb, before[0].lcb);
}

TEST(LinUcbTest, RejectsBadInputNamingTheField) {
  BanditConfig config;
  config.context_dim = 3;
  config.posthoc_dim = 2;
  absl::StatusOr<LinUcbModel> model = LinUcbModel::Create(config);
  ASSERT_TRUE(model.ok());
  absl::Status s = model->ValidateContext({1.0, 2.0});
  EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("context: expected 3 values, got 2"),
            std::string::npos)
      << s;
  s = model->ValidateContext({1.0, NAN, 2.0});
  EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("context[1]"), std::string::npos) << s;
  s = model->ValidateContext({1.0, INFINITY, 2.0});
  EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument);
  s = model->ValidateOutcome(1.5, {0.0, 1.0});
  EXPECT_NE(s.message().find("loss"), std::string::npos) << s;
  s = model->ValidateOutcome(NAN, {0.0, 1.0});
  EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument);
  s = model->ValidateOutcome(1.0, {0.0});
  EXPECT_NE(s.message().find("posthoc: expected 2 values, got 1"),
            std::string::npos)
      << s;
  s = model->ValidateOutcome(1.0, {});
  EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument)
      << "post hoc learner needs p";
  EXPECT_TRUE(model->ValidateOutcome(0.0, {0.5, 0.5}).ok());

  config.learner = Learner::kContextOnly;
  absl::StatusOr<LinUcbModel> context_only = LinUcbModel::Create(config);
  ASSERT_TRUE(context_only.ok());
  EXPECT_TRUE(context_only->ValidateOutcome(1.0, {}).ok());
}

TEST(LinUcbTest, RejectsBadConfig) {
  BanditConfig config;
  config.lambda_c = 0;
  EXPECT_NE(LinUcbModel::Create(config).status().message().find("lambda_c"),
            std::string::npos);
  config = BanditConfig();
  config.action_names = {"a", "a"};
  EXPECT_NE(LinUcbModel::Create(config).status().message().find("duplicate"),
            std::string::npos);
  config = BanditConfig();
  config.posthoc_dim = 0;
  EXPECT_FALSE(LinUcbModel::Create(config).ok());
}

TEST(LinUcbTest, DualMemoryGrowsWithRoundsNotDSquared) {
  BanditConfig config;
  config.context_dim = 2048;
  absl::StatusOr<LinUcbModel> model = LinUcbModel::Create(config);
  ASSERT_TRUE(model.ok());
  std::mt19937_64 rng(5);
  std::vector<Round> rounds;
  for (int t = 0; t < 60; ++t) {
    Round round;
    round.context = RandomVector(2048, rng);
    round.action = t % 6;
    round.posthoc = {1, 0, 0, 0};
    round.loss = t % 2;
    model->Update(round);
    rounds.push_back(round);
  }
  // 60 rounds x 2048 doubles is ~1 MB; one d x d matrix alone is 32 MB.
  EXPECT_LT(model->MemoryBytes(), 4u << 20);
  for (int a = 0; a < 6; ++a) EXPECT_FALSE(model->IsPrimal(a));
  // So is the same model rebuilt from its log (no conversion's matrix
  // allocated before its time).
  absl::StatusOr<LinUcbModel> rebuilt = LinUcbModel::Rebuild(config, rounds);
  ASSERT_TRUE(rebuilt.ok());
  EXPECT_LT(rebuilt->MemoryBytes(), 4u << 20);
}

}  // namespace
}  // namespace bitewise::bandit
