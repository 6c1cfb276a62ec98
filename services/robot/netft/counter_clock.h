// CounterClock: checks the Net F/T box's ft_sequence counter against the
// host's clock, so that sample times derived from it can be trusted, and
// says loudly when they cannot.
//
// ATI documents ft_sequence as counting at the box's internal sample rate,
// but that rate is a box setting and firmware differs; a driver that
// assumes the wrong rate stamps every sample with the wrong time. Sample
// times feed the trace HapticNet sees and the host-time mapping, so a wrong
// rate must stop the robot, not quietly skew the data. The clock:
//  - uses a configured rate, or learns one from arrival times (rate 0);
//  - measures the counter rate continuously over a sliding window of
//    arrival times, from the least-delayed record in each half of the
//    window (network and scheduler delays only ever add to arrival times,
//    so the lower envelope is what the sensor's clock looks like);
//  - flags a counter that goes backwards, stalls (no advance while arrival
//    time moves on) or jumps (advances by much more time than arrived);
//  - stays in fault until a full window of clean records has passed.
//
// Not thread-safe: the NetFtRdtClient calls it under its own lock.
#ifndef BITEWISE_SERVICES_ROBOT_NETFT_COUNTER_CLOCK_H_
#define BITEWISE_SERVICES_ROBOT_NETFT_COUNTER_CLOCK_H_

#include <cstdint>
#include <deque>
#include <string>

#include "absl/status/status.h"

namespace bitewise::netft {

struct CounterClockOptions {
  // The rate at which ft_sequence advances, in Hz. 0 learns it from the
  // arrival times of the first `window_s` of records, then checks it like a
  // configured one. Default: 7000 Hz, the Net F/T's documented rate.
  double expected_rate_hz = 7000.0;
  // Largest allowed |measured / expected - 1|. Default 0.2: arrival jitter
  // on a loaded machine costs a few per cent; a wrong box setting is off by
  // a factor (1 kHz against 7 kHz is -86%).
  double tolerance = 0.2;
  // Arrival time over which the rate is measured (default 1 s), and the
  // least of it needed before a verdict (default 0.5 s).
  double window_s = 1.0;
  double min_window_s = 0.5;
  // One record's counter advance may exceed its arrival gap by at most this
  // (default 0.1 s); more is a jump. A counter that does not advance while
  // this much arrival time passes has stalled.
  double max_step_s = 0.1;
};

enum class CounterClockState {
  kVerifying,  // not enough records yet (or too soon after a fault)
  kOk,
  kFault,
};
const char* CounterClockStateName(CounterClockState state);

struct CounterClockReport {
  CounterClockState state = CounterClockState::kVerifying;
  // The rate in use: configured, or learned (0 while learning).
  double rate_hz = 0.0;
  // Measured over the current window; 0 before min_window_s of records.
  double measured_rate_hz = 0.0;
  // Why the clock is in fault or still verifying (empty when kOk).
  std::string problem;
};

class CounterClock {
 public:
  // INVALID_ARGUMENT for a negative or non-finite rate, a tolerance outside
  // (0, 1) or windows that are not positive and ordered.
  static absl::Status Validate(const CounterClockOptions& options);

  explicit CounterClock(const CounterClockOptions& options);

  // A new stream starts (the box restarted its sequence): forgets the
  // measurements; a learned rate is kept.
  void Restart();

  // One accepted record: its arrival time on the host's steady clock and
  // how far ft_sequence moved since the previous record (as a signed 32-bit
  // difference, so the u32 counter may wrap). The first record of a stream
  // passes 0.
  void Observe(double arrival_s, int64_t delta_ticks);

  // The verdict now. Cheap enough for every control period.
  CounterClockReport Report() const;

  // The rate used to turn ticks into seconds: configured, learned, or
  // (while learning) the nominal 7 kHz.
  double rate_in_use_hz() const;

 private:
  struct Point {
    double arrival_s;
    int64_t ticks;
  };
  void Fault(double arrival_s, std::string problem);
  // Learns the rate, or re-measures it and faults on a mismatch.
  void Evaluate(double arrival_s);
  // Envelope rate over `points_` against `reference_hz`; 0 if too short.
  double MeasuredRate(double reference_hz) const;

  const CounterClockOptions options_;
  double learned_rate_hz_ = 0.0;
  double measured_rate_hz_ = 0.0;
  double last_evaluate_s_ = 0.0;
  std::deque<Point> points_;
  int64_t ticks_ = 0;
  bool have_point_ = false;
  double last_arrival_s_ = 0.0;
  // Arrival time of the last counter advance (for stalls).
  double last_advance_s_ = 0.0;
  bool faulted_ = false;
  double fault_arrival_s_ = 0.0;
  std::string fault_problem_;
};

}  // namespace bitewise::netft

#endif  // BITEWISE_SERVICES_ROBOT_NETFT_COUNTER_CLOCK_H_
