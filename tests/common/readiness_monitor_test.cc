// ReadinessMonitor (services/common/readiness_monitor.h) on its own real
// thread: the first state is reported at once and later only changes, a
// Recheck() polls without waiting out the period, and destruction stops it.
#include "services/common/readiness_monitor.h"

#include <atomic>
#include <memory>
#include <vector>

#include "absl/synchronization/mutex.h"
#include "absl/time/clock.h"
#include "absl/time/time.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace bitewise {
namespace {

using ::testing::ElementsAre;

// What the monitor saw and said, shared with its thread.
class Probe {
 public:
  bool Live() {
    ++polls_;
    return live_.load();
  }
  void SetServing(bool serving) {
    absl::MutexLock lock(&mu_);
    reports_.push_back(serving);
  }
  void set_live(bool live) { live_ = live; }
  int polls() const { return polls_.load(); }
  std::vector<bool> reports() {
    absl::MutexLock lock(&mu_);
    return reports_;
  }
  // Waits up to `timeout` for the `n`-th report.
  bool AwaitReports(size_t n, absl::Duration timeout) {
    absl::MutexLock lock(&mu_);
    auto enough = [this, n]() ABSL_SHARED_LOCKS_REQUIRED(mu_) {
      return reports_.size() >= n;
    };
    return mu_.AwaitWithTimeout(absl::Condition(&enough), timeout);
  }

 private:
  std::atomic<bool> live_{false};
  std::atomic<int> polls_{0};
  absl::Mutex mu_;
  std::vector<bool> reports_ ABSL_GUARDED_BY(mu_);
};

TEST(ReadinessMonitorTest, ReportsTheFirstStateAtOnceThenOnlyItsChanges) {
  Probe probe;
  ReadinessMonitor monitor([&probe] { return probe.Live(); },
                           [&probe](bool s) { probe.SetServing(s); },
                           /*period_s=*/0.005);
  ASSERT_TRUE(probe.AwaitReports(1, absl::Seconds(10)));
  // Many polls of an unchanged state say nothing more.
  const absl::Time deadline = absl::Now() + absl::Seconds(10);
  while (probe.polls() < 10 && absl::Now() < deadline) {
    absl::SleepFor(absl::Milliseconds(5));
  }
  ASSERT_GE(probe.polls(), 10);
  EXPECT_THAT(probe.reports(), ElementsAre(false));

  probe.set_live(true);
  ASSERT_TRUE(probe.AwaitReports(2, absl::Seconds(10)));
  probe.set_live(false);
  ASSERT_TRUE(probe.AwaitReports(3, absl::Seconds(10)));
  absl::SleepFor(absl::Milliseconds(50));
  EXPECT_THAT(probe.reports(), ElementsAre(false, true, false));
}

TEST(ReadinessMonitorTest, ARecheckPollsWithoutWaitingOutThePeriod) {
  Probe probe;
  probe.set_live(true);
  // A period no test waits out: only Recheck() can bring the next poll.
  ReadinessMonitor monitor([&probe] { return probe.Live(); },
                           [&probe](bool s) { probe.SetServing(s); },
                           /*period_s=*/3600.0);
  ASSERT_TRUE(probe.AwaitReports(1, absl::Seconds(10)));
  probe.set_live(false);
  absl::SleepFor(absl::Milliseconds(50));
  EXPECT_THAT(probe.reports(), ElementsAre(true));
  EXPECT_EQ(probe.polls(), 1);

  monitor.Recheck();
  ASSERT_TRUE(probe.AwaitReports(2, absl::Seconds(10)));
  EXPECT_THAT(probe.reports(), ElementsAre(true, false));
  EXPECT_EQ(probe.polls(), 2);
}

TEST(ReadinessMonitorTest, DestructionStopsItWithoutWaitingOutThePeriod) {
  Probe probe;
  auto monitor = std::make_unique<ReadinessMonitor>(
      [&probe] { return probe.Live(); },
      [&probe](bool s) { probe.SetServing(s); }, /*period_s=*/3600.0);
  ASSERT_TRUE(probe.AwaitReports(1, absl::Seconds(10)));
  const absl::Time start = absl::Now();
  monitor.reset();
  EXPECT_LT(absl::Now() - start, absl::Seconds(5));
  const int polls = probe.polls();
  probe.set_live(true);
  absl::SleepFor(absl::Milliseconds(50));
  EXPECT_EQ(probe.polls(), polls);
  EXPECT_THAT(probe.reports(), ElementsAre(false));
}

}  // namespace
}  // namespace bitewise
