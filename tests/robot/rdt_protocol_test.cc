// Byte-level tests of the RDT codec against packets written out by hand
// from the protocol description (docs/robot.md), not from the encoder.
#include "services/robot/netft/rdt_protocol.h"

#include <cstdint>
#include <vector>

#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace bitewise::netft {
namespace {

using ::testing::ElementsAre;
using ::testing::HasSubstr;

TEST(RdtRequestTest, StartStreamingIsBigEndian) {
  EXPECT_THAT(EncodeRdtRequest({RdtCommand::kStartRealTimeStreaming, 0}),
              ElementsAre(0x12, 0x34, 0x00, 0x02, 0x00, 0x00, 0x00, 0x00));
}

TEST(RdtRequestTest, StopAndBias) {
  EXPECT_THAT(EncodeRdtRequest({RdtCommand::kStopStreaming, 0}),
              ElementsAre(0x12, 0x34, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00));
  EXPECT_THAT(EncodeRdtRequest({RdtCommand::kSetSoftwareBias, 0}),
              ElementsAre(0x12, 0x34, 0x00, 0x42, 0x00, 0x00, 0x00, 0x00));
}

// The widely copied driver writes the low 16 bits twice: 23 45 23 45.
TEST(RdtRequestTest, SampleCountIsAFullBigEndianU32) {
  EXPECT_THAT(
      EncodeRdtRequest({RdtCommand::kStartRealTimeStreaming, 0x00012345u}),
      ElementsAre(0x12, 0x34, 0x00, 0x02, 0x00, 0x01, 0x23, 0x45));
  EXPECT_THAT(
      EncodeRdtRequest({RdtCommand::kStartRealTimeStreaming, 0xA1B2C3D4u}),
      ElementsAre(0x12, 0x34, 0x00, 0x02, 0xA1, 0xB2, 0xC3, 0xD4));
}

TEST(RdtRequestTest, DecodesHandWrittenRequest) {
  const std::vector<uint8_t> bytes = {0x12, 0x34, 0x00, 0x02,
                                      0x00, 0x01, 0x23, 0x45};
  absl::StatusOr<RdtRequest> request = DecodeRdtRequest(bytes);
  ASSERT_TRUE(request.ok()) << request.status();
  EXPECT_EQ(request->command, RdtCommand::kStartRealTimeStreaming);
  EXPECT_EQ(request->sample_count, 0x00012345u);
}

TEST(RdtRequestTest, RejectsBadRequests) {
  const std::vector<uint8_t> short_request = {0x12, 0x34, 0x00, 0x02};
  EXPECT_THAT(DecodeRdtRequest(short_request).status().message(),
              HasSubstr("8 bytes, got 4"));
  const std::vector<uint8_t> bad_header = {0x34, 0x12, 0, 2, 0, 0, 0, 0};
  EXPECT_THAT(DecodeRdtRequest(bad_header).status().message(),
              HasSubstr("header must be 0x1234, got 0x3412"));
  const std::vector<uint8_t> bad_command = {0x12, 0x34, 0, 7, 0, 0, 0, 0};
  EXPECT_EQ(DecodeRdtRequest(bad_command).status().code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(DecodeRdtRequest(bad_command).status().message(),
              HasSubstr("0x0007"));
}

TEST(RdtRecordTest, DecodesHandWrittenRecord) {
  const std::vector<uint8_t> bytes = {
      0x00, 0x00, 0x01, 0x02,  // rdt_sequence 258
      0x80, 0x00, 0x00, 0x01,  // ft_sequence 2^31 + 1
      0x00, 0x00, 0x00, 0x00,  // status
      0x00, 0x0F, 0x42, 0x40,  // Fx  1000000
      0xFF, 0xF0, 0xBD, 0xC0,  // Fy -1000000
      0x7F, 0xFF, 0xFF, 0xFF,  // Fz  INT32_MAX
      0x80, 0x00, 0x00, 0x00,  // Tx  INT32_MIN
      0xFF, 0xFF, 0xFF, 0xFF,  // Ty -1
      0x00, 0x00, 0x00, 0x01,  // Tz  1
  };
  absl::StatusOr<RdtRecord> record = DecodeRdtRecord(bytes);
  ASSERT_TRUE(record.ok()) << record.status();
  EXPECT_EQ(record->rdt_sequence, 258u);
  EXPECT_EQ(record->ft_sequence, 0x80000001u);
  EXPECT_EQ(record->status, 0u);
  EXPECT_THAT(record->counts,
              ElementsAre(1000000, -1000000, INT32_MAX, INT32_MIN, -1, 1));
}

TEST(RdtRecordTest, EncodesByteForByte) {
  RdtRecord record;
  record.rdt_sequence = 0x01020304;
  record.ft_sequence = 0x05060708;
  record.status = 0x80000000;
  record.counts = {1, -2, 0x0A0B0C0D, -16777216, 0, 255};
  EXPECT_THAT(
      EncodeRdtRecord(record),
      ElementsAre(0x01, 0x02, 0x03, 0x04, 0x05, 0x06, 0x07, 0x08, 0x80, 0x00,
                  0x00, 0x00, 0x00, 0x00, 0x00, 0x01, 0xFF, 0xFF, 0xFF, 0xFE,
                  0x0A, 0x0B, 0x0C, 0x0D, 0xFF, 0x00, 0x00, 0x00, 0x00, 0x00,
                  0x00, 0x00, 0x00, 0x00, 0x00, 0xFF));
}

TEST(RdtRecordTest, RejectsWrongLength) {
  const std::vector<uint8_t> bytes(35, 0);
  absl::Status status = DecodeRdtRecord(bytes).status();
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(status.message(), HasSubstr("36 bytes, got 35"));
  const std::vector<uint8_t> longer(37, 0);
  EXPECT_FALSE(DecodeRdtRecord(longer).ok());
}

}  // namespace
}  // namespace bitewise::netft
