// NetFtRdtClient: the production driver of the "Forque", an ATI Nano25 on the
// fork read through an ATI Net F/T box over its UDP RDT protocol. It asks the
// box to stream, converts counts to newtons and newton-metres with the
// box's counts-per-force and counts-per-torque, tracks RDT sequence numbers
// (lost, out-of-order, duplicate and stale packets are counted; stale ones
// are dropped), stamps each sample with sensor time from ft_sequence,
// checks that counter against the host's clock (CounterClock: a wrong rate,
// a stalled, jumping or backwards counter is a fault, never a quiet skew),
// and tells a silent sensor apart from merely stale data. Safety code (the
// acquisition watchdog) builds on CheckLive().
//
// Thread-safe. One background thread receives; every accessor may be called
// from any thread.
#ifndef BITEWISE_SERVICES_ROBOT_NETFT_NETFT_RDT_CLIENT_H_
#define BITEWISE_SERVICES_ROBOT_NETFT_NETFT_RDT_CLIENT_H_

#include <array>
#include <atomic>
#include <cstdint>
#include <deque>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "absl/base/thread_annotations.h"
#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/synchronization/mutex.h"
#include "services/domain/wrench.h"
#include "services/robot/netft/counter_clock.h"
#include "services/robot/netft/rdt_protocol.h"

namespace bitewise::netft {

using Wrench = domain::Wrench;

struct FtSample {
  // Monotonic index over the client's lifetime (see SamplesSince()).
  uint64_t index = 0;
  // When the datagram was received, on SteadyNowS(). Independent of the
  // counter, so safety code never depends on the counter's rate.
  double arrival_s = 0.0;
  // ft_sequence unwrapped, relative to the first record of this stream.
  int64_t ticks = 0;
  // `ticks` turned into seconds at the counter's rate (configured or
  // learned), so samples keep the sensor's own spacing whatever the
  // network did.
  double sensor_time_s = 0.0;
  // The same instant on SteadyNowS(): sensor time plus the smallest
  // receive-time offset seen in this stream (the least delayed packet), as
  // known when the sample is read, so samples keep their sensor spacing.
  double host_time_s = 0.0;
  uint32_t rdt_sequence = 0;
  uint32_t ft_sequence = 0;
  uint32_t status = 0;
  Wrench wrench;
};

struct NetFtRdtClientOptions {
  // The box's address. 192.168.1.1 is the Net F/T factory default.
  std::string host = "192.168.1.1";
  uint16_t port = kRdtPort;
  // From the box's configuration page (Counts per Force / per Torque): raw
  // counts per N and per N·m. 1e6 is the factory setting for a Nano25.
  double counts_per_force = 1e6;
  double counts_per_torque = 1e6;
  // The rate at which ft_sequence advances (the box's internal sample rate,
  // 7000 Hz by default on the Net F/T; 0 learns it) and how it is checked
  // against arrival times. See CounterClockOptions.
  CounterClockOptions counter;
  // No accepted sample for this long means the sensor is silent.
  double silence_timeout_s = 0.05;
  // All six raw readings identical for this long (by arrival time) and for
  // at least kMinFrozenRecords records in a row means the gauges are not
  // being read: a live transducer's noise moves the counts of every new
  // internal sample (at the factory 1e6 counts per N, 0.01 N of noise is
  // 10,000 counts); a box streaming faster than it samples repeats a sample
  // in a record or two, never for 0.1 s.
  // 0 turns the check off.
  double frozen_after_s = 0.1;
  // While silent, the start request is sent again this often, so a box that
  // rebooted resumes streaming by itself.
  double restart_interval_s = 1.0;
  // Samples kept for SamplesSince(): at 7 kHz, 2^16 is about 9 s.
  size_t history_capacity = size_t{1} << 16;
};

// Fewer identical records in a row are never called frozen (a slow stream).
inline constexpr int kMinFrozenRecords = 10;

// Everything counted since Connect().
struct RdtStats {
  uint64_t packets_received = 0;  // every datagram, valid or not
  uint64_t samples_accepted = 0;  // newer than all before: delivered
  // Sequence numbers skipped and not (yet) seen. A packet that arrives late
  // is taken off again: it was reordered, not lost.
  uint64_t packets_lost = 0;
  // Sequence numbers skipped, each counted once when skipped and never
  // taken off (a counter: packets_lost can go down).
  uint64_t packets_skipped = 0;
  uint64_t out_of_order = 0;   // arrived after a later one
  uint64_t duplicates = 0;     // the same rdt_sequence twice
  uint64_t stale_dropped = 0;  // not newer than the latest: never delivered
  uint64_t malformed = 0;      // not a 36-byte record
  uint64_t status_errors = 0;  // records with a non-zero status word
  uint64_t restarts = 0;       // start requests re-sent while silent
  uint32_t last_status = 0;
};

enum class StreamState {
  kWaitingForData,  // started, nothing received yet
  kStreaming,
  kSilent,  // data stopped for longer than silence_timeout_s
};
const char* StreamStateName(StreamState state);

struct StreamHealth {
  StreamState state = StreamState::kWaitingForData;
  // Since the last accepted sample (or since Connect() when none).
  double silent_for_s = 0.0;
  // Accepted samples per second over the last half second (arrival times).
  double rate_hz = 0.0;
  // The ft_sequence counter checked against arrival times.
  CounterClockReport counter;
  // How long (arrival times) and for how many records in a row the six
  // readings have not changed: a live sensor's stay near 0.
  double readings_unchanged_s = 0.0;
  uint64_t readings_unchanged_records = 0;
};

class NetFtRdtClient {
 public:
  // Opens a UDP socket to the box, sends the start-streaming request
  // (sample count 0: until stopped) and starts receiving. Returns as soon as
  // the request is sent; data may not have arrived yet (see Health()).
  // Errors: INVALID_ARGUMENT for non-positive counts or rates or an
  // unresolvable host; UNAVAILABLE if the socket cannot be set up.
  static absl::StatusOr<std::unique_ptr<NetFtRdtClient>> Connect(
      const NetFtRdtClientOptions& options);

