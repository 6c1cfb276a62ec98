// Seeded randomness for the whole project: the bandit policies, the
// simulated world and its devices, the HapticNet trainer and the
// experiments all draw through these functions. The engine is
// std::mt19937_64, whose output the C++ standard fixes; the distributions
// of <random> are not used, because the standard leaves their algorithms to
// the library. Written out here, a seed gives the same numbers with any
// compiler and standard library, which is what "a restarted service draws
// exactly what it would have drawn", "bit-identical weights" and
// "regenerate the published plots" rest on. tests/domain/random_test.cc
// pins draws of every function, so a change here is noticed.
//
// Two families, kept so that nothing drawn before this library existed
// changed when it arrived:
//  - Canonical, Uniform, UniformInt, Normal: the algorithms libstdc++ (GCC
//    12) uses for uniform_real_distribution, uniform_int_distribution and
//    normal_distribution with a 64-bit engine (a 64-bit draw over 2^64;
//    Lemire's multiply-and-reject; Marsaglia's polar method, the second
//    value of each pair kept for the next call). The services, the world,
//    the devices and the trainer use these.
//  - Uniform01, UniformIndex, StandardNormal: the experiments' draws (top 53
//    bits; rejection; Box-Muller), which their published results were
//    generated with. MixSeed derives independent streams from one seed.
//
// Every function is thread-compatible (one engine per thread). The ones
// with a floating-point sum (Uniform, Normal) are compiled out of line in
// random.cc with FMA contraction off, so no caller's flags (-march=native
// contracts a * b + c into one rounding by default) change a draw.
#ifndef BITEWISE_SERVICES_DOMAIN_RANDOM_H_
#define BITEWISE_SERVICES_DOMAIN_RANDOM_H_

#include <cmath>
#include <cstdint>
#include <random>

namespace bitewise::random {

using Engine = std::mt19937_64;

__extension__ typedef unsigned __int128 Uint128;  // GCC and Clang

// Uniform in [0, 1): one 64-bit draw over 2^64, rounded to double (a value
// that rounds up to 1 becomes the largest double below 1).
inline double Canonical(Engine& rng) {
  const double value = static_cast<double>(rng()) / 18446744073709551616.0;
  return value >= 1.0 ? std::nextafter(1.0, 0.0) : value;
}

// Uniform in [lo, hi).
double Uniform(Engine& rng, double lo, double hi);

// Log-uniform in [lo, hi): exp of Uniform(log lo, log hi); one draw.
double LogUniform(Engine& rng, double lo, double hi);

// Uniform integer in [lo, hi] (inclusive), by Lemire's multiply-and-reject
// on a 64-bit draw: no modulo bias, usually one draw.
inline int64_t UniformInt(Engine& rng, int64_t lo, int64_t hi) {
  const uint64_t range = static_cast<uint64_t>(hi) - static_cast<uint64_t>(lo);
  if (range == UINT64_MAX) return static_cast<int64_t>(rng());
  const uint64_t count = range + 1;
  Uint128 product = static_cast<Uint128>(rng()) * static_cast<Uint128>(count);
  uint64_t low = static_cast<uint64_t>(product);
  if (low < count) {
    const uint64_t threshold = -count % count;
    while (low < threshold) {
      product = static_cast<Uint128>(rng()) * static_cast<Uint128>(count);
      low = static_cast<uint64_t>(product);
    }
  }
  return static_cast<int64_t>(static_cast<uint64_t>(product >> 64) +
                              static_cast<uint64_t>(lo));
}

// Normal draws with a mean and standard deviation, by Marsaglia's polar
// method: each pair of uniforms gives two values, the second kept for the
// next call, so the stream depends on the object's lifetime (as with
// std::normal_distribution).
class Normal {
 public:
  explicit Normal(double mean = 0.0, double stddev = 1.0)
      : mean_(mean), stddev_(stddev) {}

  double operator()(Engine& rng);

 private:
  double mean_;
  double stddev_;
  double saved_ = 0.0;
  bool saved_available_ = false;
};

// SplitMix64 finaliser: decorrelates nearby seeds (trial 0, 1, 2, ...).
inline uint64_t MixSeed(uint64_t seed, uint64_t stream) {
  uint64_t z = seed + 0x9e3779b97f4a7c15ULL * (stream + 1);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

// Uniform in [0, 1) from the top 53 bits (the experiments' uniform).
inline double Uniform01(Engine& rng) {
  return static_cast<double>(rng() >> 11) * 0x1.0p-53;
}

// Uniform integer in [0, n) by rejection, so there is no modulo bias (the
// experiments' index draw).
inline int UniformIndex(Engine& rng, int n) {
  const uint64_t range = static_cast<uint64_t>(n);
  const uint64_t limit = UINT64_MAX - UINT64_MAX % range;
  uint64_t x;
  do {
    x = rng();
  } while (x >= limit);
  return static_cast<int>(x % range);
}

// Standard normal by Box-Muller, one of the pair (the experiments' normal).
inline double StandardNormal(Engine& rng) {
  double u1;
  do {
    u1 = Uniform01(rng);
  } while (u1 <= 0.0);
  const double u2 = Uniform01(rng);
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
}

}  // namespace bitewise::random

#endif  // BITEWISE_SERVICES_DOMAIN_RANDOM_H_
