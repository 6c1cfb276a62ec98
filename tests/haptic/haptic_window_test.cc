// Windowing and resampling against values computed by hand.
#include "services/haptic/core/haptic_window.h"

#include <cmath>
#include <vector>

#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace bitewise::haptic {
namespace {

using ::testing::HasSubstr;

TimedWrench Sample(double t_s, double fx) {
  TimedWrench s;
  s.t_s = t_s;
  s.wrench = WrenchFromChannels({fx, 2.0 * fx, 0.0, 0.0, 0.0, -fx});
  return s;
}

TEST(ResampleLinearTest, MatchesHandComputedValuesOnIrregularTimes) {
  // fx: 0 at t=0, 1 at t=0.1, 5 at t=0.3 (uneven spacing).
  const std::vector<TimedWrench> trace = {Sample(0.0, 0.0), Sample(0.1, 1.0),
                                          Sample(0.3, 5.0)};
  const std::vector<double> times = {-1.0, 0.0, 0.05, 0.1, 0.2, 0.25, 0.3, 0.4};
  // 0.05: halfway 0..1 -> 0.5; 0.2: halfway 1..5 -> 3; 0.25: 3/4 -> 4;
  // outside the trace the end values hold.
  const std::vector<double> expected = {0.0, 0.0, 0.5, 1.0, 3.0, 4.0, 5.0, 5.0};
  const auto values = ResampleLinear(trace, times);
  ASSERT_EQ(values.size(), expected.size());
  for (size_t k = 0; k < times.size(); ++k) {
    EXPECT_DOUBLE_EQ(values[k][0], expected[k]) << "t = " << times[k];
    EXPECT_DOUBLE_EQ(values[k][1], 2.0 * expected[k]);
    EXPECT_DOUBLE_EQ(values[k][5], -expected[k]);
  }
}

TEST(ExtractWindowTest, SixtyFourPointsPerChannelChannelMajorMinusOffset) {
  // 1 kHz, fz = 100 N/s * t + 3 (offset 3), tx = 0.5 everywhere (offset
  // 0.5), so tared fz is exactly linear and tared tx is zero.
  std::vector<TimedWrench> trace;
  for (int i = 0; i < 200; ++i) {
    TimedWrench s;
    s.t_s = i * 0.001;
    s.wrench =
        WrenchFromChannels({0.0, 0.0, 100.0 * s.t_s + 3.0, 0.5, 0.0, 0.0});
    trace.push_back(s);
  }
  const std::array<double, kWrenchChannels> offset = {0, 0, 3.0, 0.5, 0, 0};
  absl::StatusOr<HapticWindow> window =
      ExtractWindow(trace, 0.0404, offset, WindowOptions());
  ASSERT_TRUE(window.ok()) << window.status();
  EXPECT_DOUBLE_EQ(window->start_s, 0.0404);
  EXPECT_DOUBLE_EQ(window->end_s, 0.0904);
  for (int k = 0; k < kWindowPoints; ++k) {
    const double t = 0.0404 + 0.05 * k / 63.0;
    EXPECT_NEAR(window->inputs[2 * kWindowPoints + k], 100.0 * t, 1e-5)
        << "k = " << k;
    EXPECT_EQ(window->inputs[0 * kWindowPoints + k], 0.0f);
    EXPECT_NEAR(window->inputs[3 * kWindowPoints + k], 0.0, 1e-7);
  }
  // First and last points by hand: 100 * 0.0404 = 4.04, 100 * 0.0904.
  EXPECT_FLOAT_EQ(window->inputs[2 * kWindowPoints], 4.04f);
  EXPECT_FLOAT_EQ(window->inputs[2 * kWindowPoints + 63], 9.04f);
}

TEST(ExtractWindowTest, LowRatesStretchTheWindowToTheMinimumSampleCount) {
  // 40 Hz: a 50 ms window would hold 2 samples; it stretches to the 5th
  // sample after contact at 0.1 s: 0.125, 0.15, 0.175, 0.2, 0.225.
  std::vector<TimedWrench> trace;
  for (int i = 0; i < 20; ++i) trace.push_back(Sample(i * 0.025, i));
  absl::StatusOr<HapticWindow> window =
      ExtractWindow(trace, 0.1, {}, WindowOptions());
  ASSERT_TRUE(window.ok()) << window.status();
  EXPECT_DOUBLE_EQ(window->end_s, 0.225);
  // fx = 40 * t on this trace; at the last point t = 0.225 -> 9.
  EXPECT_FLOAT_EQ(window->inputs[63], 9.0f);
  // At 100 Hz the 50 ms window already holds 5 samples: no stretch.
  trace.clear();
  for (int i = 0; i < 40; ++i) trace.push_back(Sample(i * 0.01, i));
  window = ExtractWindow(trace, 0.1, {}, WindowOptions());
  ASSERT_TRUE(window.ok()) << window.status();
  EXPECT_DOUBLE_EQ(window->end_s, 0.15);
}

TEST(ExtractWindowTest, TraceEndingRightAfterContactIsInvalid) {
  std::vector<TimedWrench> trace;
  for (int i = 0; i < 10; ++i) trace.push_back(Sample(i * 0.01, 0.0));
  absl::StatusOr<HapticWindow> window =
      ExtractWindow(trace, 0.065, {}, WindowOptions());
  ASSERT_EQ(window.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(window.status().message(), HasSubstr("only 3 samples after"));
}

TEST(ValidateWindowOptionsTest, NamesTheField) {
  WindowOptions options;
  options.window_s = 0.0;
  EXPECT_THAT(ValidateWindowOptions(options).message(), HasSubstr("window_s"));
  options = WindowOptions();
  options.min_window_samples = 1;
  EXPECT_THAT(ValidateWindowOptions(options).message(),
              HasSubstr("min_window_samples"));
}

}  // namespace
}  // namespace bitewise::haptic
