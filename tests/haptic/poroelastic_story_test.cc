// The poroelastic story (services/sim/poroelastic_story.cc) against its own
// account in services/sim/trace_stories.h: seeded, sampled as an EtherCAT
// master reads a Mini40 (500 Hz, 1 kHz or 2 kHz, finite, free motion first,
// contact 0.1-0.3 s in, 0.3 s after it), and keeping what its physics
// implies: crisp tissue the firmest, cracking again and again; pastes the
// weakest and never failing; a berry's skin bursting away most of the force
// at once; torques of a sensor far above the tines.
#include <algorithm>
#include <array>
#include <cmath>
#include <random>
#include <vector>

#include "gtest/gtest.h"
#include "services/domain/wrench.h"
#include "services/sim/trace_stories.h"
#include "tests/haptic/story_test_helpers.h"

namespace bitewise::sim {
namespace {

// A trace reduced to what a test reads: times, and the tared (by the median
// of the first 50 ms) force and torque magnitudes, averaged over the
// trailing `window_s`.
struct Tared {
  std::vector<double> t, force, torque;
};

Tared Tare(const std::vector<TimedWrench>& trace, double window_s) {
  std::array<double, 6> tare{};
  for (int k = 0; k < 6; ++k) {
    std::vector<double> first;
    for (const TimedWrench& s : trace) {
      if (s.t_s < 0.05) first.push_back(domain::Channel(s.wrench, k));
    }
    tare[k] = Median(first);
  }
  Tared out;
  std::array<double, 6> sum{};
  for (size_t i = 0, begin = 0; i < trace.size(); ++i) {
    for (int k = 0; k < 6; ++k) sum[k] += domain::Channel(trace[i].wrench, k);
    while (trace[i].t_s - trace[begin].t_s > window_s) {
      for (int k = 0; k < 6; ++k) {
        sum[k] -= domain::Channel(trace[begin].wrench, k);
      }
      ++begin;
    }
    const double n = static_cast<double>(i - begin + 1);
    double f2 = 0.0, t2 = 0.0;
    for (int k = 0; k < 6; ++k) {
      const double c = sum[k] / n - tare[k];
      (k < 3 ? f2 : t2) += c * c;
    }
    out.t.push_back(trace[i].t_s);
    out.force.push_back(std::sqrt(f2));
    out.torque.push_back(std::sqrt(t2));
  }
  return out;
}

// The first time the tared force passes `threshold` (-1 if never).
double Onset(const Tared& tared, double threshold) {
  for (size_t i = 0; i < tared.t.size(); ++i) {
    if (tared.force[i] > threshold) return tared.t[i];
  }
  return -1.0;
}

double PeakBetween(const Tared& tared, double from, double to) {
  double peak = 0.0;
  for (size_t i = 0; i < tared.t.size(); ++i) {
    if (tared.t[i] >= from && tared.t[i] <= to) {
      peak = std::max(peak, tared.force[i]);
    }
  }
  return peak;
}

// The sudden losses of force: for each sample, the share of the highest
// force of the last `within_s` that is gone, counted only when over 0.25 N
// is lost (more than the arm's vibration and the gauges' noise); returns
// the largest share, and counts losses of more than `share` that start at
// least `gap_s` after the previous counted one.
double Drops(const Tared& tared, double within_s, double share, double gap_s,
             int* count) {
  double largest = 0.0, last = -1.0;
  *count = 0;
  for (size_t i = 0, j = 0; i < tared.t.size(); ++i) {
    while (tared.t[i] - tared.t[j] > within_s) ++j;
    double high = 0.0;
    for (size_t k = j; k < i; ++k) high = std::max(high, tared.force[k]);
    if (high - tared.force[i] < 0.25) continue;
    const double lost = (high - tared.force[i]) / high;
    largest = std::max(largest, lost);
    if (lost > share && tared.t[i] - last > gap_s) {
      ++*count;
      last = tared.t[i];
    }
  }
  return largest;
}

std::vector<TimedWrench> Trace(HapticCategory category, uint64_t seed) {
  std::mt19937_64 rng(seed);
  return PoroelasticStoryTrace(category, rng);
}

TEST(PoroelasticStoryTest, SameSeedSameTraceAnotherSeedAnother) {
  for (HapticCategory category : kCategories) {
    const auto a = Trace(category, 11);
    const auto b = Trace(category, 11);
    const auto c = Trace(category, 12);
    ASSERT_EQ(a.size(), b.size());
    for (size_t i = 0; i < a.size(); ++i) {
      ASSERT_EQ(a[i].t_s, b[i].t_s);
      ASSERT_EQ(domain::Channels(a[i].wrench), domain::Channels(b[i].wrench));
    }
    bool differs = a.size() != c.size();
    for (size_t i = 0; !differs && i < a.size(); ++i) {
      differs = domain::Channels(a[i].wrench) != domain::Channels(c[i].wrench);
    }
    EXPECT_TRUE(differs);
  }
}

// EtherCAT cycles: 500 Hz, 1 kHz or 2 kHz, strictly increasing stamps with
// small jitter, finite and far below 100 N; each rate is drawn.
TEST(PoroelasticStoryTest, SampledAtEtherCatCycles) {
  std::array<int, 3> seen{};
  for (HapticCategory category : kCategories) {
    for (uint64_t seed = 0; seed < 15; ++seed) {
      const auto trace = Trace(category, 1000 + seed);
      ASSERT_GT(trace.size(), 100u);
      EXPECT_GE(trace.front().t_s, 0.0);
      std::vector<double> gaps;
      for (size_t i = 1; i < trace.size(); ++i) {
        ASSERT_GT(trace[i].t_s, trace[i - 1].t_s);
        gaps.push_back(trace[i].t_s - trace[i - 1].t_s);
      }
      const double period = Median(gaps);
      int index = -1;
      for (int r = 0; r < 3; ++r) {
        const double expected = 1.0 / std::array{500.0, 1000.0, 2000.0}[r];
        if (std::abs(period - expected) < 0.03 * expected) index = r;
      }
      ASSERT_GE(index, 0) << period;
      ++seen[index];
      for (const double gap : gaps) {
        EXPECT_NEAR(gap, period, 0.05 * period);
      }
      for (const TimedWrench& s : trace) {
        for (double c : domain::Channels(s.wrench))
          ASSERT_TRUE(std::isfinite(c));
        const auto& f = s.wrench.force_n;
        EXPECT_LT(std::sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]), 90.0);
      }
    }
  }
  for (int n : seen) EXPECT_GT(n, 0);
}

