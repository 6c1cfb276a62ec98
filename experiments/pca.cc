#include "experiments/pca.h"

#include "Eigen/Eigenvalues"

namespace bitewise::experiments {

absl::StatusOr<Pca> Pca::Fit(const Eigen::MatrixXd& data, int components) {
  if (data.rows() < 2 || components < 1 || components > data.cols()) {
    return absl::InvalidArgumentError(
        "PCA needs at least 2 samples and 1 <= components <= dimension");
  }
  Pca pca;
  pca.mean_ = data.colwise().mean();
  const Eigen::MatrixXd centred = data.rowwise() - pca.mean_;
  // D x D covariance (784 x 784 for MNIST) is far cheaper to decompose than
  // an SVD of the n x D data.
  Eigen::MatrixXd cov = Eigen::MatrixXd::Zero(data.cols(), data.cols());
  cov.selfadjointView<Eigen::Lower>().rankUpdate(centred.transpose());
  cov = cov.selfadjointView<Eigen::Lower>();
  cov /= static_cast<double>(data.rows() - 1);
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(cov);
  if (eig.info() != Eigen::Success) {
    return absl::InternalError("PCA eigendecomposition failed");
  }
  // Eigen returns ascending eigenvalues; the largest are at the end.
  const int d = static_cast<int>(data.cols());
  pca.components_.resize(d, components);
  pca.variances_.resize(components);
  for (int k = 0; k < components; ++k) {
    pca.components_.col(k) = eig.eigenvectors().col(d - 1 - k);
    pca.variances_(k) = eig.eigenvalues()(d - 1 - k);
  }
  return pca;
}

Eigen::MatrixXd Pca::Transform(const Eigen::MatrixXd& data) const {
  return (data.rowwise() - mean_) * components_;
}

}  // namespace bitewise::experiments
