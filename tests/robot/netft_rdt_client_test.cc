// The production NetFtRdtClient against (1) a minimal Net F/T box written
// here by hand, byte by byte, which checks exact forces, the exact request
// bytes and exact sequence accounting; and (2) the simulated box with its
// fault switches: packet loss, reordering, silence and bias drift.
#include "services/robot/netft/netft_rdt_client.h"

#include <chrono>
#include <cmath>
#include <functional>
#include <limits>
#include <memory>
#include <thread>
#include <vector>

#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "services/domain/steady_time.h"
#include "services/robot/sim/sim_netft_box.h"
#include "tests/robot/udp_test_peer.h"
#include "tests/robot/wait_for.h"

namespace bitewise::netft {
namespace {

using ::bitewise::testing::HandWrittenRecord;
using ::bitewise::testing::UdpTestPeer;
using ::testing::AllOf;
using ::testing::ElementsAre;
using ::testing::HasSubstr;

constexpr auto kReceiveTimeout = std::chrono::milliseconds(10000);

// Polls `done` for up to 20 s (the machine may be loaded).
bool WaitFor(const std::function<bool()>& done) {
  return ::bitewise::testing::WaitFor(done, 20.0);
}

class HandWrittenBoxTest : public ::testing::Test {
 protected:
  // A long restart interval by default, so no unexpected start request
  // arrives while a test waits for a specific one.
  std::unique_ptr<NetFtRdtClient> Connect(double counts_per_force = 1e6,
                                          double counts_per_torque = 1e6,
                                          double restart_interval_s = 600.0) {
    NetFtRdtClientOptions options;
    options.host = "127.0.0.1";
    options.port = box_.port();
    options.counts_per_force = counts_per_force;
    options.counts_per_torque = counts_per_torque;
    options.silence_timeout_s = 0.2;
    options.restart_interval_s = restart_interval_s;
    auto client = NetFtRdtClient::Connect(options);
    EXPECT_TRUE(client.ok()) << client.status();
    // The first thing on the wire: start streaming, count 0.
    auto request = box_.Receive(kReceiveTimeout);
    EXPECT_TRUE(request.has_value());
    if (request) {
      EXPECT_THAT(*request,
                  ElementsAre(0x12, 0x34, 0x00, 0x02, 0x00, 0x00, 0x00, 0x00));
    }
    return client.ok() ? std::move(client).value() : nullptr;
  }

  void Send(uint32_t rdt, uint32_t ft, std::array<int32_t, 6> counts = {},
            uint32_t status = 0) {
    ASSERT_TRUE(box_.SendToPeer(HandWrittenRecord(rdt, ft, status, counts)));
  }

