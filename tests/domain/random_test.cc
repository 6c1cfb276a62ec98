// The project's random library (services/domain/random.h): a few draws of
// every function pinned, so a change to the library (or to the engine) is
// noticed; and, on libstdc++, each of the first family equal to the <random>
// distribution it replaced, draw for draw, which is why nothing seeded
// changed when the library arrived.
#include "services/domain/random.h"

#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "gtest/gtest.h"

namespace bitewise::random {
namespace {

TEST(RandomTest, PinnedDraws) {
  Engine rng(20261201);
  EXPECT_EQ(Canonical(rng), 0x1.c043a3132d47ap-6);
  EXPECT_EQ(Uniform(rng, -2.0, 3.0), 0x1.7bc7071351fp+0);
  EXPECT_EQ(UniformInt(rng, 0, 5), 3);
  EXPECT_EQ(UniformInt(rng, -1000, 1000), -48);
  Normal normal(1.0, 0.5);
  EXPECT_EQ(normal(rng), 0x1.8f5222a09d0aep+0);
  EXPECT_EQ(normal(rng), 0x1.7094c39b59008p-2);
  EXPECT_EQ(MixSeed(1, 2), 17911839290282890590ULL);
  EXPECT_EQ(Uniform01(rng), 0x1.27a10f1d8c66cp-2);
  EXPECT_EQ(UniformIndex(rng, 7), 0);
  EXPECT_EQ(StandardNormal(rng), -0x1.156309cdbfbddp+1);
}

TEST(RandomTest, LogUniformIsTheExpOfAUniformLogAndStaysInRange) {
  Engine a(17), b(17);
  for (int i = 0; i < 1000; ++i) {
    const double x = LogUniform(a, 250.0, 4000.0);
    EXPECT_EQ(x, std::exp(Uniform(b, std::log(250.0), std::log(4000.0))));
    EXPECT_GE(x, 250.0 * (1 - 1e-12));
    EXPECT_LT(x, 4000.0 * (1 + 1e-12));
  }
}

TEST(RandomTest, UniformIntCoversItsRangeAndNothingElse) {
  Engine rng(3);
  std::vector<int> counts(6, 0);
  for (int i = 0; i < 60000; ++i) {
    const int64_t v = UniformInt(rng, 10, 15);
    ASSERT_GE(v, 10);
    ASSERT_LE(v, 15);
    ++counts[v - 10];
  }
  for (int c : counts) EXPECT_NEAR(c, 10000, 500);
  EXPECT_EQ(UniformInt(rng, 4, 4), 4);
}

#if defined(__GLIBCXX__)
TEST(RandomTest, FirstFamilyDrawsWhatLibstdcxxDrew) {
  Engine ours(77), theirs(77);
  for (int i = 0; i < 20000; ++i) {
    ASSERT_EQ(Uniform(ours, -0.5, 2.5),
              std::uniform_real_distribution<double>(-0.5, 2.5)(theirs));
    ASSERT_EQ(UniformInt(ours, 0, 5),
              std::uniform_int_distribution<int>(0, 5)(theirs));
    ASSERT_EQ(UniformInt(ours, 0, 999),
              static_cast<int64_t>(
                  std::uniform_int_distribution<size_t>(0, 999)(theirs)));
  }
  Normal normal(0.2, 0.35);
  std::normal_distribution<double> std_normal(0.2, 0.35);
  for (int i = 0; i < 20001; ++i) {
    ASSERT_EQ(normal(ours), std_normal(theirs)) << i;
  }
}
#endif

}  // namespace
}  // namespace bitewise::random
