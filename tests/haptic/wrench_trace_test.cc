// ValidateTrace (services/haptic/core/wrench_trace.h) at its limits: the
// sample count, each channel's range and finiteness, strictly increasing
// time and the average rate, each refusal naming the sample and field.
#include "services/haptic/core/wrench_trace.h"

#include <array>
#include <limits>
#include <vector>

#include "absl/strings/str_cat.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace bitewise::haptic {
namespace {

using ::testing::HasSubstr;

// `n` samples at `rate_hz` from t = 0, a small constant wrench.
std::vector<TimedWrench> Trace(int n, double rate_hz) {
  std::vector<TimedWrench> trace(n);
  for (int i = 0; i < n; ++i) {
    trace[i].t_s = i / rate_hz;
    trace[i].wrench = WrenchFromChannels({0.1, -0.2, 1.5, 0.01, 0.0, -0.01});
  }
  return trace;
}

TEST(ValidateTraceTest, TheSampleCountIsAtLeastTheMinimum) {
  EXPECT_TRUE(ValidateTrace(Trace(8, 1000.0), 8).ok());
  const absl::Status status = ValidateTrace(Trace(7, 1000.0), 8);
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(status.message(), HasSubstr("7 samples, need at least 8"));
  // Nothing to check in nothing, when nothing is asked for; one sample
  // has no rate.
  EXPECT_TRUE(ValidateTrace({}, 0).ok());
  EXPECT_TRUE(ValidateTrace(Trace(1, 1000.0), 1).ok());
}

TEST(ValidateTraceTest, ForcesAndTorquesUpToTheirLimitsPassAndBeyondAreNamed) {
  std::vector<TimedWrench> trace = Trace(20, 1000.0);
  trace[3].wrench.force_n[1] = -kMaxForceN;
  trace[4].wrench.torque_nm[2] = kMaxTorqueNm;
  EXPECT_TRUE(ValidateTrace(trace, 8).ok());

  const char* names[kWrenchChannels] = {"fx_n",  "fy_n",  "fz_n",
                                        "tx_nm", "ty_nm", "tz_nm"};
  for (int c = 0; c < kWrenchChannels; ++c) {
    std::vector<TimedWrench> bad = Trace(20, 1000.0);
    std::array<double, kWrenchChannels> channels = Channels(bad[11].wrench);
    const double limit = c < 3 ? kMaxForceN : kMaxTorqueNm;
    channels[c] = -1.001 * limit;
    bad[11].wrench = WrenchFromChannels(channels);
    const absl::Status status = ValidateTrace(bad, 8);
    EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument) << c;
    EXPECT_THAT(status.message(),
                HasSubstr(absl::StrCat("samples[11].", names[c], " = ")));
    EXPECT_THAT(status.message(), HasSubstr("beyond any F/T sensor's range"));
  }
}

TEST(ValidateTraceTest, NonFiniteValuesAreNamedWhereTheyAre) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  std::vector<TimedWrench> trace = Trace(20, 1000.0);
  trace[5].wrench.torque_nm[0] = inf;
  trace[9].wrench.force_n[2] = nan;  // later: the first is reported
  absl::Status status = ValidateTrace(trace, 8);
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(status.message(), HasSubstr("samples[5].tx_nm is not finite"));

  trace = Trace(20, 1000.0);
  trace[0].t_s = -inf;
  status = ValidateTrace(trace, 8);
  EXPECT_THAT(status.message(), HasSubstr("samples[0].t_s is not finite"));
}

TEST(ValidateTraceTest, TimeMustIncreaseStrictly) {
  std::vector<TimedWrench> trace = Trace(20, 1000.0);
  trace[12].t_s = trace[11].t_s;  // a repeated stamp
  absl::Status status = ValidateTrace(trace, 8);
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(status.message(),
              HasSubstr("samples[12].t_s = 0.011 s does not increase"));
  EXPECT_THAT(status.message(), HasSubstr("samples[11].t_s = 0.011 s"));
  EXPECT_THAT(status.message(), HasSubstr("strictly increasing"));

  trace = Trace(20, 1000.0);
  trace[3].t_s = 0.0001;  // back in time
  EXPECT_THAT(ValidateTrace(trace, 8).message(),
              HasSubstr("samples[3].t_s = 0.0001 s"));
}

TEST(ValidateTraceTest, TheAverageRateMustBeWithinTheTrainedRange) {
  // (n - 1) / (t_last - t_first): exactly the limits pass.
  EXPECT_TRUE(ValidateTrace(Trace(91, kMinRateHz), 8).ok());
  EXPECT_TRUE(ValidateTrace(Trace(7701, kMaxRateHz), 8).ok());
  for (const double rate : {80.0, 8000.0}) {
    const absl::Status status = ValidateTrace(Trace(100, rate), 8);
    EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument) << rate;
    EXPECT_THAT(status.message(),
                HasSubstr(absl::StrCat("100 samples at ", rate, " Hz")));
    EXPECT_THAT(status.message(), HasSubstr("trained on 90-7700 Hz"));
  }
  // An uneven trace is judged by its average: bursts at 10 kHz with a
  // pause, 500 Hz overall, pass.
  std::vector<TimedWrench> bursty = Trace(101, 10000.0);
  for (int i = 50; i <= 100; ++i) bursty[i].t_s += 0.19;
  EXPECT_TRUE(ValidateTrace(bursty, 8).ok());
}

}  // namespace
}  // namespace bitewise::haptic
