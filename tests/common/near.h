// Numeric comparison for tests, one rule everywhere: relative to the larger
// magnitude with a floor of 1, so values near zero compare absolutely.
//   EXPECT_TRUE(RelNear(model.Theta(a), reference.theta, 1e-8));
//   EXPECT_TRUE(RelNear(response.lcb(), expected_lcb, 1e-12)) << "action 3";
// Vectors (Eigen) compare by the norm of their difference.
#ifndef BITEWISE_TESTS_COMMON_NEAR_H_
#define BITEWISE_TESTS_COMMON_NEAR_H_

#include <algorithm>
#include <cmath>

#include "Eigen/Core"
#include "gtest/gtest.h"

namespace bitewise::testing {

inline ::testing::AssertionResult RelNear(double actual, double expected,
                                          double tolerance) {
  const double scale = std::max({1.0, std::abs(actual), std::abs(expected)});
  if (std::abs(actual - expected) <= tolerance * scale) {
    return ::testing::AssertionSuccess();
  }
  return ::testing::AssertionFailure()
         << actual << " vs " << expected << " (difference "
         << std::abs(actual - expected) << ", tolerance " << tolerance * scale
         << ")";
}

inline ::testing::AssertionResult RelNear(const Eigen::VectorXd& actual,
                                          const Eigen::VectorXd& expected,
                                          double tolerance) {
  if (actual.size() != expected.size()) {
    return ::testing::AssertionFailure()
           << "sizes " << actual.size() << " vs " << expected.size();
  }
  const double scale = std::max({1.0, actual.norm(), expected.norm()});
  const double difference = (actual - expected).norm();
  if (difference <= tolerance * scale) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << "difference norm " << difference
                                       << ", tolerance " << tolerance * scale;
}

}  // namespace bitewise::testing

#endif  // BITEWISE_TESTS_COMMON_NEAR_H_
