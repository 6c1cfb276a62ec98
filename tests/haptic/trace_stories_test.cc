// The independent trace stories (services/sim/trace_stories.h) through the
// trainer's entry point: seeded, distinct, and each keeping the physical
// signature of the four classes that its header promises; and the story
// list parser's refusals.
#include <algorithm>
#include <array>
#include <cstdio>
#include <vector>

#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "services/haptic/training/labelled_traces.h"

namespace bitewise::haptic {
namespace {

using ::testing::HasSubstr;

// Axial force shape of one trace in what HapticNet sees: the first 60 ms
// after the smoothed, tared Fz first reaches 0.5 N. Tared by the median of
// the first 50 ms (free motion in every story), smoothed over 3 ms so noise
// and vibration do not count as drops.
struct Shape {
  double peak_n = 0.0;  // highest smoothed tared Fz
  double drop = 0.0;    // share of the peak lost at the lowest point after it
};

Shape ShapeOf(const LabelledTrace& trace) {
  std::vector<double> first;
  for (const TimedWrench& s : trace.samples) {
    if (s.t_s < 0.05) first.push_back(s.wrench.force_n[2]);
  }
  std::nth_element(first.begin(), first.begin() + first.size() / 2,
                   first.end());
  const double tare = first[first.size() / 2];
  std::vector<double> smooth;
  for (size_t i = 0, begin = 0; i < trace.samples.size(); ++i) {
    while (trace.samples[i].t_s - trace.samples[begin].t_s > 0.003) ++begin;
    double sum = 0.0;
    for (size_t j = begin; j <= i; ++j) {
      sum += trace.samples[j].wrench.force_n[2];
    }
    smooth.push_back(sum / (i - begin + 1) - tare);
  }
  size_t begin = 0;
  while (begin + 1 < smooth.size() && smooth[begin] < 0.5) ++begin;
  size_t end = begin;
  while (end < smooth.size() &&
         trace.samples[end].t_s < trace.samples[begin].t_s + 0.06) {
    ++end;
  }
  const auto from = smooth.begin() + begin, last = smooth.begin() + end;
  const auto at = std::max_element(from, last);
  Shape shape;
  shape.peak_n = *at;
  const double lowest = *std::min_element(at, last);
  shape.drop = (shape.peak_n - lowest) / shape.peak_n;
  return shape;
}

double Median(std::vector<double> v) {
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

class TraceStoryTest : public ::testing::TestWithParam<TraceStory> {};

TEST_P(TraceStoryTest, IsSeededAndKeepsTheClassSignatures) {
  const TraceStory story = GetParam();
  const std::vector<LabelledTrace> traces = StoryTraces(story, 150, 5);
  const std::vector<LabelledTrace> again = StoryTraces(story, 2, 5);
  ASSERT_EQ(traces.size(), 600u);
  for (size_t i = 0; i < again.size(); ++i) {
    EXPECT_EQ(again[i].label, traces[i].label);
    ASSERT_EQ(again[i].samples.size(), traces[i].samples.size());
    EXPECT_EQ(Channels(again[i].samples.back().wrench),
              Channels(traces[i].samples.back().wrench));
  }
  std::array<std::vector<double>, kHapticClasses> peaks, drops;
  for (const LabelledTrace& trace : traces) {
    const Shape shape = ShapeOf(trace);
    peaks[static_cast<int>(trace.label)].push_back(shape.peak_n);
    drops[static_cast<int>(trace.label)].push_back(shape.drop);
  }
  const int hard = static_cast<int>(HapticClass::kHard);
  const int medium = static_cast<int>(HapticClass::kMedium);
  const int soft = static_cast<int>(HapticClass::kSoft);
  const int skin = static_cast<int>(HapticClass::kHardSkin);
  for (int k = 0; k < kHapticClasses; ++k) {
    std::printf("%s %-9s peak median %5.2f N, drop after it median %.2f\n",
                TraceStoryName(story),
                HapticClassName(static_cast<HapticClass>(k)), Median(peaks[k]),
                Median(drops[k]));
  }
  // Hard is the firmest, soft the weakest, medium in between.
  EXPECT_GT(Median(peaks[hard]), 2.0 * Median(peaks[medium]));
  EXPECT_GT(Median(peaks[medium]), Median(peaks[soft]));
  EXPECT_GT(Median(peaks[hard]), Median(peaks[skin]));
  // The skin gives way: most of the force is lost; a medium item loses
  // less at its puncture; a soft item hardly loses anything.
  EXPECT_GT(Median(drops[skin]), 0.5);
  EXPECT_GT(Median(drops[medium]), 0.08);
  EXPECT_LT(Median(drops[medium]), Median(drops[skin]));
  EXPECT_LT(Median(drops[soft]), 0.2);
}

// The puncture story is not among them: by its own account its medium items'
// force keeps rising as the tines go in (each tine's burst is taken up by
// the others and the descending fork), so their median drop within 60 ms of
// touching is 0.00, where these four stories promise at least 8 %. Its own
// tests (puncture_story_test.cc) check its own account.
INSTANTIATE_TEST_SUITE_P(Stories, TraceStoryTest,
                         ::testing::Values(TraceStory::kWorld,
                                           TraceStory::kPiecewise,
                                           TraceStory::kMechanics,
                                           TraceStory::kCompliant),
                         [](const ::testing::TestParamInfo<TraceStory>& info) {
                           return std::string(TraceStoryName(info.param));
                         });

TEST(TraceStoriesTest, StoriesDrawDifferentTraces) {
  const auto piecewise = StoryTraces(TraceStory::kPiecewise, 1, 5);
  const auto mechanics = StoryTraces(TraceStory::kMechanics, 1, 5);
  EXPECT_NE(Channels(piecewise[0].samples[0].wrench),
            Channels(mechanics[0].samples[0].wrench));
}

TEST(TraceStoriesTest, ParsesListsAndNamesBadOnes) {
  auto parsed = ParseTraceStories("world, mechanics");
  ASSERT_TRUE(parsed.ok()) << parsed.status();
  EXPECT_THAT(*parsed, ::testing::ElementsAre(TraceStory::kWorld,
                                              TraceStory::kMechanics));
  EXPECT_THAT(ParseTraceStories("world,recorded").status().message(),
              HasSubstr("unknown trace story \"recorded\""));
  EXPECT_THAT(ParseTraceStories("world,recorded").status().message(),
              HasSubstr("(world, piecewise, mechanics, compliant, puncture, "
                        "poroelastic, lattice)"));
  EXPECT_EQ(
      *ParseTraceStories(TraceStoryNames()),
      std::vector<TraceStory>({TraceStory::kWorld, TraceStory::kPiecewise,
                               TraceStory::kMechanics, TraceStory::kCompliant,
                               TraceStory::kPuncture, TraceStory::kPoroelastic,
                               TraceStory::kLattice}));
  EXPECT_THAT(ParseTraceStories("piecewise,piecewise").status().message(),
              HasSubstr("\"piecewise\" given twice"));
  EXPECT_THAT(ParseTraceStories(",").status().message(),
              HasSubstr("no trace story"));
}

}  // namespace
}  // namespace bitewise::haptic
