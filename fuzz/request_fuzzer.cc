// libFuzzer target: every service's request converters, run as the handlers
// run them, on requests parsed from arbitrary bytes. The first byte picks
// the request type; a request the converters accept is then checked further
// as its handler would (the frame decoded, the trace validated).
#include <cstddef>
#include <cstdint>

#include "bitewise/v1/bandit.pb.h"
#include "bitewise/v1/haptic.pb.h"
#include "bitewise/v1/perception.pb.h"
#include "bitewise/v1/robot.pb.h"
#include "services/bandit/converters.h"
#include "services/haptic/converters.h"
#include "services/haptic/core/wrench_trace.h"
#include "services/perception/converters.h"
#include "services/perception/frame.h"
#include "services/robot/converters.h"

namespace {

using namespace bitewise;  // NOLINT: the fuzzer spans the services

template <typename Message>
bool Parse(const uint8_t* data, size_t size, Message* message) {
  return message->ParseFromArray(data, static_cast<int>(size));
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  const uint8_t kind = data[0] % 6;
  ++data;
  --size;
  switch (kind) {
    case 0: {
      v1::CreateUserRequest request;
      if (!Parse(data, size, &request)) return 0;
      bandit::ConfigFromProto(request.config(), bandit::BanditConfig(),
                              request.user_id())
          .IgnoreError();
      break;
    }
    case 1: {
      v1::SelectRequest request;
      if (!Parse(data, size, &request)) return 0;
      bandit::SelectInputFromProto(request);
      break;
    }
    case 2: {
      v1::UpdateRequest request;
      if (!Parse(data, size, &request)) return 0;
      bandit::UpdateInputFromProto(request).IgnoreError();
      break;
    }
    case 3: {
      v1::DetectFoodRequest request;
      if (!Parse(data, size, &request)) return 0;
      perception::DecodeFrame(perception::FrameBytesFromProto(request.frame()))
          .IgnoreError();
      break;
    }
    case 4: {
      v1::ClassifyRequest request;
      if (!Parse(data, size, &request)) return 0;
      const std::vector<domain::TimedWrench> trace =
          haptic::TraceFromProto(request);
      haptic::ValidateTrace(trace, 8).IgnoreError();
      break;
    }
    case 5: {
      v1::AcquireRequest request;
      if (!Parse(data, size, &request)) return 0;
      robot::TargetFromProto(request).IgnoreError();
      break;
    }
  }
  return 0;
}
