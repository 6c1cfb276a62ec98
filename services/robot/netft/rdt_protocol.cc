#include "services/robot/netft/rdt_protocol.h"

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"

namespace bitewise::netft {
namespace {

void PutU16(uint16_t value, uint8_t* out) {
  out[0] = static_cast<uint8_t>(value >> 8);
  out[1] = static_cast<uint8_t>(value);
}

void PutU32(uint32_t value, uint8_t* out) {
  out[0] = static_cast<uint8_t>(value >> 24);
  out[1] = static_cast<uint8_t>(value >> 16);
  out[2] = static_cast<uint8_t>(value >> 8);
  out[3] = static_cast<uint8_t>(value);
}

uint16_t GetU16(const uint8_t* in) {
  return static_cast<uint16_t>((uint16_t{in[0]} << 8) | uint16_t{in[1]});
}

uint32_t GetU32(const uint8_t* in) {
  return (uint32_t{in[0]} << 24) | (uint32_t{in[1]} << 16) |
         (uint32_t{in[2]} << 8) | uint32_t{in[3]};
}

}  // namespace

std::array<uint8_t, kRdtRequestBytes> EncodeRdtRequest(
    const RdtRequest& request) {
  std::array<uint8_t, kRdtRequestBytes> out{};
  PutU16(kRdtHeader, &out[0]);
  PutU16(static_cast<uint16_t>(request.command), &out[2]);
  PutU32(request.sample_count, &out[4]);
  return out;
}

absl::StatusOr<RdtRequest> DecodeRdtRequest(absl::Span<const uint8_t> bytes) {
  if (bytes.size() != kRdtRequestBytes) {
    return absl::InvalidArgumentError(
        absl::StrCat("RDT request must be ", kRdtRequestBytes, " bytes, got ",
                     bytes.size()));
  }
  const uint16_t header = GetU16(&bytes[0]);
  if (header != kRdtHeader) {
    return absl::InvalidArgumentError(absl::StrFormat(
        "RDT request header must be 0x1234, got 0x%04x", header));
  }
  const uint16_t command = GetU16(&bytes[2]);
  RdtRequest request;
  switch (command) {
    case static_cast<uint16_t>(RdtCommand::kStopStreaming):
    case static_cast<uint16_t>(RdtCommand::kStartRealTimeStreaming):
    case static_cast<uint16_t>(RdtCommand::kSetSoftwareBias):
      request.command = static_cast<RdtCommand>(command);
      break;
    default:
      return absl::InvalidArgumentError(
          absl::StrFormat("RDT request command 0x%04x is not supported "
                          "(0x0000 stop, 0x0002 stream, 0x0042 bias)",
                          command));
  }
  request.sample_count = GetU32(&bytes[4]);
  return request;
}

std::array<uint8_t, kRdtRecordBytes> EncodeRdtRecord(const RdtRecord& record) {
  std::array<uint8_t, kRdtRecordBytes> out{};
  PutU32(record.rdt_sequence, &out[0]);
  PutU32(record.ft_sequence, &out[4]);
  PutU32(record.status, &out[8]);
  for (int i = 0; i < 6; ++i) {
    PutU32(static_cast<uint32_t>(record.counts[i]), &out[12 + 4 * i]);
  }
  return out;
}

absl::StatusOr<RdtRecord> DecodeRdtRecord(absl::Span<const uint8_t> bytes) {
  if (bytes.size() != kRdtRecordBytes) {
    return absl::InvalidArgumentError(absl::StrCat(
        "RDT record must be ", kRdtRecordBytes, " bytes, got ", bytes.size()));
  }
  RdtRecord record;
  record.rdt_sequence = GetU32(&bytes[0]);
  record.ft_sequence = GetU32(&bytes[4]);
  record.status = GetU32(&bytes[8]);
  for (int i = 0; i < 6; ++i) {
    // Two's complement on the wire; the cast is well defined since C++20
    // and implementation-defined (and two's complement on every target
    // bitewise builds for) before.
    record.counts[i] = static_cast<int32_t>(GetU32(&bytes[12 + 4 * i]));
  }
  return record;
}

}  // namespace bitewise::netft