  UdpTestPeer box_;
};

TEST_F(HandWrittenBoxTest, ForcesArriveExact) {
  auto client = Connect(/*counts_per_force=*/1e6, /*counts_per_torque=*/2e5);
  ASSERT_NE(client, nullptr);
  Send(1, 700, {1500000, -250000, 3000000, 100000, -50000, 1});
  ASSERT_TRUE(WaitFor([&] { return client->Latest().has_value(); }));
  const FtSample s = *client->Latest();
  EXPECT_EQ(s.rdt_sequence, 1u);
  EXPECT_EQ(s.ft_sequence, 700u);
  EXPECT_EQ(s.wrench.force_n[0], 1.5);
  EXPECT_EQ(s.wrench.force_n[1], -0.25);
  EXPECT_EQ(s.wrench.force_n[2], 3.0);
  EXPECT_EQ(s.wrench.torque_nm[0], 0.5);
  EXPECT_EQ(s.wrench.torque_nm[1], -0.25);
  EXPECT_EQ(s.wrench.torque_nm[2], 1.0 / 2e5);
  // One record says nothing about the counter's rate: not fit to move yet.
  EXPECT_THAT(client->CheckLive().message(),
              HasSubstr("verifying the ft_sequence rate"));
}

TEST_F(HandWrittenBoxTest, SensorTimeComesFromFtSequence) {
  auto client = Connect();
  ASSERT_NE(client, nullptr);
  // 1 kHz records from a 7 kHz sensor: ft_sequence steps by 7.
  for (uint32_t i = 0; i < 5; ++i) Send(1 + i, 1000 + 7 * i);
  ASSERT_TRUE(WaitFor([&] { return client->stats().samples_accepted == 5; }));
  std::vector<FtSample> samples;
  EXPECT_EQ(client->SamplesSince(0, &samples), 5u);
  ASSERT_EQ(samples.size(), 5u);
  for (int i = 0; i < 5; ++i) {
    EXPECT_EQ(samples[i].index, static_cast<uint64_t>(i));
    EXPECT_NEAR(samples[i].sensor_time_s, i * 0.001, 1e-12);
    EXPECT_NEAR(samples[i].host_time_s - samples[0].host_time_s, i * 0.001,
                1e-9);
  }
  // Only what is new.
  samples.clear();
  EXPECT_EQ(client->SamplesSince(3, &samples), 5u);
  EXPECT_EQ(samples.size(), 2u);
}

TEST_F(HandWrittenBoxTest, CountsLostReorderedDuplicateAndStale) {
  auto client = Connect();
  ASSERT_NE(client, nullptr);
  int sent = 0;
  auto send = [&](uint32_t rdt) {
    Send(rdt, rdt * 7);
    ++sent;
  };
  for (uint32_t rdt : {1, 2, 3, 5, 6}) send(rdt);
  ASSERT_TRUE(WaitFor([&] { return client->stats().packets_received == 5; }));
  RdtStats stats = client->stats();
  EXPECT_EQ(stats.packets_lost, 1u);  // 4
  EXPECT_EQ(stats.samples_accepted, 5u);

  send(4);   // late: reordered, not lost, and stale
  send(6);   // duplicate
  send(10);  // 7, 8, 9 lost
  send(8);   // late again
  ASSERT_TRUE(WaitFor([&] { return client->stats().packets_received == 9; }));
  stats = client->stats();
  EXPECT_EQ(stats.samples_accepted, 6u);
  EXPECT_EQ(stats.out_of_order, 2u);
  EXPECT_EQ(stats.duplicates, 1u);
  EXPECT_EQ(stats.stale_dropped, 3u);
  EXPECT_EQ(stats.packets_lost, 2u);  // 7 and 9
  EXPECT_EQ(client->Latest()->rdt_sequence, 10u);

  // Malformed datagrams are counted, not delivered.
  ASSERT_TRUE(box_.SendToPeer(std::vector<uint8_t>(35, 0)));
  ASSERT_TRUE(WaitFor([&] { return client->stats().malformed == 1; }));
  EXPECT_EQ(client->stats().samples_accepted, 6u);
}

TEST_F(HandWrittenBoxTest, SequenceWrapsAround) {
  auto client = Connect();
  ASSERT_NE(client, nullptr);
  Send(0xFFFFFFFEu, 0xFFFFFFF0u);
  Send(0xFFFFFFFFu, 0xFFFFFFF7u);
  Send(0x00000001u, 0x00000005u);  // 0 lost
  ASSERT_TRUE(WaitFor([&] { return client->stats().packets_received == 3; }));
  const RdtStats stats = client->stats();
  EXPECT_EQ(stats.samples_accepted, 3u);
  EXPECT_EQ(stats.packets_lost, 1u);
  EXPECT_NEAR(client->Latest()->sensor_time_s, 21.0 / 7000.0, 1e-12);
}

TEST_F(HandWrittenBoxTest, SilenceIsReportedApartFromStaleData) {
  auto client = Connect(1e6, 1e6, /*restart_interval_s=*/0.3);
  ASSERT_NE(client, nullptr);
  EXPECT_EQ(client->Health().state, StreamState::kWaitingForData);
  EXPECT_THAT(client->CheckLive().message(), HasSubstr("has sent no data"));
  Send(1, 7);
  Send(2, 14);
  ASSERT_TRUE(WaitFor(
      [&] { return client->Health().state == StreamState::kStreaming; }));
  // The box goes quiet.
  ASSERT_TRUE(
      WaitFor([&] { return client->Health().state == StreamState::kSilent; }));
  const absl::Status live = client->CheckLive();
  EXPECT_EQ(live.code(), absl::StatusCode::kUnavailable);
  EXPECT_THAT(live.message(),
              HasSubstr("Net F/T sensor at 127.0.0.1:" +
                        std::to_string(box_.port()) + " is silent"));
  EXPECT_EQ(client->stats().stale_dropped, 0u);
  // While silent, the client asks the box to stream again.
  auto restart = box_.Receive(kReceiveTimeout);
  ASSERT_TRUE(restart.has_value());
  EXPECT_THAT(*restart,
              ElementsAre(0x12, 0x34, 0x00, 0x02, 0x00, 0x00, 0x00, 0x00));
  EXPECT_GE(client->stats().restarts, 1u);
  // A rebooted box starts its sequence again; the client follows.
  Send(1, 3);
  Send(2, 10);
  ASSERT_TRUE(WaitFor([&] { return client->stats().samples_accepted == 4; }));
  EXPECT_EQ(client->stats().stale_dropped, 0u);
}

TEST_F(HandWrittenBoxTest, StatusWordFaultIsNotLive) {
  auto client = Connect();
  ASSERT_NE(client, nullptr);
  Send(1, 7, {}, 0x80001000u);
  ASSERT_TRUE(WaitFor([&] { return client->stats().status_errors == 1; }));
  EXPECT_THAT(client->CheckLive().message(),
              HasSubstr("fault status 0x80001000"));
}

// A fault flagged in one record and cleared in the next still stops the
// arm: the stream must run without one for a second.
TEST_F(HandWrittenBoxTest, AFaultClearedAtOnceIsStillNotLive) {
  auto client = Connect();
  ASSERT_NE(client, nullptr);
  Send(1, 7, {}, 0x80001000u);
  Send(2, 14, {}, 0);
  ASSERT_TRUE(WaitFor([&] { return client->stats().samples_accepted == 2; }));
  EXPECT_EQ(client->stats().last_status, 0u);
  EXPECT_THAT(client->CheckDuringMotion().message(),
              HasSubstr("reported fault status 0x80001000"));
  EXPECT_THAT(client->CheckLive().message(),
              HasSubstr("it must stream without a fault for 1000 ms"));
}

TEST_F(HandWrittenBoxTest, BiasCountAndStopRequestsAreExactBytes) {
  auto client = Connect();
  ASSERT_NE(client, nullptr);
  ASSERT_TRUE(client->Bias().ok());
  auto bias = box_.Receive(kReceiveTimeout);
  ASSERT_TRUE(bias.has_value());
  EXPECT_THAT(*bias,
              ElementsAre(0x12, 0x34, 0x00, 0x42, 0x00, 0x00, 0x00, 0x00));
  // The sample count goes out as all four bytes, not the low two twice.
  ASSERT_TRUE(
      client->Send({RdtCommand::kStartRealTimeStreaming, 0x00012345u}).ok());
  auto counted = box_.Receive(kReceiveTimeout);
  ASSERT_TRUE(counted.has_value());
  EXPECT_THAT(*counted,
              ElementsAre(0x12, 0x34, 0x00, 0x02, 0x00, 0x01, 0x23, 0x45));
  client.reset();
  auto stop = box_.Receive(kReceiveTimeout);
  ASSERT_TRUE(stop.has_value());
  EXPECT_THAT(*stop,
              ElementsAre(0x12, 0x34, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00));
}

TEST(NetFtRdtClientOptionsTest, RejectsBadConfiguration) {
  NetFtRdtClientOptions options;
  options.host = "127.0.0.1";
  absl::Status status;
  // 0, a count coarser than 0.1 N, a range under 50 N (no force limit could
  // be judged), infinite, NaN.
  for (double counts :
       {0.0, 5.0, 1e9, 1e300, std::numeric_limits<double>::infinity(),
        std::numeric_limits<double>::quiet_NaN()}) {
    options.counts_per_force = counts;
    status = NetFtRdtClient::Connect(options).status();
    EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument) << counts;
    EXPECT_THAT(status.message(),
                HasSubstr("counts_per_force must be between 10 and 42949672 "))
        << counts;
  }
  options.counts_per_force = 1e6;
  options.counts_per_torque = std::numeric_limits<double>::infinity();
  status = NetFtRdtClient::Connect(options).status();
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(status.message(), HasSubstr("counts_per_torque"));
  options.counts_per_torque = 1e6;
  options.frozen_after_s = -0.1;
  status = NetFtRdtClient::Connect(options).status();
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(status.message(), HasSubstr("frozen_after_s"));
  options.frozen_after_s = 0.1;
  options.host = "no such host.invalid";
  status = NetFtRdtClient::Connect(options).status();
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(status.message(), HasSubstr("does not resolve"));
}

// A constant load for the simulated box.
class ConstantLoad : public sim::WrenchSource {
 public:
  sim::Wrench WrenchAt(double) override {
    sim::Wrench w;
    w.force_n = {0.0, 0.0, 2.0};
    return w;
  }
};

class SimBoxTest : public ::testing::Test {
 protected:
  void Start(double rate_hz, const sim::SimNetFtFaults& faults,
             double random_bias_n = 0.0) {
    sim::SimNetFtBoxOptions options;
    options.rate_hz = rate_hz;
    options.seed = 7;
    options.noise.random_bias_n = random_bias_n;
    auto box = sim::SimNetFtBox::Start(options, &load_);
    ASSERT_TRUE(box.ok()) << box.status();
    box_ = std::move(box).value();
    box_->SetFaults(faults);
    NetFtRdtClientOptions client_options;
    client_options.host = "127.0.0.1";
    client_options.port = box_->port();
    client_options.silence_timeout_s = 0.2;
    auto client = NetFtRdtClient::Connect(client_options);
    ASSERT_TRUE(client.ok()) << client.status();
    client_ = std::move(client).value();
  }

