// Principal component analysis with Eigen, for the MNIST contexts of
// docs/experiments.md (PCA-200 of the images). Fitted on training data only, so
// test contexts are projected with what the learner could have known.
#ifndef BITEWISE_EXPERIMENTS_PCA_H_
#define BITEWISE_EXPERIMENTS_PCA_H_

#include "Eigen/Core"
#include "absl/status/statusor.h"

namespace bitewise::experiments {

class Pca {
 public:
  // `data` is n x D (one sample per row). Keeps the `components` directions
  // of largest variance of the centred data, ordered by decreasing variance.
  // INVALID_ARGUMENT unless 1 <= components <= D and n >= 2.
  static absl::StatusOr<Pca> Fit(const Eigen::MatrixXd& data, int components);

  // (x - mean) projected on the components: n x components.
  Eigen::MatrixXd Transform(const Eigen::MatrixXd& data) const;

  const Eigen::RowVectorXd& mean() const { return mean_; }
  // D x components, orthonormal columns.
  const Eigen::MatrixXd& components() const { return components_; }
  // Variance along each component (sample covariance eigenvalues).
  const Eigen::VectorXd& variances() const { return variances_; }

 private:
  Eigen::RowVectorXd mean_;
  Eigen::MatrixXd components_;
  Eigen::VectorXd variances_;
};

}  // namespace bitewise::experiments

#endif  // BITEWISE_EXPERIMENTS_PCA_H_
