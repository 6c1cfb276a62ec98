// The puncture story (services/sim/puncture_story.cc) against its own
// account in services/sim/trace_stories.h: seeded, sampled as the Net F/T
// streams (7 kHz / n, finite, contact 0.1-0.3 s in, 0.3 s after it), and
// keeping each category's mechanics: hard pieces the firmest and cracking
// again and again, soft ones the weakest with no failure, a berry's skin
// splitting away most of the force within milliseconds, medium tissue
// losing less at its bioyield, soft tissue only relaxing; torques no larger
// than the fork's lever.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "gtest/gtest.h"
#include "services/domain/wrench.h"
#include "services/sim/trace_stories.h"
#include "tests/haptic/story_test_helpers.h"

namespace bitewise::sim {
namespace {

// A channel tared by its median over the first 50 ms (free motion) and
// averaged over the trailing `window_s`.
std::vector<double> Smoothed(const std::vector<TimedWrench>& trace, int channel,
                             double window_s) {
  std::vector<double> first;
  for (const TimedWrench& s : trace) {
    if (s.t_s < 0.05) first.push_back(domain::Channel(s.wrench, channel));
  }
  const double tare = Median(first);
  std::vector<double> out;
  double sum = 0.0;
  for (size_t i = 0, begin = 0; i < trace.size(); ++i) {
    sum += domain::Channel(trace[i].wrench, channel);
    while (trace[i].t_s - trace[begin].t_s > window_s) {
      sum -= domain::Channel(trace[begin].wrench, channel);
      ++begin;
    }
    out.push_back(sum / (i - begin + 1) - tare);
  }
  return out;
}

// The largest share of the force reached so far that is lost within
// `within_s` (counted once the force has passed 0.5 N).
double FastestDrop(const std::vector<TimedWrench>& trace,
                   const std::vector<double>& fz, double within_s) {
  double reached = 0.0, drop = 0.0;
  for (size_t i = 0; i < fz.size(); ++i) {
    reached = std::max(reached, fz[i]);
    if (reached < 0.5) continue;
    double lowest = fz[i];
    for (size_t j = i + 1;
         j < fz.size() && trace[j].t_s - trace[i].t_s <= within_s; ++j) {
      lowest = std::min(lowest, fz[j]);
    }
    drop = std::max(drop, (fz[i] - lowest) / reached);
  }
  return drop;
}

// Separate falls of at least `share` of the peak within 3 ms.
int Falls(const std::vector<TimedWrench>& trace, const std::vector<double>& fz,
          double share) {
  const double peak = *std::max_element(fz.begin(), fz.end());
  int falls = 0;
  for (size_t i = 0; i < fz.size(); ++i) {
    for (size_t j = i + 1;
         j < fz.size() && trace[j].t_s - trace[i].t_s <= 0.003; ++j) {
      if (fz[i] - fz[j] >= share * peak) {
        ++falls;
        while (i + 1 < fz.size() && trace[i + 1].t_s <= trace[j].t_s + 0.003)
          ++i;
        break;
      }
    }
  }
  return falls;
}

std::vector<std::vector<TimedWrench>> Traces(HapticCategory category, int n,
                                             uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<std::vector<TimedWrench>> traces;
  for (int i = 0; i < n; ++i) {
    traces.push_back(PunctureStoryTrace(category, rng));
  }
  return traces;
}

TEST(PunctureStoryTest, IsDeterministicForASeed) {
  for (HapticCategory category : kCategories) {
    std::mt19937_64 a(7), b(7), c(8);
    const auto first = PunctureStoryTrace(category, a);
    const auto again = PunctureStoryTrace(category, b);
    const auto other = PunctureStoryTrace(category, c);
    ASSERT_EQ(first.size(), again.size());
    for (size_t i = 0; i < first.size(); ++i) {
      ASSERT_EQ(first[i].t_s, again[i].t_s);
      ASSERT_EQ(domain::Channels(first[i].wrench),
                domain::Channels(again[i].wrench));
    }
    EXPECT_NE(domain::Channels(first[0].wrench),
              domain::Channels(other[0].wrench));
  }
}

TEST(PunctureStoryTest, StreamsAsTheBoxDoes) {
  constexpr std::array<int, 7> kDecimations = {1, 2, 4, 7, 14, 28, 70};
  std::array<int, 7> seen{};
  for (HapticCategory category : kCategories) {
    for (const auto& trace : Traces(category, 30, 11)) {
      ASSERT_GE(trace.size(), 2u);
      EXPECT_EQ(trace[0].t_s, 0.0);
      // Every n-th sample of the 7 kHz gauges, by sequence number.
      const double period = trace[1].t_s - trace[0].t_s;
      const int n = static_cast<int>(std::lround(period * 7000.0));
      const auto it = std::find(kDecimations.begin(), kDecimations.end(), n);
      ASSERT_NE(it, kDecimations.end()) << "period " << period;
      ++seen[it - kDecimations.begin()];
      for (size_t i = 1; i < trace.size(); ++i) {
        ASSERT_NEAR(trace[i].t_s - trace[i - 1].t_s, n / 7000.0, 1e-9);
      }
      // Contact 0.1-0.3 s in, 0.3 s after it.
      EXPECT_GE(trace.back().t_s, 0.4 - n / 7000.0);
      EXPECT_LE(trace.back().t_s, 0.6);
      for (const TimedWrench& s : trace) {
        for (double v : domain::Channels(s.wrench)) {
          ASSERT_TRUE(std::isfinite(v));
        }
      }
    }
  }
  for (int count : seen) EXPECT_GT(count, 0);
}

TEST(PunctureStoryTest, TouchesAfterTheFreeMotion) {
  for (HapticCategory category : kCategories) {
    for (const auto& trace : Traces(category, 60, 12)) {
      const std::vector<double> fz = Smoothed(trace, 2, 0.003);
      double before = 0.0, crossing = -1.0;
      for (size_t i = 0; i < trace.size(); ++i) {
        if (trace[i].t_s < 0.1) before = std::max(before, std::abs(fz[i]));
        if (crossing < 0.0 && fz[i] > 0.3) crossing = trace[i].t_s;
      }
      // Nothing but noise and drift before 0.1 s; the fork has met the
      // food (contact by 0.3 s) well before the end.
      EXPECT_LT(before, 0.25) << HapticClassName(category);
      EXPECT_GE(crossing, 0.1) << HapticClassName(category);
      EXPECT_LE(crossing, 0.45) << HapticClassName(category);
    }
  }
}

TEST(PunctureStoryTest, KeepsEachCategorysMechanics) {
  std::array<std::vector<double>, 4> peaks, drops;
  std::array<std::vector<double>, 4> falls;  // traces at 1 kHz and above
  for (HapticCategory category : kCategories) {
    const int k = static_cast<int>(category);
    for (const auto& trace : Traces(category, 120, 13)) {
      const std::vector<double> fz = Smoothed(trace, 2, 0.003);
      peaks[k].push_back(*std::max_element(fz.begin(), fz.end()));
      drops[k].push_back(FastestDrop(trace, fz, 0.015));
      if (trace[1].t_s - trace[0].t_s <= 1e-3 + 1e-9) {
        falls[k].push_back(Falls(trace, Smoothed(trace, 2, 0.001), 0.05));
      }
    }
    std::printf(
        "puncture %-9s peak median %5.2f N, fastest drop median %.2f, "
        "falls median %.0f\n",
        HapticClassName(category), Median(peaks[k]), Median(drops[k]),
        Median(falls[k]));
  }
  const int hard = static_cast<int>(HapticCategory::kHard);
  const int medium = static_cast<int>(HapticCategory::kMedium);
  const int soft = static_cast<int>(HapticCategory::kSoft);
  const int skin = static_cast<int>(HapticCategory::kHardSkin);
  // Bourne's coefficients: hard tissue an order above medium, soft below.
  EXPECT_GT(Median(peaks[hard]), 2.0 * Median(peaks[medium]));
  EXPECT_GT(Median(peaks[medium]), Median(peaks[soft]));
  EXPECT_GT(Median(peaks[hard]), Median(peaks[skin]));
  // The skin's split sheds most of the force within milliseconds; a medium
  // tine sheds part of its own share at its bioyield; soft tissue never
  // fails and only relaxes.
  EXPECT_GT(Median(drops[skin]), 0.5);
  EXPECT_LT(Median(drops[medium]), Median(drops[skin]));
  EXPECT_LT(Median(drops[soft]), 0.15);
  // Brittle tissue cracks again and again under each tine.
  EXPECT_GE(Median(falls[hard]), 3.0);
  EXPECT_EQ(Median(falls[soft]), 0.0);
}

TEST(PunctureStoryTest, SoftTissueOnlyRelaxes) {
  // No failure: what the force loses from its peak by the end is the
  // tissue's relaxation once the arm slows and holds, never more than the
  // largest relaxation share (55 %).
  std::vector<double> sags;
  for (const auto& trace : Traces(HapticCategory::kSoft, 100, 15)) {
    const std::vector<double> fz = Smoothed(trace, 2, 0.003);
    const double peak = *std::max_element(fz.begin(), fz.end());
    sags.push_back((peak - fz.back()) / peak);
  }
  EXPECT_LT(*std::max_element(sags.begin(), sags.end()), 0.55);
  EXPECT_GT(Median(sags), 0.02);
}

TEST(PunctureStoryTest, TorquesComeFromForcesOnTheFork) {
  for (HapticCategory category : kCategories) {
    for (const auto& trace : Traces(category, 50, 14)) {
      std::array<std::vector<double>, 6> w;
      for (int c = 0; c < 6; ++c) w[c] = Smoothed(trace, c, 0.003);
      const size_t at =
          std::max_element(w[2].begin(), w[2].end()) - w[2].begin();
      const double force = std::hypot(w[0][at], w[1][at], w[2][at]);
      const double torque = std::hypot(w[3][at], w[4][at], w[5][at]);
      // The tines are at most 90 mm below the sensor and 12 mm off its
      // axis; noise adds a little.
      EXPECT_LT(torque / force, 0.11) << HapticClassName(category);
    }
  }
}

}  // namespace
}  // namespace bitewise::sim
