// Built with -ffp-contract=off (services/domain/CMakeLists.txt): each sum
// and product below is rounded on its own, whatever the caller's flags.
#include "services/domain/random.h"

#include <cmath>

namespace bitewise::random {

double Uniform(Engine& rng, double lo, double hi) {
  return Canonical(rng) * (hi - lo) + lo;
}

double LogUniform(Engine& rng, double lo, double hi) {
  return std::exp(Uniform(rng, std::log(lo), std::log(hi)));
}

double Normal::operator()(Engine& rng) {
  double value;
  if (saved_available_) {
    saved_available_ = false;
    value = saved_;
  } else {
    double x, y, r2;
    do {
      x = 2.0 * Canonical(rng) - 1.0;
      y = 2.0 * Canonical(rng) - 1.0;
      r2 = x * x + y * y;
    } while (r2 > 1.0 || r2 == 0.0);
    const double mult = std::sqrt(-2 * std::log(r2) / r2);
    saved_ = x * mult;
    saved_available_ = true;
    value = y * mult;
  }
  return value * stddev_ + mean_;
}

}  // namespace bitewise::random
