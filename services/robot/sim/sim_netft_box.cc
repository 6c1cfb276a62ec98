#include "services/robot/sim/sim_netft_box.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <limits>

#include "absl/strings/str_cat.h"
#include "services/domain/random.h"
#include "services/domain/steady_time.h"
#include "services/robot/netft/rdt_protocol.h"

namespace bitewise::sim {
namespace {

// More records than this due at one wake-up means the box thread was starved;
// the backlog is skipped (time moves on) instead of flooding the client.
constexpr uint64_t kMaxBurst = 2000;

int32_t ToCounts(double value, double counts_per_unit) {
  const double counts = std::round(value * counts_per_unit);
  return static_cast<int32_t>(
      std::clamp(counts, double{std::numeric_limits<int32_t>::min()},
                 double{std::numeric_limits<int32_t>::max()}));
}

}  // namespace

absl::StatusOr<std::unique_ptr<SimNetFtBox>> SimNetFtBox::Start(
    const SimNetFtBoxOptions& options, WrenchSource* source) {
  if (!(options.rate_hz > 0.0) ||
      !(options.rate_hz <= options.internal_rate_hz)) {
    return absl::InvalidArgumentError(
        absl::StrCat("simulated Net F/T rate_hz must be in (0, ",
                     options.internal_rate_hz, "], got ", options.rate_hz));
  }
  if (!(options.counts_per_force > 0.0) || !(options.counts_per_torque > 0.0)) {
    return absl::InvalidArgumentError(
        "simulated Net F/T counts per force and torque must be positive");
  }
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(options.port);
  if (inet_pton(AF_INET, options.host.c_str(), &addr.sin_addr) != 1) {
    return absl::InvalidArgumentError(
        absl::StrCat("simulated Net F/T host must be an IPv4 address, got \"",
                     options.host, "\""));
  }
  const int fd = socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return absl::UnavailableError(std::strerror(errno));
  int buffer_bytes = 1 << 20;
  setsockopt(fd, SOL_SOCKET, SO_SNDBUF, &buffer_bytes, sizeof(buffer_bytes));
  socklen_t len = sizeof(addr);
  if (bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)) != 0 ||
      getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len) != 0) {
    const std::string error = std::strerror(errno);
    close(fd);
    return absl::UnavailableError(
        absl::StrCat("simulated Net F/T box cannot bind ", options.host, ":",
                     options.port, ": ", error));
  }
  std::unique_ptr<SimNetFtBox> box(
      new SimNetFtBox(options, source, fd, ntohs(addr.sin_port)));
  box->server_ = std::thread([b = box.get()] { b->Serve(); });
  return box;
}

SimNetFtBox::SimNetFtBox(const SimNetFtBoxOptions& options,
                         WrenchSource* source, int fd, uint16_t port)
    : options_(options),
      source_(source),
      fd_(fd),
      port_(port),
      noise_rng_(options.seed),
      fault_rng_(options.seed ^ 0x9e3779b97f4a7c15ULL) {
  boot_time_s_ = SteadyNowS();
  bias_ = options.noise.bias;
  if (options.noise.random_bias_n > 0.0) {
    const double b = options.noise.random_bias_n;
    for (int i = 0; i < 3; ++i) {
      bias_.force_n[i] += b * random::Uniform(noise_rng_, -1.0, 1.0);
      bias_.torque_nm[i] += 0.02 * b * random::Uniform(noise_rng_, -1.0, 1.0);
    }
  }
}

SimNetFtBox::~SimNetFtBox() {
  stop_ = true;
  if (server_.joinable()) server_.join();
  close(fd_);
}

void SimNetFtBox::SetFaults(const SimNetFtFaults& faults) {
  absl::MutexLock lock(&mu_);
  faults_ = faults;
}

SimNetFtFaults SimNetFtBox::faults() const {
  absl::MutexLock lock(&mu_);
  return faults_;
}

SimNetFtCounters SimNetFtBox::counters() const {
  absl::MutexLock lock(&mu_);
  SimNetFtCounters counters = counters_;
  return counters;
}

void SimNetFtBox::Serve() {
  while (!stop_) {
    // 1 ms wake-ups: records due in between go out as a burst with their
    // own timestamps, which is what a 7 kHz box looks like after any
    // scheduler delay anyway.
    pollfd pfd{fd_, POLLIN, 0};
    poll(&pfd, 1, /*timeout_ms=*/1);
    const double now_s = SteadyNowS();
    HandleRequests(now_s);
    if (streaming_) Stream(now_s);
  }
}

