// The ATI Net F/T Raw Data Transfer (RDT) protocol over UDP, as bytes: the
// 8-byte request a client sends and the 36-byte record the box streams back
// (docs/robot.md). Shared by the production client (NetFtRdtClient) and the
// simulated box, and kept free of sockets so every byte can be tested against
// hand-written packets. All multi-byte fields are big-endian on the wire.
#ifndef BITEWISE_SERVICES_ROBOT_NETFT_RDT_PROTOCOL_H_
#define BITEWISE_SERVICES_ROBOT_NETFT_RDT_PROTOCOL_H_

#include <array>
#include <cstddef>
#include <cstdint>

#include "absl/status/statusor.h"
#include "absl/types/span.h"

namespace bitewise::netft {

// The UDP port a Net F/T box listens on for RDT requests.
constexpr uint16_t kRdtPort = 49152;
// First field of every request.
constexpr uint16_t kRdtHeader = 0x1234;
constexpr size_t kRdtRequestBytes = 8;
constexpr size_t kRdtRecordBytes = 36;

enum class RdtCommand : uint16_t {
  kStopStreaming = 0x0000,
  kStartRealTimeStreaming = 0x0002,
  // Software bias: the box zeroes its output at the current load.
  kSetSoftwareBias = 0x0042,
};

struct RdtRequest {
  RdtCommand command = RdtCommand::kStopStreaming;
  // Records to send; 0 means stream until told to stop.
  uint32_t sample_count = 0;
};

// One record: sequence numbers, the box's status word and the raw counts of
// Fx, Fy, Fz, Tx, Ty, Tz.
struct RdtRecord {
  // Packets sent since the last start request (the box starts again at 1).
  uint32_t rdt_sequence = 0;
  // The sensor's internal sample counter, running at its internal rate.
  uint32_t ft_sequence = 0;
  // 0 when healthy; any other value is a box-reported fault.
  uint32_t status = 0;
  std::array<int32_t, 6> counts{};
};

// {u16 0x1234, u16 command, u32 sample_count}, big-endian. The count is
// written as all four bytes (a widely copied driver writes its low 16 bits
// twice, so a count of 0x00012345 goes out as 23 45 23 45).
std::array<uint8_t, kRdtRequestBytes> EncodeRdtRequest(
    const RdtRequest& request);

// INVALID_ARGUMENT if `bytes` is not 8 bytes long, the header is not 0x1234
// or the command is not one of the three above.
absl::StatusOr<RdtRequest> DecodeRdtRequest(absl::Span<const uint8_t> bytes);

std::array<uint8_t, kRdtRecordBytes> EncodeRdtRecord(const RdtRecord& record);

// INVALID_ARGUMENT if `bytes` is not exactly 36 bytes long.
absl::StatusOr<RdtRecord> DecodeRdtRecord(absl::Span<const uint8_t> bytes);

}  // namespace bitewise::netft

#endif  // BITEWISE_SERVICES_ROBOT_NETFT_RDT_PROTOCOL_H_