  // Lets `n` records through, clears the faults and waits for the tail.
  void RunFor(uint64_t n) {
    ASSERT_TRUE(
        WaitFor([&] { return client_->stats().samples_accepted >= n; }));
    box_->SetFaults(sim::SimNetFtFaults());
    const uint32_t last = box_->counters().last_rdt_sequence;
    ASSERT_TRUE(WaitFor([&] {
      auto latest = client_->Latest();
      return latest && latest->rdt_sequence > last + 20;
    }));
  }

  ConstantLoad load_;
  std::unique_ptr<sim::SimNetFtBox> box_;
  std::unique_ptr<NetFtRdtClient> client_;
};

TEST_F(SimBoxTest, LostPacketsMatchTheBoxsDrops) {
  sim::SimNetFtFaults faults;
  faults.loss_probability = 0.1;
  Start(1000.0, faults);
  RunFor(600);
  const sim::SimNetFtCounters counters = box_->counters();
  const RdtStats stats = client_->stats();
  EXPECT_GT(counters.records_dropped, 20u);
  EXPECT_EQ(stats.packets_lost, counters.records_dropped);
  EXPECT_EQ(stats.out_of_order, 0u);
  EXPECT_EQ(stats.stale_dropped, 0u);
}

TEST_F(SimBoxTest, ReorderedPacketsAreCountedAndDropped) {
  sim::SimNetFtFaults faults;
  faults.reorder_probability = 0.05;
  Start(1000.0, faults);
  RunFor(600);
  const sim::SimNetFtCounters counters = box_->counters();
  const RdtStats stats = client_->stats();
  EXPECT_GT(counters.records_reordered, 10u);
  EXPECT_EQ(stats.out_of_order, counters.records_reordered);
  EXPECT_EQ(stats.stale_dropped, counters.records_reordered);
  EXPECT_EQ(stats.packets_lost, 0u);
  EXPECT_EQ(stats.duplicates, 0u);
}

TEST_F(SimBoxTest, SilenceIsDetectedAndRecovers) {
  Start(1000.0, sim::SimNetFtFaults());
  ASSERT_TRUE(WaitFor(
      [&] { return client_->Health().state == StreamState::kStreaming; }));
  sim::SimNetFtFaults faults;
  faults.silent = true;
  box_->SetFaults(faults);
  ASSERT_TRUE(
      WaitFor([&] { return client_->Health().state == StreamState::kSilent; }));
  EXPECT_THAT(client_->CheckLive().message(), HasSubstr("is silent"));
  box_->SetFaults(sim::SimNetFtFaults());
  ASSERT_TRUE(WaitFor(
      [&] { return client_->Health().state == StreamState::kStreaming; }));
  ASSERT_TRUE(WaitFor([&] { return client_->CheckLive().ok(); }));
  EXPECT_EQ(client_->stats().packets_lost, 0u);
}

// Records that keep flowing with a sane counter and a clean status word but
// repeat their readings exactly are not a live sensor: not live, naming the
// sensor and how long; live again once the readings move. A noisy stream
// is never called frozen.
TEST_F(SimBoxTest, FrozenReadingsAreNotLiveAndRecover) {
  Start(1000.0, sim::SimNetFtFaults());
  ASSERT_TRUE(WaitFor([&] { return client_->CheckLive().ok(); }));
  ASSERT_TRUE(
      WaitFor([&] { return client_->stats().samples_accepted >= 300; }));
  EXPECT_TRUE(client_->CheckLive().ok());
  EXPECT_LE(client_->Health().readings_unchanged_records, 2u);
  sim::SimNetFtFaults faults;
  faults.readings_frozen = true;
  box_->SetFaults(faults);
  ASSERT_TRUE(WaitFor([&] { return !client_->CheckLive().ok(); }));
  const absl::Status live = client_->CheckLive();
  EXPECT_EQ(live.code(), absl::StatusCode::kUnavailable);
  EXPECT_THAT(live.message(), AllOf(HasSubstr("Net F/T sensor at 127.0.0.1:"),
                                    HasSubstr("all six readings identical"),
                                    HasSubstr("no force protection")));
  EXPECT_EQ(client_->CheckDuringMotion().code(),
            absl::StatusCode::kUnavailable);
  const StreamHealth health = client_->Health();
  EXPECT_EQ(health.state, StreamState::kStreaming);
  EXPECT_GE(health.readings_unchanged_s, 0.1);
  EXPECT_GE(health.readings_unchanged_records, 9u);
  box_->SetFaults(sim::SimNetFtFaults());
  ASSERT_TRUE(WaitFor([&] { return client_->CheckLive().ok(); }));
  EXPECT_EQ(client_->stats().packets_lost, 0u);
}

TEST_F(SimBoxTest, BiasDriftIsVisibleAndBiasCommandZeroesIt) {
  sim::SimNetFtFaults faults;
  faults.bias_drift_n_per_s = 10.0;
  Start(1000.0, faults, /*random_bias_n=*/0.5);
  ASSERT_TRUE(WaitFor([&] { return client_->stats().samples_accepted > 50; }));
  const double fz0 = client_->Latest()->wrench.force_n[2];
  ASSERT_TRUE(WaitFor(
      [&] { return client_->Latest()->wrench.force_n[2] > fz0 + 2.0; }));
  box_->SetFaults(sim::SimNetFtFaults());
  ASSERT_TRUE(client_->Bias().ok());
  ASSERT_TRUE(WaitFor([&] { return box_->counters().bias_commands == 1; }));
  // Average out the noise (0.08 N per sample) over the samples after it.
  const uint64_t from = client_->Latest()->index + 5;
  std::vector<FtSample> samples;
  ASSERT_TRUE(WaitFor([&] {
    samples.clear();
    client_->SamplesSince(from, &samples);
    return samples.size() >= 200;
  }));
  double fz = 0.0;
  for (const FtSample& s : samples) fz += s.wrench.force_n[2];
  EXPECT_NEAR(fz / samples.size(), 0.0, 0.05);
}

TEST_F(SimBoxTest, StreamsAtSevenKilohertz) {
  Start(7000.0, sim::SimNetFtFaults());
  ASSERT_TRUE(WaitFor([&] { return client_->stats().samples_accepted > 100; }));
  const uint64_t n0 = box_->counters().records_sent;
  const double t0 = SteadyNowS();
  std::this_thread::sleep_for(std::chrono::milliseconds(1000));
  const double rate =
      (box_->counters().records_sent - n0) / (SteadyNowS() - t0);
  EXPECT_NEAR(rate, 7000.0, 700.0);
  // The sensor clock spaces the samples exactly 1/7000 s apart.
  std::vector<FtSample> samples;
  client_->SamplesSince(client_->Latest()->index - 50, &samples);
  ASSERT_GE(samples.size(), 2u);
  const FtSample& a = samples.front();
  const FtSample& b = samples.back();
  const double expected =
      (b.rdt_sequence - a.rdt_sequence) / 7000.0;  // no loss on loopback
  EXPECT_NEAR(b.sensor_time_s - a.sensor_time_s, expected, 1e-9);
  EXPECT_NEAR(a.wrench.force_n[2], 2.0, 0.5);
}

}  // namespace
}  // namespace bitewise::netft