void SimNetFtBox::HandleRequests(double now_s) {
  while (true) {
    uint8_t buffer[64];
    sockaddr_storage from{};
    socklen_t from_len = sizeof(from);
    const ssize_t n = recvfrom(fd_, buffer, sizeof(buffer), MSG_DONTWAIT,
                               reinterpret_cast<sockaddr*>(&from), &from_len);
    if (n < 0) return;
    absl::StatusOr<netft::RdtRequest> request = netft::DecodeRdtRequest(
        absl::MakeConstSpan(buffer, static_cast<size_t>(n)));
    absl::MutexLock lock(&mu_);
    if (!request.ok()) {
      ++counters_.malformed_requests;
      continue;
    }
    ++counters_.requests;
    switch (request->command) {
      case netft::RdtCommand::kStartRealTimeStreaming:
        // As on the real box, a start request (re)starts the sequence and
        // streams to whoever asked.
        streaming_ = true;
        unlimited_ = request->sample_count == 0;
        remaining_ = request->sample_count;
        client_addr_.assign(reinterpret_cast<uint8_t*>(&from),
                            reinterpret_cast<uint8_t*>(&from) + from_len);
        rdt_sequence_ = 0;
        stream_start_s_ = now_s;
        next_k_ = 0;
        last_drift_s_ = now_s;
        held_.clear();
        counters_.streaming = true;
        break;
      case netft::RdtCommand::kStopStreaming:
        streaming_ = false;
        held_.clear();
        counters_.streaming = false;
        break;
      case netft::RdtCommand::kSetSoftwareBias:
        ++counters_.bias_commands;
        // Zero the output at the current load, drift included.
        for (int i = 0; i < 3; ++i) {
          tare_.force_n[i] =
              last_clean_.force_n[i] + bias_.force_n[i] + drift_.force_n[i];
          tare_.torque_nm[i] = last_clean_.torque_nm[i] + bias_.torque_nm[i];
        }
        break;
    }
  }
}

void SimNetFtBox::SendRecord(const uint8_t* bytes) {
  const ssize_t sent =
      sendto(fd_, bytes, netft::kRdtRecordBytes, MSG_DONTWAIT,
             reinterpret_cast<const sockaddr*>(client_addr_.data()),
             static_cast<socklen_t>(client_addr_.size()));
  if (sent == static_cast<ssize_t>(netft::kRdtRecordBytes)) {
    ++counters_.records_sent;
  }
}

void SimNetFtBox::Stream(double now_s) {
  const double period_s = 1.0 / options_.rate_hz;
  uint64_t due = static_cast<uint64_t>((now_s - stream_start_s_) / period_s);
  if (due >= next_k_ + kMaxBurst) next_k_ = due - kMaxBurst / 2;
  random::Normal normal;
  absl::MutexLock lock(&mu_);
  for (; next_k_ <= due && streaming_; ++next_k_) {
    const double t_s = stream_start_s_ + next_k_ * period_s;
    const double drift_dt = std::max(0.0, t_s - last_drift_s_);
    last_drift_s_ = std::max(last_drift_s_, t_s);
    if (faults_.bias_drift_n_per_s != 0.0) {
      // A fixed direction, mostly axial, like thermal drift of the gauges.
      const double step = faults_.bias_drift_n_per_s * drift_dt;
      drift_.force_n[0] += 0.3 * step;
      drift_.force_n[1] -= 0.2 * step;
      drift_.force_n[2] += step;
    }
    // Time passes for the sensor even while the box is silent.
    if (faults_.silent) continue;
    last_clean_ = source_ != nullptr ? source_->WrenchAt(t_s) : Wrench();
    netft::RdtRecord record;
    record.rdt_sequence = ++rdt_sequence_;
    if (!faults_.counter_frozen) {
      last_ft_sequence_ = static_cast<uint32_t>(
          options_.ft_sequence_at_boot +
          static_cast<uint64_t>(
              std::llround((t_s - boot_time_s_) * options_.internal_rate_hz) +
              faults_.counter_offset_counts));
    }
    record.ft_sequence = last_ft_sequence_;
    record.status = faults_.status_word;
    for (int i = 0; i < 3; ++i) {
      const double f = last_clean_.force_n[i] + bias_.force_n[i] +
                       drift_.force_n[i] - tare_.force_n[i] +
                       (i == 2 ? faults_.press_n : 0.0) +
                       options_.noise.force_sd_n * normal(noise_rng_);
      const double tq = last_clean_.torque_nm[i] + bias_.torque_nm[i] -
                        tare_.torque_nm[i] +
                        options_.noise.torque_sd_nm * normal(noise_rng_);
      record.counts[i] = ToCounts(f, options_.counts_per_force);
      record.counts[3 + i] = ToCounts(tq, options_.counts_per_torque);
    }
    if (faults_.readings_frozen) {
      for (int i = 0; i < 6; ++i) record.counts[i] = last_counts_[i];
    }
    for (int i = 0; i < 6; ++i) last_counts_[i] = record.counts[i];
    counters_.last_rdt_sequence = record.rdt_sequence;
    const auto bytes = netft::EncodeRdtRecord(record);
    if (faults_.loss_probability > 0.0 &&
        random::Canonical(fault_rng_) < faults_.loss_probability) {
      ++counters_.records_dropped;
      counters_.dropped_sequences.push_back(record.rdt_sequence);
    } else if (held_.empty() && faults_.reorder_probability > 0.0 &&
               random::Canonical(fault_rng_) < faults_.reorder_probability) {
      held_.assign(bytes.begin(), bytes.end());
      ++counters_.records_reordered;
    } else {
      SendRecord(bytes.data());
      if (!held_.empty()) {
        SendRecord(held_.data());
        held_.clear();
      }
    }
    if (!unlimited_ && --remaining_ == 0) {
      if (!held_.empty()) {
        SendRecord(held_.data());
        held_.clear();
      }
      streaming_ = false;
      counters_.streaming = false;
    }
  }
}

}  // namespace bitewise::sim
