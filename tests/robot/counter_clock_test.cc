// CounterClock on synthetic arrival times: a right counter under network
// and scheduler delays is never a fault; a wrong rate, a counter that jumps,
// stalls or goes backwards always is, with a message that gives the rates;
// a learned rate; and recovery once the stream is sane again.
#include "services/robot/netft/counter_clock.h"

#include <cmath>
#include <cstdint>
#include <random>

#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace bitewise::netft {
namespace {

using ::testing::AllOf;
using ::testing::ContainsRegex;
using ::testing::HasSubstr;

// Plays a box: records every 1/record_hz s of sensor time, the counter
// advancing at counter_hz, each arriving after a random delay (0-3 ms, and
// now and then a 150 ms scheduler stall that releases a burst).
class SyntheticBox {
 public:
  SyntheticBox(double record_hz, double counter_hz, uint64_t seed)
      : record_hz_(record_hz), counter_hz_(counter_hz), rng_(seed) {}

  // Feeds `seconds` of records into `clock`.
  void Play(CounterClock* clock, double seconds) {
    std::uniform_real_distribution<double> jitter(0.0, 0.003);
    std::uniform_real_distribution<double> uniform(0.0, 1.0);
    const int n = static_cast<int>(std::lround(seconds * record_hz_));
    for (int i = 0; i < n; ++i) {
      const double sent_s = k_ / record_hz_;
      ++k_;
      if (uniform(rng_) < 0.002) stall_until_s_ = sent_s + 0.15;
      double arrival_s = sent_s + 0.001 + jitter(rng_);
      // A receiver that did not run: everything waiting arrives at once.
      if (arrival_s < stall_until_s_) arrival_s = stall_until_s_;
      arrival_s = std::max(arrival_s, last_arrival_s_);
      last_arrival_s_ = arrival_s;
      const int64_t ticks = frozen_
                                ? ticks_at_freeze_
                                : std::llround(sent_s * counter_hz_) + offset_;
      clock->Observe(arrival_s, first_ ? 0 : ticks - last_ticks_);
      first_ = false;
      last_ticks_ = ticks;
      worst_ = std::max(worst_, clock->Report().state);
    }
  }
  void Jump(int64_t counts) { offset_ += counts; }
  void Freeze() {
    frozen_ = true;
    ticks_at_freeze_ = last_ticks_;
  }
  // The worst state seen since the last call.
  CounterClockState TakeWorst() {
    const CounterClockState worst = worst_;
    worst_ = CounterClockState::kVerifying;
    return worst;
  }

