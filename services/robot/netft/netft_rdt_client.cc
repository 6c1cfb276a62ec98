#include "services/robot/netft/netft_rdt_client.h"

#include <netdb.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/types.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <utility>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "services/domain/steady_time.h"

namespace bitewise::netft {
namespace {

constexpr int kWindow = 64;  // sequence numbers remembered for reordering
constexpr double kRateWindowS = 0.5;

absl::StatusOr<sockaddr_in> Resolve(const std::string& host, uint16_t port) {
  addrinfo hints{};
  hints.ai_family = AF_INET;
  hints.ai_socktype = SOCK_DGRAM;
  addrinfo* result = nullptr;
  const int rc = getaddrinfo(host.c_str(), nullptr, &hints, &result);
  if (rc != 0 || result == nullptr) {
    return absl::InvalidArgumentError(absl::StrCat(
        "Net F/T host \"", host, "\" does not resolve: ", gai_strerror(rc)));
  }
  sockaddr_in addr = *reinterpret_cast<sockaddr_in*>(result->ai_addr);
  freeaddrinfo(result);
  addr.sin_port = htons(port);
  return addr;
}

}  // namespace

const char* StreamStateName(StreamState state) {
  switch (state) {
    case StreamState::kWaitingForData:
      return "waiting for data";
    case StreamState::kStreaming:
      return "streaming";
    case StreamState::kSilent:
      return "silent";
  }
  return "unknown";
}

absl::StatusOr<std::unique_ptr<NetFtRdtClient>> NetFtRdtClient::Connect(
    const NetFtRdtClientOptions& options) {
  // A reading is an int32 count over the calibration. The force's range
  // must cover kMinForceRangeN, or a fork pressed harder than that reads a
  // saturated count and no force limit (the largest is 25 N) could be
  // judged; and a count must resolve at least kMaxForceStepN, a tenth of
  // the 1 N contact threshold. (ATI ships 1,000,000 counts per N.)
  constexpr double kMaxCount = 2147483647.0;
  constexpr double kMinForceRangeN = 50.0;
  constexpr double kMaxForceStepN = 0.1;
  if (!(options.counts_per_force >= 1.0 / kMaxForceStepN &&
        options.counts_per_force <= kMaxCount / kMinForceRangeN) ||
      !(options.counts_per_torque > 0.0 &&
        std::isfinite(options.counts_per_torque))) {
    return absl::InvalidArgumentError(absl::StrCat(
        "counts_per_force must be between ",
        static_cast<int64_t>(1.0 / kMaxForceStepN), " and ",
        static_cast<int64_t>(kMaxCount / kMinForceRangeN),
        " (a count of at most 0.1 N; a range of at least 50 N), and "
        "counts_per_torque positive and finite; got ",
        options.counts_per_force, " and ", options.counts_per_torque));
  }
  if (absl::Status valid = CounterClock::Validate(options.counter);
      !valid.ok()) {
    return valid;
  }
  if (!(options.silence_timeout_s > 0.0) || options.history_capacity == 0) {
    return absl::InvalidArgumentError(
        "silence_timeout_s and history_capacity must be positive");
  }
  if (!(options.frozen_after_s >= 0.0) ||
      !std::isfinite(options.frozen_after_s)) {
    return absl::InvalidArgumentError(absl::StrCat(
        "frozen_after_s must be >= 0 (0: off), got ", options.frozen_after_s));
  }
  absl::StatusOr<sockaddr_in> addr = Resolve(options.host, options.port);
  if (!addr.ok()) return addr.status();
  const int fd = socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  if (fd < 0) {
    return absl::UnavailableError(
        absl::StrCat("Net F/T socket: ", std::strerror(errno)));
  }
  // Bursts of several hundred records arrive when this process is
  // descheduled for a few ms at 7 kHz.
  int buffer_bytes = 1 << 20;
  setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &buffer_bytes, sizeof(buffer_bytes));
  // Connected, so only the box's datagrams are received.
  if (connect(fd, reinterpret_cast<const sockaddr*>(&*addr), sizeof(*addr)) !=
      0) {
    const std::string error = std::strerror(errno);
    close(fd);
    return absl::UnavailableError(absl::StrCat(
        "Net F/T sensor at ", options.host, ":", options.port, ": ", error));
  }
  std::unique_ptr<NetFtRdtClient> client(new NetFtRdtClient(
      options, fd,
      absl::StrCat("Net F/T sensor at ", options.host, ":", options.port)));
  absl::Status sent =
      client->Send({RdtCommand::kStartRealTimeStreaming, /*sample_count=*/0});
  if (!sent.ok()) return sent;
  client->receiver_ = std::thread([c = client.get()] { c->ReceiveLoop(); });
  return client;
}

NetFtRdtClient::NetFtRdtClient(const NetFtRdtClientOptions& options, int fd,
                               std::string name)
    : options_(options),
      fd_(fd),
      name_(std::move(name)),
      connect_time_s_(SteadyNowS()),
      clock_(options.counter) {
  last_restart_s_ = connect_time_s_;
}

