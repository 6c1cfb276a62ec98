// The context ridge of a new user (docs/algorithms.md): lambda_c only means
// something relative to the contexts' mean squared norm, so a new user's
// lambda_c is rho_c x E||c||^2 of the featurizer in use, unless one is given
// explicitly. Written once here for the meal library and the experiments.
#ifndef BITEWISE_SERVICES_DOMAIN_CONTEXT_RIDGE_H_
#define BITEWISE_SERVICES_DOMAIN_CONTEXT_RIDGE_H_

namespace bitewise::domain {

// An explicit `lambda_c` > 0 is used exactly. Otherwise rho_c times the
// featurizer's E||c||^2 (`context_msn`) when the featurizer reports one;
// 0 when it does not, which means "keep the BanditService's default".
inline double NewUserContextRidge(double lambda_c, double rho_c,
                                  double context_msn) {
  if (lambda_c > 0.0) return lambda_c;
  if (context_msn > 0.0) return rho_c * context_msn;
  return 0.0;
}

}  // namespace bitewise::domain

#endif  // BITEWISE_SERVICES_DOMAIN_CONTEXT_RIDGE_H_
