// The HapticNet model shipped in models/hapticnet/hapticnet.onnx, compiled
// into the binaries so the HapticService runs with no flags and no files
// beside it. The bytes are embedded at build time by embed_model.cmake, so
// rebuilding after retraining picks the new model up.
#ifndef BITEWISE_SERVICES_HAPTIC_DEFAULT_MODEL_H_
#define BITEWISE_SERVICES_HAPTIC_DEFAULT_MODEL_H_

#include "absl/strings/string_view.h"

namespace bitewise::haptic {

// The ONNX bytes of the shipped model.
absl::string_view DefaultHapticNetOnnx();

// Names the embedded model in messages and logs.
constexpr char kDefaultHapticNetSource[] =
    "<embedded models/hapticnet/hapticnet.onnx>";

// The familiarity model fitted with it,
// models/hapticnet/hapticnet.onnx.familiarity (core/familiarity.h).
absl::string_view DefaultHapticFamiliarity();

constexpr char kDefaultHapticFamiliaritySource[] =
    "<embedded models/hapticnet/hapticnet.onnx.familiarity>";

}  // namespace bitewise::haptic

#endif  // BITEWISE_SERVICES_HAPTIC_DEFAULT_MODEL_H_
