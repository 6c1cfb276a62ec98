#include "services/common/readiness_monitor.h"

#include <cstdio>
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

LoggedReadiness LogReadiness(std::string program,
                             std::function<absl::Status()> check,
                             std::function<void(bool)> set_serving,
                             std::string again) {
  // live() and set_serving() run one after the other on the monitor's
  // thread: the reason is passed between them here.
  auto why_not = std::make_shared<std::string>();
  LoggedReadiness out;
  out.live = [check = std::move(check), why_not] {
    const absl::Status status = check();
    *why_not = std::string(status.message());
    return status.ok();
  };
  out.set_serving =
      [program = std::move(program), set_serving = std::move(set_serving),
       why_not, again = std::move(again), first = true](bool serving) mutable {
        set_serving(serving);
        if (!first || !serving) {
          if (serving) {
            std::fprintf(stderr, "%s: health SERVING%s\n", program.c_str(),
                         again.c_str());
          } else {
            std::fprintf(stderr, "%s: health NOT_SERVING: %s\n",
                         program.c_str(), why_not->c_str());
          }
          std::fflush(stderr);
        }
        first = false;
      };
  return out;
}

ReadinessMonitor::~ReadinessMonitor() {
  {
    absl::MutexLock lock(&mu_);
    stop_ = true;
  }
  thread_.join();
}

}  // namespace bitewise
