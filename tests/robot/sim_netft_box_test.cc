// The simulated Net F/T box against a minimal RDT client written here by
// hand (raw socket, hand-packed requests, hand-unpacked records): what any
// other Net F/T client would see.
#include "services/robot/sim/sim_netft_box.h"

#include <chrono>
#include <memory>
#include <vector>

#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "tests/robot/udp_test_peer.h"

namespace bitewise::sim {
namespace {

using ::bitewise::testing::ReadBigEndian32;
using ::bitewise::testing::UdpTestPeer;

constexpr auto kTimeout = std::chrono::milliseconds(10000);

const std::vector<uint8_t> kStartForever = {0x12, 0x34, 0x00, 0x02,
                                            0x00, 0x00, 0x00, 0x00};
const std::vector<uint8_t> kStop = {0x12, 0x34, 0x00, 0x00,
                                    0x00, 0x00, 0x00, 0x00};
const std::vector<uint8_t> kBias = {0x12, 0x34, 0x00, 0x42,
                                    0x00, 0x00, 0x00, 0x00};

class FixedLoad : public WrenchSource {
 public:
  Wrench WrenchAt(double) override {
    Wrench w;
    w.force_n = {-1.25, 0.5, 2.5};
    w.torque_nm = {0.1, -0.02, 0.0};
    return w;
  }
};

class SimNetFtBoxTest : public ::testing::Test {
 protected:
  void SetUp() override {
    SimNetFtBoxOptions options;
    options.rate_hz = 1000.0;
    options.noise.force_sd_n = 0.0;
    options.noise.torque_sd_nm = 0.0;
    options.noise.random_bias_n = 0.0;
    auto box = SimNetFtBox::Start(options, &load_);
    ASSERT_TRUE(box.ok()) << box.status();
    box_ = std::move(box).value();
  }

  int32_t Count(const std::vector<uint8_t>& record, int channel) {
    return static_cast<int32_t>(ReadBigEndian32(record, 12 + 4 * channel));
  }

  FixedLoad load_;
  std::unique_ptr<SimNetFtBox> box_;
  UdpTestPeer client_;
};

TEST_F(SimNetFtBoxTest, StreamsExactlyTheRequestedCount) {
  // 0x00000100 = 256 records.
  ASSERT_TRUE(client_.SendToPort(
      box_->port(), {0x12, 0x34, 0x00, 0x02, 0x00, 0x00, 0x01, 0x00}));
  uint32_t last_ft = 0;
  for (uint32_t i = 1; i <= 256; ++i) {
    auto record = client_.Receive(kTimeout);
    ASSERT_TRUE(record.has_value()) << "record " << i;
    ASSERT_EQ(record->size(), 36u);
    EXPECT_EQ(ReadBigEndian32(*record, 0), i);  // rdt_sequence from 1
    const uint32_t ft = ReadBigEndian32(*record, 4);
    if (i > 1) {
      EXPECT_EQ(ft - last_ft, 7u);  // 7 kHz sensor, 1 kHz output
    }
    last_ft = ft;
    EXPECT_EQ(ReadBigEndian32(*record, 8), 0u);
    // 1e6 counts per N and per N·m.
    EXPECT_EQ(Count(*record, 0), -1250000);
    EXPECT_EQ(Count(*record, 1), 500000);
    EXPECT_EQ(Count(*record, 2), 2500000);
    EXPECT_EQ(Count(*record, 3), 100000);
    EXPECT_EQ(Count(*record, 4), -20000);
    EXPECT_EQ(Count(*record, 5), 0);
  }
  EXPECT_FALSE(client_.Receive(std::chrono::milliseconds(200)).has_value());
  EXPECT_FALSE(box_->counters().streaming);
}

TEST_F(SimNetFtBoxTest, StopAndBiasCommands) {
  ASSERT_TRUE(client_.SendToPort(box_->port(), kStartForever));
  ASSERT_TRUE(client_.Receive(kTimeout).has_value());
  ASSERT_TRUE(client_.SendToPort(box_->port(), kBias));
  // After the bias, the load reads as zero.
  bool zeroed = false;
  for (int i = 0; i < 5000 && !zeroed; ++i) {
    auto record = client_.Receive(kTimeout);
    ASSERT_TRUE(record.has_value());
    zeroed = Count(*record, 0) == 0 && Count(*record, 2) == 0 &&
             Count(*record, 3) == 0;
  }
  EXPECT_TRUE(zeroed);
  ASSERT_TRUE(client_.SendToPort(box_->port(), kStop));
  // Drain what was in flight, then silence.
  int drained = 0;
  while (client_.Receive(std::chrono::milliseconds(300)).has_value()) {
    ASSERT_LT(++drained, 20000);
  }
  EXPECT_FALSE(box_->counters().streaming);
  EXPECT_EQ(box_->counters().bias_commands, 1u);
}

TEST_F(SimNetFtBoxTest, IgnoresMalformedRequests) {
  ASSERT_TRUE(
      client_.SendToPort(box_->port(), {0x34, 0x12, 0x00, 0x02, 0, 0, 0, 0}));
  ASSERT_TRUE(client_.SendToPort(box_->port(), {0x12, 0x34, 0x00}));
  EXPECT_FALSE(client_.Receive(std::chrono::milliseconds(300)).has_value());
  EXPECT_EQ(box_->counters().malformed_requests, 2u);
  EXPECT_EQ(box_->counters().requests, 0u);
}

TEST(SimNetFtBoxOptionsTest, RejectsRatesAboveTheInternalRate) {
  SimNetFtBoxOptions options;
  options.rate_hz = 8000.0;
  absl::Status status = SimNetFtBox::Start(options, nullptr).status();
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(status.message(), ::testing::HasSubstr("rate_hz"));
}

}  // namespace
}  // namespace bitewise::sim