NetFtRdtClient::~NetFtRdtClient() {
  // Best effort: a box left streaming keeps flooding the link.
  Send({RdtCommand::kStopStreaming, 0}).IgnoreError();
  stop_ = true;
  if (receiver_.joinable()) receiver_.join();
  close(fd_);
}

absl::Status NetFtRdtClient::Send(const RdtRequest& request) {
  const std::array<uint8_t, kRdtRequestBytes> bytes = EncodeRdtRequest(request);
  const ssize_t sent = send(fd_, bytes.data(), bytes.size(), 0);
  if (sent != static_cast<ssize_t>(bytes.size())) {
    return absl::UnavailableError(
        absl::StrCat(name_, ": sending a request failed: ",
                     sent < 0 ? std::strerror(errno) : "short write"));
  }
  return absl::OkStatus();
}

absl::Status NetFtRdtClient::Bias() {
  return Send({RdtCommand::kSetSoftwareBias, 0});
}

void NetFtRdtClient::ReceiveLoop() {
  std::array<uint8_t, 2048> buffer;
  while (!stop_) {
    pollfd pfd{fd_, POLLIN, 0};
    poll(&pfd, 1, /*timeout_ms=*/10);
    const double now_s = SteadyNowS();
    absl::MutexLock lock(&mu_);
    while (true) {
      const ssize_t n = recv(fd_, buffer.data(), buffer.size(), MSG_DONTWAIT);
      if (n < 0) break;  // EAGAIN, or ECONNREFUSED while no box listens
      HandleDatagram(buffer.data(), static_cast<size_t>(n), now_s);
    }
    const double last = have_sequence_ ? last_sample_time_s_ : connect_time_s_;
    if (now_s - last > options_.silence_timeout_s &&
        now_s - last_restart_s_ > options_.restart_interval_s) {
      // A rebooted box has forgotten us; ask again. The sequence restarts.
      last_restart_s_ = now_s;
      ++stats_.restarts;
      have_sequence_ = false;
      const auto bytes =
          EncodeRdtRequest({RdtCommand::kStartRealTimeStreaming, 0});
      send(fd_, bytes.data(), bytes.size(), MSG_DONTWAIT);
    }
  }
}

void NetFtRdtClient::HandleDatagram(const uint8_t* data, size_t size,
                                    double now_s) {
  ++stats_.packets_received;
  absl::StatusOr<RdtRecord> record =
      DecodeRdtRecord(absl::MakeConstSpan(data, size));
  if (!record.ok()) {
    ++stats_.malformed;
    return;
  }
  if (!have_sequence_) {
    // A new stream: fix the host times of the old one first.
    for (FtSample& old : history_) {
      if (old.index >= first_index_of_stream_) old = Stamped(old);
    }
    first_index_of_stream_ = next_index_;
    have_sequence_ = true;
    last_rdt_sequence_ = record->rdt_sequence;
    seen_mask_ = 1;
    last_ft_sequence_ = record->ft_sequence;
    ft_ticks_ = 0;
    host_offset_s_ = now_s;
    clock_.Restart();
    clock_.Observe(now_s, 0);
  } else {
    const int32_t ahead =
        static_cast<int32_t>(record->rdt_sequence - last_rdt_sequence_);
    if (ahead <= 0) {
      const int age = ahead == INT32_MIN ? kWindow : -ahead;
      ++stats_.stale_dropped;
      if (age < kWindow && (seen_mask_ >> age) & 1) {
        ++stats_.duplicates;
      } else {
        ++stats_.out_of_order;
        if (age < kWindow) {
          seen_mask_ |= uint64_t{1} << age;
          if (stats_.packets_lost > 0) --stats_.packets_lost;
        }
      }
      return;
    }
    stats_.packets_lost += static_cast<uint64_t>(ahead - 1);
    stats_.packets_skipped += static_cast<uint64_t>(ahead - 1);
    seen_mask_ = ahead >= kWindow ? 0 : seen_mask_ << ahead;
    seen_mask_ |= 1;
    last_rdt_sequence_ = record->rdt_sequence;
    // A signed difference, so the u32 counter may wrap.
    const int32_t delta =
        static_cast<int32_t>(record->ft_sequence - last_ft_sequence_);
    ft_ticks_ += delta;
    last_ft_sequence_ = record->ft_sequence;
    clock_.Observe(now_s, delta);
  }
  if (record->status != 0) {
    ++stats_.status_errors;
    last_fault_status_ = record->status;
    last_fault_s_ = now_s;
  }
  stats_.last_status = record->status;
  if (stats_.samples_accepted > 0 && record->counts == last_counts_) {
    ++unchanged_records_;
  } else {
    last_counts_ = record->counts;
    counts_changed_s_ = now_s;
    unchanged_records_ = 0;
  }

  FtSample sample;
  sample.index = next_index_++;
  sample.arrival_s = now_s;
  sample.ticks = ft_ticks_;
  host_offset_s_ =
      std::min(host_offset_s_, now_s - static_cast<double>(ft_ticks_) /
                                           clock_.rate_in_use_hz());
  sample.rdt_sequence = record->rdt_sequence;
  sample.ft_sequence = record->ft_sequence;
  sample.status = record->status;
  for (int i = 0; i < 3; ++i) {
    sample.wrench.force_n[i] = record->counts[i] / options_.counts_per_force;
    sample.wrench.torque_nm[i] =
        record->counts[3 + i] / options_.counts_per_torque;
  }
  ++stats_.samples_accepted;
  last_sample_time_s_ = now_s;
  history_.push_back(sample);
  while (history_.size() > options_.history_capacity) history_.pop_front();
}

