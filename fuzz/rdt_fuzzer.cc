// libFuzzer target: the Net F/T RDT decoders on arbitrary datagrams. A
// datagram that decodes must encode back to the same bytes.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>

#include "services/robot/netft/rdt_protocol.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace bitewise::netft;  // NOLINT: one namespace
  const absl::Span<const uint8_t> bytes(data, size);
  absl::StatusOr<RdtRecord> record = DecodeRdtRecord(bytes);
  if (record.ok()) {
    const auto encoded = EncodeRdtRecord(*record);
    if (size != encoded.size() ||
        std::memcmp(encoded.data(), data, size) != 0) {
      std::abort();  // decode and encode disagree
    }
  }
  DecodeRdtRequest(bytes).IgnoreError();
  return 0;
}
