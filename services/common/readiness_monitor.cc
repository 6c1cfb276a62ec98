#include "services/common/readiness_monitor.h"

#include <utility>

#include "absl/time/time.h"

namespace bitewise {

ReadinessMonitor::ReadinessMonitor(std::function<bool()> live,
                                   std::function<void(bool)> set_serving,
                                   double period_s) {
  thread_ = std::thread([this, live = std::move(live),
                         set_serving = std::move(set_serving), period_s] {
    bool first = true;
    bool last = false;
    absl::MutexLock lock(&mu_);
    while (!stop_) {
      recheck_ = false;
      const bool now = live();
      if (first || now != last) set_serving(now);
      first = false;
      last = now;
      mu_.AwaitWithTimeout(absl::Condition(&WakeUp, this),
                           absl::Seconds(period_s));
    }
  });
}

bool ReadinessMonitor::WakeUp(ReadinessMonitor* monitor) {
  return monitor->stop_ || monitor->recheck_;
}

void ReadinessMonitor::Recheck() {
  absl::MutexLock lock(&mu_);
  recheck_ = true;
}

ReadinessMonitor::~ReadinessMonitor() {
  {
    absl::MutexLock lock(&mu_);
    stop_ = true;
  }
  thread_.join();
}

}  // namespace bitewise