// Free motion first (only offset, noise and vibration), the touch 0.1-0.3 s
// in, at least 0.25 s recorded after it; hard, medium and hard-skin items
// pass 1 N within 50 ms of the touch.
TEST(PoroelasticStoryTest, FreeMotionThenContactWindow) {
  for (HapticCategory category : kCategories) {
    int firm = 0, total = 0;
    for (uint64_t seed = 0; seed < 60; ++seed) {
      const auto trace = Trace(category, 2000 + seed);
      const Tared tared = Tare(trace, 0.002);
      EXPECT_LT(PeakBetween(tared, 0.0, 0.1), 0.3) << seed;
      const double onset = Onset(tared, 0.3);
      if (onset < 0.0) {
        EXPECT_EQ(category, HapticCategory::kSoft);
        continue;
      }
      EXPECT_GE(onset, 0.1);
      // A paste may pass 0.3 N well after the touch; the others within
      // 50 ms of it, which is 0.1-0.3 s in.
      if (category != HapticCategory::kSoft) {
        EXPECT_LE(onset, 0.35) << seed;
        EXPECT_GE(tared.t.back(), onset + 0.25) << seed;
      } else {
        EXPECT_GE(tared.t.back(), 0.1 + 0.3 - 0.01);
      }
      ++total;
      if (PeakBetween(tared, onset, onset + 0.05) > 1.0) ++firm;
    }
    if (category != HapticCategory::kSoft) {
      EXPECT_GE(firm, 0.9 * total) << static_cast<int>(category);
    }
  }
}

