#include "services/camera/frame_publisher.h"

#include <utility>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/time/clock.h"
#include "absl/time/time.h"

namespace bitewise::camera {
namespace {

constexpr absl::Duration kRetryInterval = absl::Milliseconds(100);

}  // namespace

FramePublisher::FramePublisher(std::unique_ptr<FrameSource> source)
    : source_(std::move(source)), name_(source_->name()) {
  thread_ = std::thread([this] { Run(); });
}

FramePublisher::~FramePublisher() {
  stop_ = true;
  thread_.join();
}

void FramePublisher::Run() {
  bool ended = false;
  while (!stop_) {
    if (ended) {  // a finished recording: the newest frame just ages
      absl::SleepFor(absl::Milliseconds(20));
      continue;
    }
    const absl::Time asked = absl::Now();
    absl::StatusOr<domain::RgbdFrame> frame = source_->Next();
    if (!frame.ok()) {
      {
        absl::MutexLock lock(&mu_);
        last_error_ = frame.status().ToString();
      }
      ended = absl::IsOutOfRange(frame.status());
      // A device that fails fast (a camera unplugged, whatever the error's
      // code) must not spin the core: at most ten tries a second.
      const absl::Duration spent = absl::Now() - asked;
      if (!ended && spent < kRetryInterval) {
        absl::SleepFor(kRetryInterval - spent);
      }
      continue;
    }
    auto shared = std::make_shared<const domain::RgbdFrame>(*std::move(frame));
    absl::MutexLock lock(&mu_);
    if (newest_ != nullptr && shared->sequence > newest_->sequence + 1) {
      dropped_ += shared->sequence - newest_->sequence - 1;
    }
    ++captured_;
    newest_ = std::move(shared);
    last_error_.clear();
  }
}

absl::StatusOr<PublishedFrame> FramePublisher::Newest(double max_age_s) const {
  std::shared_ptr<const domain::RgbdFrame> newest;
  PublishedFrame out;
  std::string last_error;
  {
    absl::MutexLock lock(&mu_);
    newest = newest_;
    out.frames_captured = captured_;
    out.frames_dropped = dropped_;
    last_error = last_error_;
  }
  const std::string why =
      last_error.empty() ? "" : absl::StrCat("; last error: ", last_error);
  if (newest == nullptr) {
    return absl::UnavailableError(
        absl::StrCat("camera ", name_, " has sent no frame yet", why));
  }
  out.age_s = SteadyNowS() - newest->capture_s;
  if (max_age_s > 0.0 && out.age_s > max_age_s) {
    return absl::FailedPreconditionError(absl::StrFormat(
        "the newest frame from camera %s is %.2f s old (limit %.2f s): the "
        "camera has stopped or stalled%s",
        name_, out.age_s, max_age_s, why));
  }
  out.frame = *newest;
  return out;
}

PublisherCounters FramePublisher::Counters() const {
  absl::MutexLock lock(&mu_);
  PublisherCounters c;
  c.frames_captured = captured_;
  c.frames_dropped = dropped_;
  c.newest_age_s = newest_ ? SteadyNowS() - newest_->capture_s : -1.0;
  c.last_error = last_error_;
  return c;
}

}  // namespace bitewise::camera
