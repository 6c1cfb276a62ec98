#include "services/robot/netft/counter_clock.h"

#include <cmath>
#include <limits>
#include <utility>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"

namespace bitewise::netft {
namespace {

// Sensor times need some rate while one is being learned; the Net F/T's.
constexpr double kNominalRateHz = 7000.0;
// How often (arrival time) the window's rate is re-measured.
constexpr double kEvaluateEveryS = 0.05;

}  // namespace

const char* CounterClockStateName(CounterClockState state) {
  switch (state) {
    case CounterClockState::kVerifying:
      return "verifying";
    case CounterClockState::kOk:
      return "ok";
    case CounterClockState::kFault:
      return "fault";
  }
  return "unknown";
}

absl::Status CounterClock::Validate(const CounterClockOptions& options) {
  if (!std::isfinite(options.expected_rate_hz) ||
      options.expected_rate_hz < 0.0) {
    return absl::InvalidArgumentError(absl::StrCat(
        "ft_sequence rate must be positive (or 0 to learn it), got ",
        options.expected_rate_hz));
  }
  if (!(options.tolerance > 0.0 && options.tolerance < 1.0)) {
    return absl::InvalidArgumentError(
        absl::StrCat("ft_sequence rate tolerance must be in (0, 1), got ",
                     options.tolerance));
  }
  if (!(options.min_window_s > 0.0 &&
        options.window_s >= options.min_window_s && options.max_step_s > 0.0)) {
    return absl::InvalidArgumentError(
        "ft_sequence check windows must be positive, with window_s >= "
        "min_window_s");
  }
  return absl::OkStatus();
}

CounterClock::CounterClock(const CounterClockOptions& options)
    : options_(options) {}

void CounterClock::Restart() {
  points_.clear();
  have_point_ = false;
  measured_rate_hz_ = 0.0;
}

double CounterClock::rate_in_use_hz() const {
  if (options_.expected_rate_hz > 0.0) return options_.expected_rate_hz;
  return learned_rate_hz_ > 0.0 ? learned_rate_hz_ : kNominalRateHz;
}

void CounterClock::Fault(double arrival_s, std::string problem) {
  faulted_ = true;
  fault_arrival_s_ = arrival_s;
  fault_problem_ = std::move(problem);
  // The rate is measured afresh from records after the fault (the last
  // measurement stays in reports until then).
  points_.clear();
}

void CounterClock::Observe(double arrival_s, int64_t delta_ticks) {
  if (!have_point_) {
    have_point_ = true;
    last_arrival_s_ = arrival_s;
    last_advance_s_ = arrival_s;
    last_evaluate_s_ = arrival_s;
    points_.push_back({arrival_s, ticks_});
    return;
  }
  const double reference_hz = options_.expected_rate_hz > 0.0
                                  ? options_.expected_rate_hz
                                  : learned_rate_hz_;
  if (delta_ticks < 0) {
    Fault(arrival_s, absl::StrCat("ft_sequence went backwards by ",
                                  -delta_ticks, " counts"));
  } else if (delta_ticks == 0) {
    if (arrival_s - last_advance_s_ > options_.max_step_s) {
      Fault(arrival_s,
            absl::StrFormat("ft_sequence stalled: no advance in %.0f ms while "
                            "records kept arriving",
                            1e3 * (arrival_s - last_advance_s_)));
    }
  } else {
    const double gap_s = arrival_s - last_arrival_s_;
    if (reference_hz > 0.0 &&
        delta_ticks / reference_hz > gap_s + options_.max_step_s) {
      Fault(arrival_s,
            absl::StrFormat("ft_sequence jumped by %d counts (%.3f s at %.0f "
                            "Hz) between records %.0f ms apart",
                            delta_ticks, delta_ticks / reference_hz,
                            reference_hz, 1e3 * gap_s));
    }
    last_advance_s_ = arrival_s;
  }
  ticks_ += delta_ticks;
  last_arrival_s_ = arrival_s;
  points_.push_back({arrival_s, ticks_});
  while (arrival_s - points_.front().arrival_s > options_.window_s) {
    points_.pop_front();
  }
  if (arrival_s - last_evaluate_s_ >= kEvaluateEveryS) {
    last_evaluate_s_ = arrival_s;
    Evaluate(arrival_s);
  }
}

void CounterClock::Evaluate(double arrival_s) {
  const double span_s = points_.back().arrival_s - points_.front().arrival_s;
  if (options_.expected_rate_hz <= 0.0 && learned_rate_hz_ <= 0.0) {
    // Learning: a full window, first with the plain end-to-end rate as the
    // envelope's reference, then the envelope's own.
    if (span_s < options_.window_s * 0.95) return;
    const double crude_hz =
        (points_.back().ticks - points_.front().ticks) / span_s;
    if (!(crude_hz > 0.0)) return;
    learned_rate_hz_ = MeasuredRate(crude_hz);
    if (!(learned_rate_hz_ > 0.0)) learned_rate_hz_ = 0.0;
    return;
  }
  const double reference_hz = rate_in_use_hz();
  const double measured_hz = MeasuredRate(reference_hz);
  if (measured_hz <= 0.0) return;  // too few records since the last fault
  measured_rate_hz_ = measured_hz;
  if (std::abs(measured_rate_hz_ / reference_hz - 1.0) > options_.tolerance) {
    Fault(arrival_s,
          absl::StrFormat(
              "ft_sequence advances at %.0f Hz but %.0f Hz is %s "
              "(tolerance %.0f%%)",
              measured_rate_hz_, reference_hz,
              options_.expected_rate_hz > 0.0 ? "configured" : "learned",
              100.0 * options_.tolerance));
    return;
  }
  if (faulted_ && arrival_s - fault_arrival_s_ >= options_.window_s) {
    faulted_ = false;
    fault_problem_.clear();
  }
}

double CounterClock::MeasuredRate(double reference_hz) const {
  if (points_.size() < 3) return 0.0;
  const double first_s = points_.front().arrival_s;
  const double span_s = points_.back().arrival_s - first_s;
  if (span_s < options_.min_window_s) return 0.0;
  // The least-delayed record of the oldest and of the newest third.
  const Point* oldest = nullptr;
  const Point* newest = nullptr;
  double oldest_offset = std::numeric_limits<double>::infinity();
  double newest_offset = std::numeric_limits<double>::infinity();
  for (const Point& p : points_) {
    const double offset = p.arrival_s - p.ticks / reference_hz;
    if (p.arrival_s <= first_s + span_s / 3.0) {
      if (offset < oldest_offset) {
        oldest_offset = offset;
        oldest = &p;
      }
    } else if (p.arrival_s >= first_s + 2.0 * span_s / 3.0) {
      if (offset < newest_offset) {
        newest_offset = offset;
        newest = &p;
      }
    }
  }
  if (oldest == nullptr || newest == nullptr) return 0.0;
  const double dt_s = newest->arrival_s - oldest->arrival_s;
  if (!(dt_s > 0.0)) return 0.0;
  return (newest->ticks - oldest->ticks) / dt_s;
}

CounterClockReport CounterClock::Report() const {
  CounterClockReport report;
  report.rate_hz = options_.expected_rate_hz > 0.0 ? options_.expected_rate_hz
                                                   : learned_rate_hz_;
  report.measured_rate_hz = measured_rate_hz_;
  if (faulted_) {
    report.state = CounterClockState::kFault;
    report.problem =
        absl::StrCat(fault_problem_, "; sample times cannot be trusted until ",
                     absl::StrFormat("%.1f", options_.window_s),
                     " s of records agree with the rate");
    return report;
  }
  if (report.rate_hz <= 0.0) {
    report.state = CounterClockState::kVerifying;
    report.problem = absl::StrFormat(
        "learning the ft_sequence rate (needs %.1f s of records)",
        options_.window_s);
    return report;
  }
  if (measured_rate_hz_ <= 0.0) {
    report.state = CounterClockState::kVerifying;
    report.problem = absl::StrFormat(
        "verifying the ft_sequence rate (needs %.1f s of records)",
        options_.min_window_s);
    return report;
  }
  report.state = CounterClockState::kOk;
  return report;
}

}  // namespace bitewise::netft