// Per category over 100 items: the peak in the first 50 ms after the touch,
// the largest share lost within 10 ms, the number of such losses of more
// than 15% (10 ms apart), and the peak torque over the peak force.
struct Signatures {
  std::vector<double> early_peak, largest_drop, lever;
  std::vector<int> drops;
};

Signatures Measure(HapticCategory category) {
  Signatures out;
  for (uint64_t seed = 0; seed < 100; ++seed) {
    const auto trace = Trace(category, 5000 + seed);
    const Tared tared = Tare(trace, 0.001);
    const double onset = Onset(tared, 0.3);
    out.early_peak.push_back(
        onset < 0.0 ? 0.0 : PeakBetween(tared, onset, onset + 0.05));
    int count = 0;
    out.largest_drop.push_back(Drops(tared, 0.01, 0.15, 0.01, &count));
    out.drops.push_back(count);
    const double peak_force =
        *std::max_element(tared.force.begin(), tared.force.end());
    const double peak_torque =
        *std::max_element(tared.torque.begin(), tared.torque.end());
    out.lever.push_back(peak_torque / peak_force);
  }
  return out;
}

class PoroelasticSignatureTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    for (int c = 0; c < 4; ++c) signatures_[c] = Measure(kCategories[c]);
  }
  static const Signatures& Of(HapticCategory category) {
    for (int c = 0; c < 4; ++c) {
      if (kCategories[c] == category) return signatures_[c];
    }
    return signatures_[0];
  }
  static std::array<Signatures, 4> signatures_;
};
std::array<Signatures, 4> PoroelasticSignatureTest::signatures_;

// Turgid crisp tissue is the stiffest and toughest, pastes the softest:
// the median early peak orders hard > medium > soft, and a berry's
// pressurised skin is firmer than a paste.
TEST_F(PoroelasticSignatureTest, FirmnessOrder) {
  const double hard = Median(Of(HapticCategory::kHard).early_peak);
  const double medium = Median(Of(HapticCategory::kMedium).early_peak);
  const double soft = Median(Of(HapticCategory::kSoft).early_peak);
  const double skin = Median(Of(HapticCategory::kHardSkin).early_peak);
  EXPECT_GT(hard, 1.5 * medium);
  EXPECT_GT(medium, 1.5 * soft);
  EXPECT_GT(skin, 1.5 * soft);
}

// A skin burst releases the membrane's whole load onto soft flesh: most
// berries lose over 40% within 10 ms, more than medium flesh at its
// bioyield.
TEST_F(PoroelasticSignatureTest, SkinBurstsAwayMostOfTheForce) {
  const auto& skin = Of(HapticCategory::kHardSkin).largest_drop;
  EXPECT_GT(Median(skin), 0.4);
  EXPECT_GT(Median(skin), Median(Of(HapticCategory::kMedium).largest_drop));
}

// Pastes crack as fast as the tine moves: no sudden loss of force.
TEST_F(PoroelasticSignatureTest, PastesNeverFail) {
  const auto& soft = Of(HapticCategory::kSoft).largest_drop;
  const int failing =
      std::count_if(soft.begin(), soft.end(), [](double d) { return d > 0.2; });
  EXPECT_LE(failing, 10);
}

// Crisp tissue cracks unstably and reloads: a sawtooth of several losses.
TEST_F(PoroelasticSignatureTest, CrispTissueCracksAgainAndAgain) {
  std::vector<double> hard, soft;
  for (int n : Of(HapticCategory::kHard).drops) hard.push_back(n);
  for (int n : Of(HapticCategory::kSoft).drops) soft.push_back(n);
  EXPECT_GE(Median(hard), 2.0);
  EXPECT_LE(Median(soft), 0.0);
}

// The wrist sensor sits 16-24 cm above the tines with the fork tilted and
// off-centre: torques are a sizeable lever on the force, never more than
// the tines' distance.
TEST_F(PoroelasticSignatureTest, WristLever) {
  std::vector<double> all;
  for (HapticCategory category : kCategories) {
    for (double lever : Of(category).lever) {
      EXPECT_LT(lever, 0.3);
      all.push_back(lever);
    }
  }
  EXPECT_GT(Median(all), 0.01);
}

}  // namespace
}  // namespace bitewise::sim
