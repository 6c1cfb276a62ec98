// SimNetFtBox: a simulated ATI Net F/T box, a real UDP server on loopback
// that answers the RDT protocol (start, stop, software bias) and streams
// 36-byte records at a configurable rate up to 7 kHz. Its wrench comes from
// a WrenchSource (the simulated world: the force-trace model with contact
// timing from the simulated arm), plus sensor noise and bias. Fault switches
// (packet loss, reordering, silence, bias drift) are seeded, so tests of the
// production NetFtRdtClient repeat.
//
// Thread-safe: one thread serves; setters may be called from any thread.
#ifndef BITEWISE_SERVICES_ROBOT_SIM_SIM_NETFT_BOX_H_
#define BITEWISE_SERVICES_ROBOT_SIM_SIM_NETFT_BOX_H_

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "absl/base/thread_annotations.h"
#include "absl/status/statusor.h"
#include "absl/synchronization/mutex.h"
#include "services/sim/force_trace.h"

namespace bitewise::sim {

// What the sensor physically feels at a time on SteadyNowS(), before
// noise, bias and tare. Called from the box's thread only, with
// non-decreasing times.
class WrenchSource {
 public:
  virtual ~WrenchSource() = default;
  virtual Wrench WrenchAt(double time_s) = 0;
};

struct SimNetFtBoxOptions {
  // Loopback by default; port 0 picks a free port (see port()).
  std::string host = "127.0.0.1";
  uint16_t port = 0;
  // Records per second, at most the internal rate.
  double rate_hz = 1000.0;
  // The rate at which ft_sequence advances, as on the real box. Equal to
  // rate_hz, it advances once per record (as some firmware does).
  double internal_rate_hz = 7000.0;
  // ft_sequence at boot: near 2^32 to test the counter's wrap.
  uint32_t ft_sequence_at_boot = 0;
  double counts_per_force = 1e6;
  double counts_per_torque = 1e6;
  // White noise and a constant bias (SensorNoise::bias, plus a random one
  // of random_bias_n drawn once at start), as in the force-trace model.
  SensorNoise noise;
  uint64_t seed = 1;
};

struct SimNetFtFaults {
  double loss_probability = 0.0;     // each record dropped independently
  double reorder_probability = 0.0;  // a record held back behind the next
  bool silent = false;  // sends nothing; rdt_sequence does not advance
  // Added to Fz (and, scaled, Fx, Fy) per second while set.
  double bias_drift_n_per_s = 0.0;
  // Counter faults: ft_sequence stops advancing while records still flow;
  // or is shifted by this many counts (set mid-stream: a jump; negative:
  // backwards).
  bool counter_frozen = false;
  int64_t counter_offset_counts = 0;
  // Sent as every record's status word (non-zero: the box reports a
  // fault, e.g. a saturated gauge).
  uint32_t status_word = 0;
  // The gauges are no longer read: records keep flowing with advancing
  // counters and a clean status word, but repeat the last readings exactly
  // (a frozen amplifier, a transducer cable pulled at the box).
  bool readings_frozen = false;
  // A load on the fork (N, along the sensor's z) that the world does not
  // know of: someone pressing the fork, or an unexpected obstacle.
  double press_n = 0.0;
};

struct SimNetFtCounters {
  uint64_t requests = 0;  // valid requests received
  uint64_t malformed_requests = 0;
  uint64_t records_sent = 0;     // datagrams that left the socket
  uint64_t records_dropped = 0;  // lost on purpose (loss fault)
  uint64_t records_reordered = 0;
  uint64_t bias_commands = 0;
  uint32_t last_rdt_sequence = 0;  // of the last record generated
  bool streaming = false;
  // rdt_sequence of every dropped record, for exact checks in tests.
  std::vector<uint32_t> dropped_sequences;
};

class SimNetFtBox {
 public:
  // Binds the socket and starts serving. `source` may be null (no load) and
  // must outlive the box. Errors: INVALID_ARGUMENT for a rate outside
  // (0, internal_rate_hz] or non-positive counts; UNAVAILABLE if the address
  // cannot be bound.
  static absl::StatusOr<std::unique_ptr<SimNetFtBox>> Start(
      const SimNetFtBoxOptions& options, WrenchSource* source);
  ~SimNetFtBox();
  SimNetFtBox(const SimNetFtBox&) = delete;
  SimNetFtBox& operator=(const SimNetFtBox&) = delete;

  uint16_t port() const { return port_; }
  const SimNetFtBoxOptions& options() const { return options_; }

  void SetFaults(const SimNetFtFaults& faults);
  SimNetFtFaults faults() const;
  SimNetFtCounters counters() const;

 private:
  SimNetFtBox(const SimNetFtBoxOptions& options, WrenchSource* source, int fd,
              uint16_t port);
  void Serve();
  void HandleRequests(double now_s);
  void Stream(double now_s);
  void SendRecord(const uint8_t* bytes);

  const SimNetFtBoxOptions options_;
  WrenchSource* const source_;
  const int fd_;
  const uint16_t port_;
  std::atomic<bool> stop_{false};
  std::thread server_;

  mutable absl::Mutex mu_;
  SimNetFtFaults faults_ ABSL_GUARDED_BY(mu_);
  SimNetFtCounters counters_ ABSL_GUARDED_BY(mu_);
  Wrench tare_ ABSL_GUARDED_BY(mu_);
  Wrench drift_ ABSL_GUARDED_BY(mu_);
  // Streaming state: only the server thread touches these.
  bool streaming_ = false;
  uint32_t remaining_ = 0;  // records left; 0 with `unlimited_` streams on
  bool unlimited_ = true;
  std::vector<uint8_t> client_addr_;
  uint32_t rdt_sequence_ = 0;
  double stream_start_s_ = 0.0;
  uint64_t next_k_ = 0;       // index of the next record in time
  double boot_time_s_ = 0.0;  // ft_sequence counts from here
  double last_drift_s_ = 0.0;
  uint32_t last_ft_sequence_ = 0;
  std::array<int32_t, 6> last_counts_{};  // of the last record made
  Wrench last_clean_;  // the last noise-free reading (for bias)
  Wrench bias_;
  std::vector<uint8_t> held_;  // a record held back for reordering
  std::mt19937_64 noise_rng_;
  std::mt19937_64 fault_rng_;
};

}  // namespace bitewise::sim

#endif  // BITEWISE_SERVICES_ROBOT_SIM_SIM_NETFT_BOX_H_
