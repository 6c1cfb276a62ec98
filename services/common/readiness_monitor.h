// ReadinessMonitor: makes a service's gRPC health status follow real
// readiness. It polls `live` (the F/T stream is sane, the database file is
// still the one opened, ...) and reports every change to `set_serving`, the
// first at once. Stops on destruction. Thread-safe.
#ifndef BITEWISE_SERVICES_COMMON_READINESS_MONITOR_H_
#define BITEWISE_SERVICES_COMMON_READINESS_MONITOR_H_

#include <functional>
#include <memory>
#include <string>
#include <thread>

#include "absl/base/thread_annotations.h"
#include "absl/status/status.h"
#include "absl/synchronization/mutex.h"

namespace bitewise {

class ReadinessMonitor {
 public:
  ReadinessMonitor(std::function<bool()> live,
                   std::function<void(bool)> set_serving,
                   double period_s = 0.05);
  ~ReadinessMonitor();

  // Polls now instead of at the end of the period (e.g. a failure that
  // `live` will report has just been seen). Returns once asked; the poll
  // runs on the monitor's thread.
  void Recheck() ABSL_LOCKS_EXCLUDED(mu_);
  ReadinessMonitor(const ReadinessMonitor&) = delete;
  ReadinessMonitor& operator=(const ReadinessMonitor&) = delete;

 private:
  absl::Mutex mu_;
  static bool WakeUp(ReadinessMonitor* monitor)
      ABSL_EXCLUSIVE_LOCKS_REQUIRED(monitor->mu_);
  bool stop_ ABSL_GUARDED_BY(mu_) = false;
  bool recheck_ ABSL_GUARDED_BY(mu_) = false;
  std::thread thread_;
};

// A ReadinessMonitor's two functions from a check that says why a service
// is not ready: the state is `check` being OK, and every change of it is
// logged to stderr for the engineer on call ("<program>: health
// NOT_SERVING: <why>", "<program>: health SERVING<again>"), except a first
// SERVING (the service's own start line says it). `check` and
// `set_serving` run on the monitor's thread.
struct LoggedReadiness {
  std::function<bool()> live;
  std::function<void(bool)> set_serving;
};
LoggedReadiness LogReadiness(std::string program,
                             std::function<absl::Status()> check,
                             std::function<void(bool)> set_serving,
                             std::string again = "");

}  // namespace bitewise

#endif  // BITEWISE_SERVICES_COMMON_READINESS_MONITOR_H_
