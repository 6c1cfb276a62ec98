// The population prior (services/bandit/core/population_prior.h): pooling
// users' models into a prior, a new user started from it, and unlike models
// or bad priors refused naming the field.
#include "services/bandit/core/population_prior.h"

#include <cmath>
#include <random>
#include <vector>

#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "services/bandit/core/linucb.h"
#include "tests/bandit/reference_checks.h"
#include "tests/common/near.h"

namespace bitewise::bandit {
namespace {

using testing::ExpectMatchesReference;
using testing::RandomVector;

// The pool is the count-weighted mean of the users' models, and its scale
// the pooled mean squared input norms; a new user with the prior and no
// rounds predicts what the pooled users' models predict, shrunk by
// kappa / (lambda + kappa) (context-only, where theta = A^-1 b exactly).
TEST(PopulationPriorTest, PoolsModelsAndStartsNewUsersFromThem) {
  std::mt19937_64 rng(77);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (Learner learner : {Learner::kContextOnly, Learner::kPostHoc}) {
    BanditConfig config;
    config.learner = learner;
    config.context_dim = 5;
    config.posthoc_dim = 3;
    config.lambda_c = 2.0;
    std::vector<LinUcbModel> users;
    for (int user = 0; user < 3; ++user) {
      LinUcbModel model = *LinUcbModel::Create(config);
      for (int t = 0; t < 20 + 10 * user; ++t) {
        Round round;
        round.context = RandomVector(5, rng);
        round.posthoc = RandomVector(3, rng);
        round.action = t % (user + 2);  // some actions untried by some
        round.loss = u(rng) < 0.4 ? 1.0 : 0.0;
        model.Update(round);
      }
      users.push_back(std::move(model));
    }
    std::vector<const LearnerModel*> pool;
    for (const LinUcbModel& m : users) pool.push_back(&m);
    absl::StatusOr<PopulationPrior> prior = PooledPrior(pool, 4.0, 1);
    ASSERT_TRUE(prior.ok()) << prior.status();
    double w = 0, cc = 0;
    for (const LinUcbModel& m : users) {
      w += m.input_scale().weight_sum;
      cc += m.input_scale().context_sq_sum;
    }
    EXPECT_NEAR(prior->context_msn, cc / w, 1e-12);
    for (int a = 0; a < config.num_actions(); ++a) {
      Eigen::VectorXd expected = Eigen::VectorXd::Zero(5);
      int64_t n = 0;
      for (const LinUcbModel& m : users) {
        expected += m.Count(a) * m.Theta(a);
        n += m.Count(a);
      }
      if (n > 0) expected /= n;
      const Eigen::Map<const Eigen::VectorXd> got(prior->theta0[a].data(), 5);
      EXPECT_TRUE(bitewise::testing::RelNear(got, expected, 1e-12)) << a;
    }
    BanditConfig newcomer = config;
    newcomer.prior = *prior;
    ASSERT_TRUE(ValidateConfig(newcomer).ok());
    LinUcbModel fresh = *LinUcbModel::Create(newcomer);
    ExpectMatchesReference(fresh, {}, RandomVector(5, rng), "fresh with prior");
    if (learner == Learner::kContextOnly) {
      const double kappa = prior->rounds * prior->context_msn;
      const Eigen::Map<const Eigen::VectorXd> theta0(prior->theta0[1].data(),
                                                     5);
      EXPECT_TRUE(bitewise::testing::RelNear(
          fresh.Theta(1), kappa / (2.0 + kappa) * theta0, 1e-12));
    }
  }
}

TEST(PopulationPriorTest, RejectsUnlikeModelsAndBadPriorsNamingTheField) {
  BanditConfig a;
  a.context_dim = 4;
  BanditConfig b = a;
  b.context_dim = 5;
  LinUcbModel ma = *LinUcbModel::Create(a);
  LinUcbModel mb = *LinUcbModel::Create(b);
  EXPECT_THAT(PooledPrior({&ma, &mb}, 1.0, 1).status().message(),
              ::testing::HasSubstr("model 1 differs"));
  EXPECT_THAT(PooledPrior({&ma}, 1.0, 1).status().message(),
              ::testing::HasSubstr("no completed rounds"));
  EXPECT_FALSE(PooledPrior({}, 1.0, 1).ok());
  EXPECT_FALSE(PooledPrior({&ma}, -1.0, 1).ok());
  BanditConfig bad = a;
  bad.prior.pool_version = 1;
  bad.prior.rounds = 2.0;
  bad.prior.context_msn = 1.0;
  bad.prior.posthoc_msn = 1.0;
  bad.prior.theta0.assign(6, std::vector<double>(3, 0.0));
  bad.prior.phi0.assign(6, std::vector<double>(4, 0.0));
  EXPECT_THAT(ValidateConfig(bad).message(),
              ::testing::HasSubstr("prior.theta0[0]: expected 4 values"));
  bad.prior.theta0.assign(6, std::vector<double>(4, 0.0));
  bad.prior.theta0[2][1] = std::nan("");
  EXPECT_THAT(ValidateConfig(bad).message(),
              ::testing::HasSubstr("prior.theta0[2]: must be finite"));
  bad.prior.theta0[2][1] = 0.0;
  bad.prior.posthoc_msn = 0.0;
  EXPECT_THAT(ValidateConfig(bad).message(),
              ::testing::HasSubstr("posthoc_msn"));
  bad.prior.posthoc_msn = 1.0;
  EXPECT_TRUE(ValidateConfig(bad).ok());
}

// A model that is not finite (here made by an Update that skipped
// ValidateRound, with a value whose square overflows) is refused whole,
// and the pool keeps what it had: one NaN would make every later user's
// prior NaN.
TEST(PopulationPriorTest, ANonFiniteModelIsRefusedAndThePoolUnchanged) {
  BanditConfig config;
  config.context_dim = 4;
  LinUcbModel good = *LinUcbModel::Create(config);
  LinUcbModel broken = *LinUcbModel::Create(config);
  Round round;
  round.context = {0.1, 0.2, 0.3, 0.4};
  round.posthoc = {0.0, 0.0, 1.0, 0.0};
  round.action = 2;
  round.loss = 1.0;
  good.Update(round, nullptr);
  round.context[1] = 1e200;  // never through ValidateRound
  broken.Update(round, nullptr);
  ASSERT_FALSE(broken.Theta(2).allFinite());
  PriorPool pool(config);
  ASSERT_TRUE(pool.Add(good).ok());
  const absl::Status refused = pool.Add(broken);
  EXPECT_EQ(refused.code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(refused.message(),
              ::testing::HasSubstr("estimate for action 2 is not finite"));
  EXPECT_EQ(pool.users(), 1);
  absl::StatusOr<PopulationPrior> prior = pool.Finish(1.0, 1);
  ASSERT_TRUE(prior.ok()) << prior.status();
  for (const auto& theta : prior->theta0) {
    for (double v : theta) EXPECT_TRUE(std::isfinite(v));
  }
}

}  // namespace
}  // namespace bitewise::bandit
