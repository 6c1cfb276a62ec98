// Writes an architecture-faithful SPANet as an ONNX file with seeded
// weights, so that tests and development run the real network shape
// through the real loader when no trained weights can be obtained.
//
// The interface (what SpanetFeaturizer and any lab's own export must match):
//   input  "rgb"       float [1, 3, 144, 144]: RGB in [0, 1], NCHW
//   input  "loc_type"  float [1, 3]: location one-hot (isolated, wall,
//                      lettuce)
//   output "features"  float [1, 2048]: the last hidden layer (the context)
//   output "scores"    float [1, 10]: sigmoid of the head; [0, 4) the two
//                      skewer points (x0, y0, x1, y1) on the 144x144 canvas
//                      scaled to [0, 1], [4, 10) success rates of VS0, VS90,
//                      TV0, TV90, TA0, TA90
// The graph is SPANet's RGB path: conv_init_rgb (Conv 3-16 k7, BN, ReLU,
// Conv 16-32 k3, BN, MaxPool 2, ReLU), conv_layers_top (three of Conv k3,
// BN, MaxPool 2, ReLU: 32-64-128-256, down to 9x9), conv_layers_bot (Conv
// 256-256 k3, BN, ReLU) applied three times with residual adds and shared
// weights, flatten to 20736, concat the one-hot, linear_layers (Linear
// 20739-2048, BN, ReLU, Linear 2048-2048, BN, ReLU) and final (Linear
// 2048-10, sigmoid). Initializers carry PyTorch's state_dict names. The
// batch is fixed at 1: OpenCV 4.6 cannot concatenate the one-hot input
// with the flattened features when the batch dimension is symbolic.
#ifndef BITEWISE_SERVICES_PERCEPTION_SPANET_ONNX_H_
#define BITEWISE_SERVICES_PERCEPTION_SPANET_ONNX_H_

#include <cstdint>
#include <string>

#include "absl/status/status.h"

namespace bitewise::perception {

struct SpanetOnnxOptions {
  // Seeds every weight; the same seed writes the same file on every machine
  // (weights come from mt19937_64's fully specified sequence).
  uint64_t seed = 1;
  // Width of the two hidden linear layers. SPANet's is 2048; a smaller
  // value exists only to test that loaders reject the wrong interface
  // cheaply.
  int hidden_features = 2048;
};

// Errors: INVALID_ARGUMENT for a non-positive hidden_features;
// FAILED_PRECONDITION naming the path when it cannot be written.
absl::Status WriteSpanetOnnx(const std::string& path,
                             const SpanetOnnxOptions& options);

// Checks an ONNX file's graph, before OpenCV runs it, for what OpenCV would
// run silently but wrongly: inputs "rgb" and "loc_type" of static shapes
// [1,3,144,144] and [1,3], outputs "features" and "scores", and every
// BatchNormalization in inference mode (one output, no training_mode=1). A
// graph exported with BatchNorm in training mode would normalise each crop
// by its own statistics instead of the training set's.
// Errors: FAILED_PRECONDITION naming the file and what is wrong (unreadable
// or not ONNX protobuf; missing or misshapen input or output; the first
// training-mode BatchNormalization node by name).
absl::Status CheckSpanetOnnxGraph(const std::string& path);

}  // namespace bitewise::perception

#endif  // BITEWISE_SERVICES_PERCEPTION_SPANET_ONNX_H_
