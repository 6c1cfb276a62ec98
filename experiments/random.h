// Seeded randomness for the experiment programs. Every draw goes through
// these helpers rather than the <random> distributions, whose output the C++
// standard leaves to the library: a seed then gives the same numbers with
// any compiler, so published plots can be regenerated bit for bit.
#ifndef BITEWISE_EXPERIMENTS_RANDOM_H_
#define BITEWISE_EXPERIMENTS_RANDOM_H_

#include <cmath>
#include <cstdint>
#include <random>

namespace bitewise::experiments {

// SplitMix64 finaliser: decorrelates nearby seeds (trial 0, 1, 2, ...).
inline uint64_t MixSeed(uint64_t seed, uint64_t stream) {
  uint64_t z = seed + 0x9e3779b97f4a7c15ULL * (stream + 1);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

// Uniform in [0, 1) from the top 53 bits.
inline double Uniform01(std::mt19937_64& rng) {
  return static_cast<double>(rng() >> 11) * 0x1.0p-53;
}

// Uniform integer in [0, n) by rejection, so there is no modulo bias.
inline int UniformIndex(std::mt19937_64& rng, int n) {
  const uint64_t range = static_cast<uint64_t>(n);
  const uint64_t limit = UINT64_MAX - UINT64_MAX % range;
  uint64_t x;
  do {
    x = rng();
  } while (x >= limit);
  return static_cast<int>(x % range);
}

// Standard normal by Box-Muller (one of the pair; simplicity over speed).
inline double StandardNormal(std::mt19937_64& rng) {
  double u1;
  do {
    u1 = Uniform01(rng);
  } while (u1 <= 0.0);
  const double u2 = Uniform01(rng);
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
}

}  // namespace bitewise::experiments

#endif  // BITEWISE_EXPERIMENTS_RANDOM_H_
