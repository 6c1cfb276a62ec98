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
      const bool now = live();
      if (first || now != last) set_serving(now);
      first = false;
      last = now;
      mu_.AwaitWithTimeout(absl::Condition(&stop_), absl::Seconds(period_s));
    }
  });
}

ReadinessMonitor::~ReadinessMonitor() {
  {
    absl::MutexLock lock(&mu_);
    stop_ = true;
  }
  thread_.join();
}

}  // namespace bitewise
