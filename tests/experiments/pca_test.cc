#include "experiments/pca.h"

#include <random>

#include "Eigen/Dense"
#include "gtest/gtest.h"
#include "services/domain/random.h"

namespace bitewise::experiments {
namespace {

// Data with standard deviations 3, 1 and 0.1 along a rotated basis: PCA
// must recover the basis and the variances, in that order.
TEST(PcaTest, RecoversKnownDirectionsAndVariances) {
  std::mt19937_64 rng(5);
  const Eigen::Matrix3d rotation =
      Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized())
          .toRotationMatrix();
  const Eigen::Vector3d scale(3.0, 1.0, 0.1);
  const int n = 20000;
  Eigen::MatrixXd data(n, 3);
  for (int i = 0; i < n; ++i) {
    Eigen::Vector3d z;
    for (int j = 0; j < 3; ++j) z(j) = scale(j) * random::StandardNormal(rng);
    data.row(i) = (rotation * z).transpose() + Eigen::RowVector3d(5, -2, 1);
  }
  auto pca = Pca::Fit(data, 2);
  ASSERT_TRUE(pca.ok()) << pca.status();
  EXPECT_NEAR(pca->variances()(0), 9.0, 0.3);
  EXPECT_NEAR(pca->variances()(1), 1.0, 0.05);
  for (int k = 0; k < 2; ++k) {
    EXPECT_NEAR(std::abs(pca->components().col(k).dot(rotation.col(k))), 1.0,
                1e-3);
  }
  EXPECT_NEAR(pca->mean()(0), 5.0, 0.1);
  const Eigen::MatrixXd projected = pca->Transform(data);
  EXPECT_NEAR(projected.col(0).mean(), 0.0, 1e-9);
  EXPECT_FALSE(Pca::Fit(data, 4).ok());
}

}  // namespace
}  // namespace bitewise::experiments