FtSample NetFtRdtClient::Stamped(const FtSample& sample) const {
  FtSample out = sample;
  if (sample.index >= first_index_of_stream_) {
    out.sensor_time_s =
        static_cast<double>(sample.ticks) / clock_.rate_in_use_hz();
    out.host_time_s = out.sensor_time_s + host_offset_s_;
  }
  return out;
}

StreamHealth NetFtRdtClient::Health() const {
  const double now_s = SteadyNowS();
  absl::MutexLock lock(&mu_);
  StreamHealth health;
  if (stats_.samples_accepted == 0) {
    health.state = StreamState::kWaitingForData;
    health.silent_for_s = now_s - connect_time_s_;
  } else {
    health.silent_for_s = now_s - last_sample_time_s_;
    health.state = health.silent_for_s > options_.silence_timeout_s
                       ? StreamState::kSilent
                       : StreamState::kStreaming;
  }
  int in_window = 0;
  for (auto it = history_.rbegin(); it != history_.rend(); ++it) {
    if (it->arrival_s < now_s - kRateWindowS) break;
    ++in_window;
  }
  health.rate_hz = in_window / kRateWindowS;
  health.counter = clock_.Report();
  if (stats_.samples_accepted > 0) {
    health.readings_unchanged_s = last_sample_time_s_ - counts_changed_s_;
    health.readings_unchanged_records = unchanged_records_;
  }
  return health;
}

absl::Status NetFtRdtClient::CheckLive() const {
  const StreamHealth health = Health();
  switch (health.state) {
    case StreamState::kWaitingForData:
      return absl::UnavailableError(
          absl::StrFormat("%s has sent no data in %.0f ms since connecting",
                          name_, 1e3 * health.silent_for_s));
    case StreamState::kSilent:
      return absl::UnavailableError(absl::StrFormat(
          "%s is silent: no data for %.0f ms (timeout %.0f ms)", name_,
          1e3 * health.silent_for_s, 1e3 * options_.silence_timeout_s));
    case StreamState::kStreaming:
      break;
  }
  return CheckDuringMotion();
}

absl::Status NetFtRdtClient::CheckDuringMotion() const {
  absl::MutexLock lock(&mu_);
  if (stats_.last_status != 0) {
    return absl::UnavailableError(absl::StrFormat(
        "%s reports fault status 0x%08x", name_, stats_.last_status));
  }
  // A fault the box flagged and cleared between two checks (the control
  // loop looks every 10 ms, the box sends up to 7 records a millisecond)
  // is not forgotten: the stream must run without one for kFaultHoldS.
  constexpr double kFaultHoldS = 1.0;
  if (last_sample_time_s_ - last_fault_s_ < kFaultHoldS) {
    return absl::UnavailableError(absl::StrFormat(
        "%s reported fault status 0x%08x %.0f ms ago; it must stream "
        "without a fault for %.0f ms",
        name_, last_fault_status_, 1e3 * (last_sample_time_s_ - last_fault_s_),
        1e3 * kFaultHoldS));
  }
  const CounterClockReport counter = clock_.Report();
  if (counter.state != CounterClockState::kOk) {
    return absl::UnavailableError(absl::StrCat(name_, ": ", counter.problem));
  }
  const double unchanged_s = last_sample_time_s_ - counts_changed_s_;
  if (options_.frozen_after_s > 0.0 &&
      unchanged_records_ + 1 >= static_cast<uint64_t>(kMinFrozenRecords) &&
      unchanged_s >= options_.frozen_after_s) {
    return absl::UnavailableError(absl::StrFormat(
        "%s: all six readings identical in the last %d records (%.0f ms): "
        "the gauges are not being read (a frozen amplifier, or the "
        "transducer cable at the box), so there is no force protection",
        name_, unchanged_records_ + 1, 1e3 * unchanged_s));
  }
  return absl::OkStatus();
}

RdtStats NetFtRdtClient::stats() const {
  absl::MutexLock lock(&mu_);
  return stats_;
}

std::optional<FtSample> NetFtRdtClient::Latest() const {
  absl::MutexLock lock(&mu_);
  if (history_.empty()) return std::nullopt;
  return Stamped(history_.back());
}

uint64_t NetFtRdtClient::SamplesSince(uint64_t from,
                                      std::vector<FtSample>* out) const {
  absl::MutexLock lock(&mu_);
  if (history_.empty()) return std::max(from, next_index_);
  const uint64_t oldest = history_.front().index;
  for (uint64_t i = std::max(from, oldest); i < next_index_; ++i) {
    out->push_back(Stamped(history_[i - oldest]));
  }
  return std::max(from, next_index_);
}

}  // namespace bitewise::netft