  // Sends the stop request and joins the receiver.
  ~NetFtRdtClient();
  NetFtRdtClient(const NetFtRdtClient&) = delete;
  NetFtRdtClient& operator=(const NetFtRdtClient&) = delete;

  // "Net F/T sensor at host:port": how errors name the sensor.
  const std::string& name() const { return name_; }
  const NetFtRdtClientOptions& options() const { return options_; }

  // Sends the software-bias command: the box zeroes its output at the load
  // it measures now. RDT has no acknowledgement; UNAVAILABLE if the send
  // fails.
  absl::Status Bias();

  // Sends a request of any kind, for tools and tests (e.g. a finite sample
  // count). UNAVAILABLE if the send fails.
  absl::Status Send(const RdtRequest& request);

  // OK while samples arrive with a trustworthy counter; UNAVAILABLE naming
  // the sensor when it is silent, has not sent anything yet, reports a
  // non-zero status word, its ft_sequence counter is still being verified
  // or in fault (the message gives measured and expected rates), or its
  // readings are frozen (frozen_after_s).
  absl::Status CheckLive() const;

  // CheckLive() without the silence checks, for the control loop, which
  // applies its own watchdog: UNAVAILABLE naming the sensor while the box
  // reports a fault status word, the counter is not verified sane, or the
  // readings are frozen.
  absl::Status CheckDuringMotion() const;

  StreamHealth Health() const;
  RdtStats stats() const;
  std::optional<FtSample> Latest() const;

  // Appends to `out` every kept sample with index >= `from`, oldest first,
  // and returns the index to pass next time. Samples older than the history
  // are gone; the caller sees that as a jump in `index`.
  uint64_t SamplesSince(uint64_t from, std::vector<FtSample>* out) const;

 private:
  NetFtRdtClient(const NetFtRdtClientOptions& options, int fd,
                 std::string name);
  void ReceiveLoop();
  void HandleDatagram(const uint8_t* data, size_t size, double now_s)
      ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_);
  // `sample` as a reader sees it: host time from the current offset.
  FtSample Stamped(const FtSample& sample) const
      ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_);

  const NetFtRdtClientOptions options_;
  const int fd_;
  const std::string name_;
  const double connect_time_s_;
  std::atomic<bool> stop_{false};
  std::thread receiver_;

  mutable absl::Mutex mu_;
  RdtStats stats_ ABSL_GUARDED_BY(mu_);
  std::deque<FtSample> history_ ABSL_GUARDED_BY(mu_);
  uint64_t next_index_ ABSL_GUARDED_BY(mu_) = 0;
  // Sequence tracking. Bit i of `seen_mask_` is set when rdt_sequence
  // last_rdt_sequence_ - i has arrived.
  bool have_sequence_ ABSL_GUARDED_BY(mu_) = false;
  uint32_t last_rdt_sequence_ ABSL_GUARDED_BY(mu_) = 0;
  uint64_t seen_mask_ ABSL_GUARDED_BY(mu_) = 0;
  // ft_sequence unwrapped to 64 bits, relative to the first record.
  uint32_t last_ft_sequence_ ABSL_GUARDED_BY(mu_) = 0;
  int64_t ft_ticks_ ABSL_GUARDED_BY(mu_) = 0;
  double host_offset_s_ ABSL_GUARDED_BY(mu_) = 0.0;
  CounterClock clock_ ABSL_GUARDED_BY(mu_);
  // Samples of earlier streams (before a restart) have their host time
  // fixed; those with index >= first_index_of_stream_ use host_offset_s_.
  uint64_t first_index_of_stream_ ABSL_GUARDED_BY(mu_) = 0;
  double last_sample_time_s_ ABSL_GUARDED_BY(mu_) = 0.0;
  double last_restart_s_ ABSL_GUARDED_BY(mu_) = 0.0;
  // The last accepted record's raw readings; when they last changed
  // (arrival time) and how many records since repeated them exactly.
  std::array<int32_t, 6> last_counts_ ABSL_GUARDED_BY(mu_){};
  double counts_changed_s_ ABSL_GUARDED_BY(mu_) = 0.0;
  // The last record with a non-zero status word, and when it arrived: a
  // fault flagged between two checks, then cleared, still counts for
  // kFaultHoldS.
  uint32_t last_fault_status_ ABSL_GUARDED_BY(mu_) = 0;
  double last_fault_s_ ABSL_GUARDED_BY(mu_) = -1e300;
  uint64_t unchanged_records_ ABSL_GUARDED_BY(mu_) = 0;
};

}  // namespace bitewise::netft

#endif  // BITEWISE_SERVICES_ROBOT_NETFT_NETFT_RDT_CLIENT_H_
