// Checks shared by the LinUCB learners' tests: a model's estimates, theta
// and phi against the dense float64 reference (dense_reference.h) at 1e-8,
// and random inputs.
#ifndef BITEWISE_TESTS_BANDIT_REFERENCE_CHECKS_H_
#define BITEWISE_TESTS_BANDIT_REFERENCE_CHECKS_H_

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "Eigen/Dense"
#include "gtest/gtest.h"
#include "services/bandit/core/linucb.h"
#include "tests/bandit/dense_reference.h"
#include "tests/common/near.h"

namespace bitewise::bandit::testing {

inline std::vector<double> RandomVector(int n, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<double> v(n);
  for (double& x : v) x = u(rng);
  return v;
}

inline void ExpectMatchesReference(const LinUcbModel& model,
                                   const std::vector<Round>& rounds,
                                   const std::vector<double>& probe,
                                   const std::string& where) {
  const BanditConfig& config = model.config();
  const std::vector<DenseActionModel> ref = DenseReference(config, rounds);
  const std::vector<ActionEstimate> est = model.Estimate(probe);
  const Eigen::Map<const Eigen::VectorXd> c(probe.data(), probe.size());
  for (int a = 0; a < config.num_actions(); ++a) {
    SCOPED_TRACE(where + " action " + std::to_string(a));
    const double pred = ref[a].theta.dot(c);
    const double width = std::sqrt(c.dot(ref[a].sigma * c));
    const double lcb = pred - config.alpha * width;
    EXPECT_TRUE(bitewise::testing::RelNear(model.Theta(a), ref[a].theta, 1e-8));
    EXPECT_TRUE(bitewise::testing::RelNear(est[a].predicted_loss, pred, 1e-8));
    EXPECT_TRUE(bitewise::testing::RelNear(est[a].width, width, 1e-8));
    EXPECT_TRUE(bitewise::testing::RelNear(est[a].lcb, lcb, 1e-8));
    if (config.learner == Learner::kPostHoc) {
      EXPECT_TRUE(bitewise::testing::RelNear(model.Phi(a), ref[a].phi, 1e-8));
    }
  }
}

}  // namespace bitewise::bandit::testing

#endif  // BITEWISE_TESTS_BANDIT_REFERENCE_CHECKS_H_