 private:
  const double record_hz_;
  const double counter_hz_;
  std::mt19937_64 rng_;
  int64_t k_ = 0;
  int64_t offset_ = 0;
  int64_t last_ticks_ = 0;
  int64_t ticks_at_freeze_ = 0;
  bool frozen_ = false;
  bool first_ = true;
  double stall_until_s_ = -1.0;
  double last_arrival_s_ = 0.0;
  CounterClockState worst_ = CounterClockState::kVerifying;
};

TEST(CounterClockTest, ARightCounterUnderDelaysAndStallsIsNeverAFault) {
  for (double counter_hz : {7000.0, 1000.0}) {
    for (uint64_t seed : {1, 2, 3}) {
      CounterClockOptions options;
      options.expected_rate_hz = counter_hz;
      CounterClock clock(options);
      SyntheticBox box(/*record_hz=*/1000.0, counter_hz, seed);
      box.Play(&clock, 0.3);
      EXPECT_EQ(clock.Report().state, CounterClockState::kVerifying);
      EXPECT_THAT(clock.Report().problem, HasSubstr("verifying"));
      box.Play(&clock, 0.4);
      box.TakeWorst();
      box.Play(&clock, 30.0);
      EXPECT_NE(box.TakeWorst(), CounterClockState::kFault)
          << counter_hz << " Hz, seed " << seed;
      const CounterClockReport report = clock.Report();
      EXPECT_EQ(report.state, CounterClockState::kOk) << report.problem;
      EXPECT_NEAR(report.measured_rate_hz / counter_hz, 1.0, 0.02);
    }
  }
}

TEST(CounterClockTest, ACounterOncePerRecordAgainstSevenKilohertzIsAFault) {
  CounterClock clock(CounterClockOptions{});  // 7000 Hz expected
  SyntheticBox box(/*record_hz=*/1000.0, /*counter_hz=*/1000.0, 4);
  box.Play(&clock, 1.0);
  const CounterClockReport report = clock.Report();
  EXPECT_EQ(report.state, CounterClockState::kFault);
  EXPECT_THAT(report.problem,
              AllOf(ContainsRegex("advances at (99[0-9]|100[0-9]) Hz"),
                    HasSubstr("but 7000 Hz is configured")));
  EXPECT_NEAR(report.measured_rate_hz, 1000.0, 20.0);
  // And it stays a fault for as long as the counter is wrong.
  box.TakeWorst();
  box.Play(&clock, 10.0);
  EXPECT_EQ(clock.Report().state, CounterClockState::kFault);
}

TEST(CounterClockTest, AFastCounterIsAFaultToo) {
  CounterClockOptions options;
  options.expected_rate_hz = 1000.0;
  CounterClock clock(options);
  SyntheticBox box(/*record_hz=*/1000.0, /*counter_hz=*/1500.0, 5);
  box.Play(&clock, 1.0);
  EXPECT_EQ(clock.Report().state, CounterClockState::kFault);
  EXPECT_THAT(clock.Report().problem,
              ContainsRegex("advances at (149[0-9]|150[0-9]) Hz"));
}

TEST(CounterClockTest, LearnsTheRateThenChecksIt) {
  CounterClockOptions options;
  options.expected_rate_hz = 0.0;
  CounterClock clock(options);
  SyntheticBox box(/*record_hz=*/1000.0, /*counter_hz=*/1000.0, 6);
  box.Play(&clock, 0.5);
  EXPECT_EQ(clock.Report().state, CounterClockState::kVerifying);
  EXPECT_THAT(clock.Report().problem, HasSubstr("learning"));
  EXPECT_EQ(clock.rate_in_use_hz(), 7000.0);  // nominal, unused
  box.Play(&clock, 2.0);
  EXPECT_EQ(clock.Report().state, CounterClockState::kOk);
  EXPECT_NEAR(clock.rate_in_use_hz(), 1000.0, 20.0);
  box.Jump(5000);
  box.Play(&clock, 0.1);
  EXPECT_EQ(clock.Report().state, CounterClockState::kFault);
  EXPECT_THAT(clock.Report().problem, HasSubstr("jumped"));
}

TEST(CounterClockTest, AJumpIsAFaultUntilAWindowOfCleanRecords) {
  CounterClock clock(CounterClockOptions{});
  SyntheticBox box(1000.0, 7000.0, 7);
  box.Play(&clock, 2.0);
  ASSERT_EQ(clock.Report().state, CounterClockState::kOk);
  box.Jump(7000);  // one second of counts in one record
  box.Play(&clock, 0.002);
  EXPECT_EQ(clock.Report().state, CounterClockState::kFault);
  EXPECT_THAT(clock.Report().problem,
              AllOf(HasSubstr("jumped by 70"), HasSubstr("cannot be trusted")));
  box.Play(&clock, 0.5);
  EXPECT_EQ(clock.Report().state, CounterClockState::kFault);
  box.Play(&clock, 1.0);
  EXPECT_EQ(clock.Report().state, CounterClockState::kOk);
}

TEST(CounterClockTest, BackwardsIsAFault) {
  CounterClock clock(CounterClockOptions{});
  SyntheticBox box(1000.0, 7000.0, 8);
  box.Play(&clock, 1.0);
  box.Jump(-700);
  box.Play(&clock, 0.01);
  EXPECT_EQ(clock.Report().state, CounterClockState::kFault);
  EXPECT_THAT(clock.Report().problem, HasSubstr("went backwards by"));
}

TEST(CounterClockTest, AStallIsAFault) {
  CounterClock clock(CounterClockOptions{});
  SyntheticBox box(1000.0, 7000.0, 9);
  box.Play(&clock, 1.0);
  box.Freeze();
  box.Play(&clock, 0.05);
  EXPECT_NE(clock.Report().state, CounterClockState::kFault);
  box.Play(&clock, 0.2);
  EXPECT_EQ(clock.Report().state, CounterClockState::kFault);
  EXPECT_THAT(clock.Report().problem, HasSubstr("stalled"));
}

TEST(CounterClockTest, BadOptionsAreRejected) {
  CounterClockOptions options;
  options.expected_rate_hz = -1.0;
  EXPECT_FALSE(CounterClock::Validate(options).ok());
  options.expected_rate_hz = std::nan("");
  EXPECT_FALSE(CounterClock::Validate(options).ok());
  options = CounterClockOptions();
  options.tolerance = 1.5;
  EXPECT_FALSE(CounterClock::Validate(options).ok());
  options = CounterClockOptions();
  options.window_s = 0.1;
  EXPECT_FALSE(CounterClock::Validate(options).ok());
  EXPECT_TRUE(CounterClock::Validate(CounterClockOptions()).ok());
}

}  // namespace
}  // namespace bitewise::netft
