// FtRecorder without an arm or a socket: the force the limit acts on comes
// from every sample received, whatever its time stamp; the baseline from
// arrival times; the trace stays strictly increasing; contact and static
// load.
#include "services/robot/ft_recorder.h"

#include <vector>

#include "gtest/gtest.h"

namespace bitewise::robot {
namespace {

netft::FtSample Sample(uint64_t index, double arrival_s, double sensor_s,
                       double fz_n, double fx_n = 0.0) {
  netft::FtSample s;
  s.index = index;
  s.arrival_s = arrival_s;
  s.sensor_time_s = sensor_s;
  s.host_time_s = sensor_s + 100.0;  // the host clock's offset
  s.wrench.force_n = {fx_n, 0.0, fz_n};
  return s;
}

TEST(FtRecorderTest, BaselineIsTheMeanOfWhatArrivedJustBefore) {
  FtRecorder recorder(0.5);
  // Arrived 0.3 s, 0.05 s and 0.01 s before the start at t = 10 s.
  recorder.Start({Sample(0, 9.7, 0.0, 9.0), Sample(1, 9.95, 0.1, 1.0),
                  Sample(2, 9.99, 0.2, 3.0)},
                 10.0, /*baseline_s=*/0.1);
  EXPECT_DOUBLE_EQ(recorder.baseline().force_n[2], 2.0);
  FtRecorder stale(0.5);  // nothing recent: the last sample
  stale.Start({Sample(0, 1.0, 0.0, 7.0)}, 10.0, 0.1);
  EXPECT_DOUBLE_EQ(stale.baseline().force_n[2], 7.0);
  FtRecorder empty(0.5);
  empty.Start({}, 10.0, 0.1);
  EXPECT_DOUBLE_EQ(empty.baseline().force_n[2], 0.0);
}

// The defect this guards against: a box whose counter ran slower than
// configured made every sample look older than the acquisition, and the
// limit saw no force at all.
TEST(FtRecorderTest, TheLimitSeesEverySampleWhateverItsTimeStamp) {
  FtRecorder recorder(0.5);
  recorder.Start({Sample(0, 9.99, 50.0, 0.0)}, 10.0, 0.1);
  // Sensor times that stall, go backwards and lie far in the past.
  recorder.Add({Sample(1, 10.001, 50.0, 2.0), Sample(2, 10.002, 49.0, 40.0),
                Sample(3, 10.003, -1000.0, 3.0)});
  EXPECT_DOUBLE_EQ(recorder.TakeMaxForceSinceLastCall(), 40.0);
  EXPECT_DOUBLE_EQ(recorder.peak_force_n(), 40.0);
  EXPECT_DOUBLE_EQ(recorder.last_force_n(), 3.0);
  // Each period starts afresh.
  EXPECT_DOUBLE_EQ(recorder.TakeMaxForceSinceLastCall(), 0.0);
  recorder.Add({Sample(4, 10.004, 50.1, 5.0)});
  EXPECT_DOUBLE_EQ(recorder.TakeMaxForceSinceLastCall(), 5.0);
  // The trace keeps only strictly increasing times.
  const std::vector<domain::TimedWrench>& trace = recorder.trace();
  ASSERT_EQ(trace.size(), 2u);
  EXPECT_LT(trace[0].t_s, trace[1].t_s);
}

TEST(FtRecorderTest, ForceIsMeasuredFromTheBaselineInEveryDirection) {
  FtRecorder recorder(0.5);
  recorder.Start({Sample(0, 9.99, 0.0, -5.0)}, 10.0, 0.1);
  recorder.Add({Sample(1, 10.0, 0.001, -5.0, 3.0)});  // 3 N sideways
  EXPECT_DOUBLE_EQ(recorder.TakeMaxForceSinceLastCall(), 3.0);
  recorder.Add({Sample(2, 10.0, 0.002, -9.0)});  // 4 N along z
  EXPECT_DOUBLE_EQ(recorder.TakeMaxForceSinceLastCall(), 4.0);
}

TEST(FtRecorderTest, TraceTimeContactAndStaticLoad) {
  FtRecorder recorder(0.5);
  recorder.Start({Sample(0, 9.99, 4.99, 1.0)}, 10.0, 0.1);
  std::vector<netft::FtSample> fresh;
  for (int i = 1; i <= 100; ++i) {
    // Contact from sample 40 on; a load of 0.2 N hanging after sample 80.
    const double fz = i >= 80 ? 0.8 : (i >= 40 ? 3.0 : 1.0);
    fresh.push_back(Sample(i, 10.0 + i * 1e-3, 5.0 + i * 1e-3, fz));
  }
  recorder.Add(fresh);
  // Trace time = host time of the first sample minus the start, then the
  // sensor's own spacing: host 105.001 - 10 = 95.001 at sample 1.
  ASSERT_EQ(recorder.trace().size(), 100u);
  EXPECT_NEAR(recorder.trace().front().t_s, 95.001, 1e-9);
  EXPECT_NEAR(recorder.contact_time_s(), 95.040, 1e-9);
  EXPECT_NEAR(recorder.StaticLoad(95.080), 0.2, 1e-12);
  EXPECT_DOUBLE_EQ(recorder.StaticLoad(1e9), 0.0);  // nothing that late
}

}  // namespace
}  // namespace bitewise::robot
