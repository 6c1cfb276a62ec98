// Conversions between the bitewise.v1 haptic protos and the haptic core's
// types, kept apart from the handler so it reads as convert, classify,
// convert back.
#ifndef BITEWISE_SERVICES_HAPTIC_CONVERTERS_H_
#define BITEWISE_SERVICES_HAPTIC_CONVERTERS_H_

#include <string>
#include <vector>

#include "bitewise/v1/haptic.pb.h"
#include "services/haptic/core/haptic_classifier.h"
#include "services/haptic/core/wrench_trace.h"

namespace bitewise::haptic {

std::vector<TimedWrench> TraceFromProto(const v1::ClassifyRequest& request);

// The inverse of TraceFromProto, for callers that hold a trace in the core's
// types (tests, benchmarks): appends `trace` to `request`'s samples.
void TraceToProto(const std::vector<TimedWrench>& trace,
                  v1::ClassifyRequest* request);

v1::HapticCategory CategoryToProto(HapticClass haptic_class);

void ClassificationToProto(const HapticClassification& result,
                           const std::string& model_fingerprint,
                           v1::ClassifyResponse* response);

}  // namespace bitewise::haptic

#endif  // BITEWISE_SERVICES_HAPTIC_CONVERTERS_H_
