// FtRecorder: the force/torque bookkeeping of one acquisition, apart from
// the control loop so it can be tested without an arm: the unloaded
// baseline, the force that the force limit and contact detection act on,
// the peak, the trace HapticNet gets, and the static load after the lift.
//
// Safety never depends on time stamps: every sample handed to Add() counts
// for the force limit and the peak, in arrival order, whatever its sensor
// or host time (a box whose counter runs at another rate than configured
// must not blind the limit). Only the trace needs times that strictly
// increase; a sample whose time does not is left out of the trace alone.
//
// Thread-compatible.
#ifndef BITEWISE_SERVICES_ROBOT_FT_RECORDER_H_
#define BITEWISE_SERVICES_ROBOT_FT_RECORDER_H_

#include <vector>

#include "services/domain/wrench.h"
#include "services/robot/netft/netft_rdt_client.h"

namespace bitewise::robot {

class FtRecorder {
 public:
  // |F - baseline| above `contact_threshold_n` is contact.
  explicit FtRecorder(double contact_threshold_n);

  // The acquisition starts at `start_s` (SteadyNowS()). The baseline is the
  // mean of the samples in `recent` that arrived in the `baseline_s` before
  // it (arrival times: independent of the sensor's counter), or the last
  // of `recent` when none did, or zero when `recent` is empty.
  void Start(const std::vector<netft::FtSample>& recent, double start_s,
             double baseline_s);

  // Samples received since the last call, in arrival order.
  void Add(const std::vector<netft::FtSample>& fresh);

  // The largest |F - baseline| of the samples added since the last call
  // (0 if none), for one control period's force-limit check.
  double TakeMaxForceSinceLastCall();

  double last_force_n() const { return last_force_n_; }
  double peak_force_n() const { return peak_force_n_; }
  // Trace time of the first sample above the contact threshold; -1: none.
  double contact_time_s() const { return contact_time_s_; }
  const netft::Wrench& baseline() const { return baseline_; }
  const std::vector<domain::TimedWrench>& trace() const { return trace_; }
  std::vector<domain::TimedWrench> TakeTrace() { return std::move(trace_); }

  // Weight on the fork: the drop of Fz below the baseline, averaged over
  // the trace from `from_s` on (0 without samples there).
  double StaticLoad(double from_s) const;

 private:
  const double contact_threshold_n_;
  double start_s_ = 0.0;
  netft::Wrench baseline_;
  // Trace time = sensor time + this, fixed at the first sample: the
  // client's host-time offset can still shrink as less delayed packets
  // arrive, and the trace must stay on the sensor's own clock.
  double trace_offset_s_ = 0.0;
  bool have_offset_ = false;
  double last_force_n_ = 0.0;
  double max_force_since_call_ = 0.0;
  double peak_force_n_ = 0.0;
  double contact_time_s_ = -1.0;
  std::vector<domain::TimedWrench> trace_;
};

}  // namespace bitewise::robot

#endif  // BITEWISE_SERVICES_ROBOT_FT_RECORDER_H_
