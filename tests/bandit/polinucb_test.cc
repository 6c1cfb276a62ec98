// PoLinUcbModel against the dense float64 evaluation of its formulas
// (DensePoLinUcbReference), on random problems in the dual, switching and
// primal regimes, with and without weights and a population prior; its
// rebuild, replay and saved state; its pooled factors across the pooled
// model's switch to primal form; a state of format 1; its input checks.
#include "services/bandit/core/polinucb.h"

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
#include "tests/bandit/dense_reference.h"
#include "tests/bandit/state_fixture.h"
#include "tests/common/near.h"

namespace bitewise::bandit {
namespace {

using ::bitewise::testing::RelNear;
using testing::DensePoLinUcbReference;
using ::testing::HasSubstr;

constexpr double kTolerance = 1e-8;

struct Problem {
  int d;
  int q;
  int k;
  int rounds;
  bool weighted;
  int primal_threshold;  // 0: the default (3d/4)
  bool prior = false;
};

std::string Name(const ::testing::TestParamInfo<Problem>& info) {
  const Problem& p = info.param;
  return absl::StrCat(
      "d", p.d, "_q", p.q, "_k", p.k, "_T", p.rounds,
      p.weighted ? "_weighted" : "",
      p.primal_threshold ? absl::StrCat("_primal", p.primal_threshold) : "",
      p.prior ? "_prior" : "");
}

BanditConfig MakeConfig(const Problem& p, std::mt19937_64& rng) {
  BanditConfig config;
  config.learner = Learner::kPoLinUcb;
  config.context_dim = p.d;
  config.posthoc_dim = p.q;
  config.action_names.clear();
  for (int a = 0; a < p.k; ++a)
    config.action_names.push_back(absl::StrCat("a", a));
  std::uniform_real_distribution<double> u(0.0, 1.0);
  config.alpha = 0.05 + u(rng);
  config.lambda_c = 0.5 + 3.0 * u(rng);
  config.lambda_p = 0.5 + 2.0 * u(rng);
  config.phi_radius = 0.1 + 2.0 * u(rng);
  if (p.prior) {
    PopulationPrior& prior = config.prior;
    prior.pool_version = 2;
    prior.rounds = 0.5 + 3.0 * u(rng);
    prior.context_msn = 0.2 + u(rng);
    prior.posthoc_msn = 0.2 + u(rng);
    for (int a = 0; a < p.k; ++a) {
      std::vector<double> theta0(p.d), phi0(p.q);
      for (double& v : theta0) v = u(rng) - 0.5;
      for (double& v : phi0) v = u(rng) - 0.5;
      prior.theta0.push_back(theta0);
      prior.phi0.push_back(phi0);
    }
  }
  return config;
}

// Post hoc contexts that depend on the context (a linear map plus noise),
// as the paper's z = phi(x) + eps, and losses from both.
std::vector<Round> MakeRounds(const Problem& p, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> noise(0.0, 0.3);
  Eigen::MatrixXd map = Eigen::MatrixXd::Random(p.q, p.d);
  std::vector<Round> rounds(p.rounds);
  for (Round& t : rounds) {
    t.context.resize(p.d);
    for (double& v : t.context) v = u(rng) - 0.3;
    const Eigen::VectorXd z =
        map * Eigen::Map<const Eigen::VectorXd>(t.context.data(), p.d);
    t.posthoc.resize(p.q);
    for (int j = 0; j < p.q; ++j) t.posthoc[j] = z(j) + noise(rng);
    t.action = static_cast<int>(rng() % p.k);
    t.loss = u(rng);
    t.weight = p.weighted ? 1.0 + 4.0 * u(rng) : 1.0;
  }
  return rounds;
}

void ExpectMatchesReference(const PoLinUcbModel& model,
                            const BanditConfig& config,
                            const std::vector<Round>& seen,
                            const std::vector<double>& at,
                            const std::string& where) {
  const testing::DensePoLinUcb ref = DensePoLinUcbReference(config, seen, at);
  EXPECT_TRUE(RelNear(model.PredictPosthoc(at), ref.p_hat, kTolerance))
      << where;
  EXPECT_TRUE(RelNear(model.PosthocRadius(at), ref.radius, kTolerance))
      << where;
  const std::vector<ActionEstimate> est = model.Estimate(at);
  for (int a = 0; a < config.num_actions(); ++a) {
    const std::string what = absl::StrCat(where, ", action ", a);
    EXPECT_TRUE(RelNear(model.Theta(a), ref.theta[a], kTolerance)) << what;
    EXPECT_TRUE(RelNear(model.Phi(a), ref.beta[a], kTolerance)) << what;
    EXPECT_TRUE(RelNear(est[a].predicted_loss, ref.predicted[a], kTolerance))
        << what;
    EXPECT_TRUE(RelNear(est[a].width, ref.width[a], kTolerance)) << what;
    EXPECT_TRUE(RelNear(est[a].lcb, ref.lcb[a], kTolerance)) << what;
  }
}

class PoLinUcbReferenceTest : public ::testing::TestWithParam<Problem> {};

TEST_P(PoLinUcbReferenceTest, IncrementalRebuiltReplayedAndLoadedMatchDense) {
  const Problem& p = GetParam();
  std::mt19937_64 rng(1000 + p.d * 31 + p.q * 7 + p.k + p.rounds);
  const BanditConfig config = MakeConfig(p, rng);
  const std::vector<Round> rounds = MakeRounds(p, rng);
  absl::StatusOr<PoLinUcbModel> made =
      PoLinUcbModel::Create(config, p.primal_threshold);
  ASSERT_TRUE(made.ok()) << made.status();
  PoLinUcbModel model = *std::move(made);
  std::vector<Round> seen;
  const std::vector<int> checks = {0, 1, p.rounds / 4, p.rounds / 2, p.rounds};
  for (int t = 0; t <= p.rounds; ++t) {
    if (std::find(checks.begin(), checks.end(), t) != checks.end()) {
      std::vector<double> at(p.d);
      std::uniform_real_distribution<double> u(-0.5, 1.0);
      for (double& v : at) v = u(rng);
      ExpectMatchesReference(model, config, seen, at,
                             absl::StrCat("after ", t, " rounds"));
    }
    if (t == p.rounds) break;
    const Round& round = rounds[t];
    ASSERT_TRUE(model.ValidateRound(round).ok());
    // Half the Updates reuse their Select's products.
    SelectProducts products;
    if (t % 2 == 0) model.Estimate(round.context, &products);
    model.Update(round, t % 2 == 0 ? &products : nullptr);
    seen.push_back(round);
  }
  EXPECT_EQ(model.TotalRounds(), p.rounds);
  const std::vector<double> at = rounds.back().context;

  absl::StatusOr<PoLinUcbModel> rebuilt =
      PoLinUcbModel::Rebuild(config, rounds, p.primal_threshold);
  ASSERT_TRUE(rebuilt.ok()) << rebuilt.status();
  ExpectMatchesReference(*rebuilt, config, rounds, at, "rebuilt");

  // A checkpoint halfway, then the rest replayed.
  const int half = p.rounds / 2;
  const std::vector<Round> first(rounds.begin(), rounds.begin() + half);
  const std::vector<Round> rest(rounds.begin() + half, rounds.end());
  PoLinUcbModel halfway =
      *PoLinUcbModel::Rebuild(config, first, p.primal_threshold);
  absl::StatusOr<PoLinUcbModel> loaded =
      PoLinUcbModel::LoadState(config, halfway.SaveState(), p.primal_threshold);
  ASSERT_TRUE(loaded.ok()) << loaded.status();
  loaded->Replay(rest);
  ExpectMatchesReference(*loaded, config, rounds, at, "loaded and replayed");
}

INSTANTIATE_TEST_SUITE_P(
    Random, PoLinUcbReferenceTest,
    ::testing::Values(Problem{6, 2, 3, 150, false, 0},
                      Problem{12, 4, 6, 200, true, 0},
                      Problem{24, 3, 4, 250, false, 6},  // switches to primal
                      Problem{40, 5, 6, 300, true, 8},
                      Problem{16, 1, 2, 160, false, 0, true},
                      Problem{20, 6, 5, 220, true, 5, true}),
    Name);

// The pooled radius from the factors while every context model is dual,
// then from the pooled model's primal form: against the dense reference
// every few rounds (weighted; half the Updates with their Select's
// products), and rebuilt, saved, loaded and replayed on both sides of the
// switch.
void CheckPooledFactorsAcrossTheSwitch(const Problem& p) {
  std::mt19937_64 rng(77 + p.d + p.k);
  const BanditConfig config = MakeConfig(p, rng);
  const std::vector<Round> rounds = MakeRounds(p, rng);
  PoLinUcbModel model = *PoLinUcbModel::Create(config, p.primal_threshold);
  EXPECT_TRUE(model.UsesPooledFactors());
  std::vector<Round> seen;
  int on = 0, off = 0;
  for (int t = 0; t <= p.rounds; ++t) {
    if (t % 3 == 0) {
      const std::vector<double> at = rounds[(t * 5) % p.rounds].context;
      ExpectMatchesReference(model, config, seen, at,
                             absl::StrCat("d ", p.d, " after ", t, " rounds"));
      (model.UsesPooledFactors() ? on : off) += 1;
    }
    if (t == p.rounds) break;
    SelectProducts products;
    if (t % 2 == 0) model.Estimate(rounds[t].context, &products);
    model.Update(rounds[t], t % 2 == 0 ? &products : nullptr);
    seen.push_back(rounds[t]);
  }
  EXPECT_GT(on, 5) << "the factors were barely used";
  EXPECT_GT(off, 1) << "the pooled model never turned primal";
  EXPECT_FALSE(model.UsesPooledFactors());

  const int threshold =
      p.primal_threshold > 0 ? p.primal_threshold : p.d * 3 / 4;
  for (int cut : {threshold / 2, threshold - 3, threshold + 2, p.rounds - 12}) {
    const std::string where = absl::StrCat("d ", p.d, ", cut at ", cut);
    const std::vector<Round> first(rounds.begin(), rounds.begin() + cut);
    PoLinUcbModel rebuilt =
        *PoLinUcbModel::Rebuild(config, first, p.primal_threshold);
    ExpectMatchesReference(rebuilt, config, first, rounds[cut].context,
                           where + ", rebuilt");
    const std::string state = rebuilt.SaveState();
    absl::StatusOr<PoLinUcbModel> loaded =
        PoLinUcbModel::LoadState(config, state, p.primal_threshold);
    ASSERT_TRUE(loaded.ok()) << loaded.status();
    EXPECT_EQ(loaded->SaveState(), state) << where;
    EXPECT_EQ(loaded->UsesPooledFactors(), rebuilt.UsesPooledFactors());
    // Ten rounds replayed, then six Updates.
    const std::vector<Round> replayed(rounds.begin() + cut,
                                      rounds.begin() + cut + 10);
    loaded->Replay(replayed);
    std::vector<Round> upto(rounds.begin(), rounds.begin() + cut + 10);
    ExpectMatchesReference(*loaded, config, upto, rounds[cut + 10].context,
                           where + ", replayed");
    for (int t = cut + 10; t < cut + 12; ++t) {
      SelectProducts products;
      if (t % 2 == 0) loaded->Estimate(rounds[t].context, &products);
      loaded->Update(rounds[t], t % 2 == 0 ? &products : nullptr);
      upto.push_back(rounds[t]);
    }
    ExpectMatchesReference(*loaded, config, upto, rounds[0].context,
                           where + ", replayed and updated");
  }
}

TEST(PoLinUcbTest, PooledFactorsMatchDenseAcrossThePooledSwitch) {
  // Four actions, all dual while the pooled model switches.
  CheckPooledFactorsAcrossTheSwitch(Problem{48, 3, 4, 90, true, 0});
  // One action: it converts beside the pooled model.
  CheckPooledFactorsAcrossTheSwitch(Problem{30, 2, 1, 70, true, 0});
  // A small threshold, a prior.
  CheckPooledFactorsAcrossTheSwitch(Problem{36, 4, 3, 80, true, 20, true});
}

// tests/bandit/testdata/polinucb_format1_2026-12-03.state: a state of
// format 1 (no pooled factors), saved by the code of commit 60dbe81 after
// Updates of the first 24 of these rounds, with this configuration.
std::vector<Round> Format1FixtureRounds(int count) {
  constexpr int kD = 40, kQ = 3, kK = 4;
  std::vector<Round> rounds(count);
  for (int t = 0; t < count; ++t) {
    Round& r = rounds[t];
    r.context.resize(kD);
    for (int i = 0; i < kD; ++i) {
      r.context[i] = 0.7 * std::sin(0.37 * (t + 1) * (i + 1) + 0.11 * i) + 0.2;
    }
    r.posthoc.resize(kQ);
    for (int j = 0; j < kQ; ++j) {
      r.posthoc[j] = std::cos(0.23 * (t + 1) * (j + 2));
    }
    r.action = (7 * t + t / 3) % kK;
    r.loss = 0.5 + 0.4 * std::sin(1.3 * t);
    r.weight = 1.0 + 0.5 * (1.0 + std::sin(0.9 * t));
  }
  return rounds;
}

TEST(PoLinUcbTest, Format1StateLoadsAndLearnsOn) {
  BanditConfig config;
  config.learner = Learner::kPoLinUcb;
  config.context_dim = 40;
  config.posthoc_dim = 3;
  config.action_names = {"a0", "a1", "a2", "a3"};
  config.alpha = 0.3;
  config.lambda_c = 1.5;
  config.lambda_p = 0.8;
  config.phi_radius = 0.7;
  int32_t format = 0;
  const std::string state = testing::ReadStateFixture(
      BITEWISE_TESTDATA "/polinucb_format1_2026-12-03.state", &format);
  ASSERT_FALSE(state.empty());
  ASSERT_EQ(format, 1);
  absl::StatusOr<PoLinUcbModel> loaded =
      PoLinUcbModel::LoadState(config, state);
  ASSERT_TRUE(loaded.ok()) << loaded.status();
  // No order of rounds to build the factors from: the pooled model's rows.
  EXPECT_FALSE(loaded->UsesPooledFactors());
  const std::vector<Round> rounds = Format1FixtureRounds(70);
  std::vector<Round> seen(rounds.begin(), rounds.begin() + 24);
  ASSERT_EQ(loaded->TotalRounds(), 24);
  ExpectMatchesReference(*loaded, config, seen, rounds[24].context, "loaded");
  // On past the pooled model's switch (threshold 30).
  for (int t = 24; t < 70; ++t) {
    SelectProducts products;
    if (t % 2 == 0) loaded->Estimate(rounds[t].context, &products);
    loaded->Update(rounds[t], t % 2 == 0 ? &products : nullptr);
    seen.push_back(rounds[t]);
    if (t % 9 == 0) {
      ExpectMatchesReference(*loaded, config, seen, rounds[t % 24].context,
                             absl::StrCat("loaded, then ", t + 1, " rounds"));
    }
  }
  // Saved again in format 2.
  const std::string again = loaded->SaveState();
  std::memcpy(&format, again.data() + 4, sizeof(format));
  EXPECT_EQ(format, 2);
  EXPECT_EQ(PoLinUcbModel::LoadState(config, again)->SaveState(), again);
}

TEST(PoLinUcbTest, SavedStateLoadsBitForBit) {
  const Problem p{10, 3, 4, 90, true, 4};
  std::mt19937_64 rng(5);
  const BanditConfig config = MakeConfig(p, rng);
  const std::vector<Round> rounds = MakeRounds(p, rng);
  PoLinUcbModel model = *PoLinUcbModel::Create(config, p.primal_threshold);
  for (const Round& round : rounds) model.Update(round);
  const std::string state = model.SaveState();
  PoLinUcbModel copy =
      *PoLinUcbModel::LoadState(config, state, p.primal_threshold);
  EXPECT_EQ(copy.SaveState(), state);
  const std::vector<ActionEstimate> a = model.Estimate(rounds[3].context);
  const std::vector<ActionEstimate> b = copy.Estimate(rounds[3].context);
  for (int i = 0; i < p.k; ++i) {
    EXPECT_EQ(a[i].predicted_loss, b[i].predicted_loss);
    EXPECT_EQ(a[i].width, b[i].width);
    EXPECT_EQ(a[i].lcb, b[i].lcb);
  }
  EXPECT_EQ(copy.TotalRounds(), model.TotalRounds());
  EXPECT_EQ(copy.input_scale().posthoc_sq_sum,
            model.input_scale().posthoc_sq_sum);

  // Another configuration, a cut state, extra bytes, another learner's.
  BanditConfig other = config;
  other.context_dim = 11;
  EXPECT_EQ(PoLinUcbModel::LoadState(other, state).status().code(),
            absl::StatusCode::kFailedPrecondition);
  for (size_t cut :
       {size_t{3}, size_t{40}, state.size() / 2, state.size() - 1}) {
    const absl::Status status =
        PoLinUcbModel::LoadState(config, state.substr(0, cut),
                                 p.primal_threshold)
            .status();
    EXPECT_EQ(status.code(), absl::StatusCode::kDataLoss) << cut;
  }
  EXPECT_EQ(PoLinUcbModel::LoadState(config, state + "x", p.primal_threshold)
                .status()
                .code(),
            absl::StatusCode::kDataLoss);
  BanditConfig linucb = config;
  linucb.learner = Learner::kContextOnly;
  const std::string foreign = LinUcbModel::Create(linucb)->SaveState();
  const absl::Status status =
      PoLinUcbModel::LoadState(config, foreign).status();
  EXPECT_EQ(status.code(), absl::StatusCode::kDataLoss);
  EXPECT_THAT(status.message(), HasSubstr("poLinUCB"));
}

TEST(PoLinUcbTest, InputsAreChecked) {
  const Problem p{4, 2, 3, 1, false, 0};
  std::mt19937_64 rng(9);
  const BanditConfig config = MakeConfig(p, rng);
  const PoLinUcbModel model = *PoLinUcbModel::Create(config);
  Round round = MakeRounds(p, rng)[0];
  EXPECT_TRUE(model.ValidateRound(round).ok());
  Round no_posthoc = round;
  no_posthoc.posthoc.clear();
  absl::Status status = model.ValidateRound(no_posthoc);
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(status.message(), HasSubstr("posthoc: expected 2 values"));
  Round nan = round;
  nan.posthoc[1] = std::nan("");
  EXPECT_THAT(model.ValidateRound(nan).message(), HasSubstr("posthoc[1]"));
  Round short_context = round;
  short_context.context.pop_back();
  EXPECT_THAT(model.ValidateRound(short_context).message(),
              HasSubstr("context: expected 4 values"));
  Round bad_loss = round;
  bad_loss.loss = 1.5;
  EXPECT_THAT(model.ValidateRound(bad_loss).message(), HasSubstr("loss"));
  Round bad_action = round;
  bad_action.action = 3;
  EXPECT_THAT(model.ValidateRound(bad_action).message(), HasSubstr("action"));

  BanditConfig no_q = config;
  no_q.posthoc_dim = 0;
  EXPECT_THAT(PoLinUcbModel::Create(no_q).status().message(),
              HasSubstr("polinucb learner needs posthoc_dim >= 1"));
  BanditConfig negative = config;
  negative.phi_radius = -1;
  EXPECT_THAT(PoLinUcbModel::Create(negative).status().message(),
              HasSubstr("phi_radius"));
  BanditConfig other = config;
  other.learner = Learner::kPostHoc;
  EXPECT_EQ(PoLinUcbModel::Create(other).status().code(),
            absl::StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace bitewise::bandit
