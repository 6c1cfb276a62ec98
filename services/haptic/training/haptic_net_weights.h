// HapticNet's parameters as the trainer holds them, the double-precision
// reference forward pass, and the export to ONNX (through the ONNX protobuf
// classes of Debian's libonnx-dev). The reference pass is the independent
// check that what OpenCV's DNN module computes from the exported file is
// what the trainer learned.
#ifndef BITEWISE_SERVICES_HAPTIC_TRAINING_HAPTIC_NET_WEIGHTS_H_
#define BITEWISE_SERVICES_HAPTIC_TRAINING_HAPTIC_NET_WEIGHTS_H_

#include <array>
#include <map>
#include <string>
#include <vector>

#include "Eigen/Dense"
#include "absl/status/statusor.h"
#include "services/haptic/core/haptic_window.h"
#include "services/haptic/core/wrench_trace.h"

namespace bitewise::haptic {

using RowMatrix =
    Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

constexpr int kHapticHidden = 128;

// The convolutional front end's kernel: 5 points of the 64-point window
// (about 4 ms of the 50 ms), zero-padded at both ends so that a layer keeps
// the length it is given ("same" padding).
constexpr int kConvKernel = 5;

// One layer of the optional convolutional front end: a 1-D convolution along
// the window's time axis, then ReLU, then max-pooling of neighbouring pairs,
// so a layer of length L gives L / 2 points per output channel.
struct ConvLayer {
  int in_channels = 0;
  int out_channels = 0;
  // Input-major like the fully connected layers: weight[(ci * kConvKernel +
  // t) * out_channels + co] multiplies input channel ci at offset t - 2.
  std::vector<double> weight;
  std::vector<double> bias;  // out_channels
};

// Layer weights are stored input-major (fan_in x fan_out): y = x * w + b.
// The ONNX file holds them transposed (see HapticNetToOnnx).
struct HapticNetWeights {
  // Per-input normalisation, x' = (x - mean) / stddev, each the statistic
  // of the input's channel (so 64 equal values per channel).
  Eigen::RowVectorXd input_mean = Eigen::RowVectorXd::Zero(kHapticInputs);
  Eigen::RowVectorXd input_stddev = Eigen::RowVectorXd::Ones(kHapticInputs);
  RowMatrix w1 = RowMatrix::Zero(kHapticInputs, kHapticHidden);
  Eigen::RowVectorXd b1 = Eigen::RowVectorXd::Zero(kHapticHidden);
  RowMatrix w2 = RowMatrix::Zero(kHapticHidden, kHapticHidden);
  Eigen::RowVectorXd b2 = Eigen::RowVectorXd::Zero(kHapticHidden);
  RowMatrix w3 = RowMatrix::Zero(kHapticHidden, kHapticClasses);
  Eigen::RowVectorXd b3 = Eigen::RowVectorXd::Zero(kHapticClasses);
  // Optional convolutional front end (`bitewise-haptic-train
  // --conv_channels`): the normalised window, seen as 6 channels of 64
  // points, goes through these layers in order, and their last output,
  // flattened channel-major, is fc1's input (w1 then has
  // FrontEndOutputs(conv) rows). Empty for the plain MLP, whose fc1 sees the
  // normalised window itself.
  std::vector<ConvLayer> conv;
};

// fc1's fan-in: kHapticInputs without a front end, else the last layer's
// channels times the points left after halving once per layer.
int FrontEndOutputs(const std::vector<ConvLayer>& conv);

// A front end of layers with these output channels (e.g. {16, 32}), zero
// weights, and w1 resized to match. INVALID_ARGUMENT when a count is below 1
// or there are more layers than halvings of the 64 points allow (at most 6).
absl::StatusOr<HapticNetWeights> WeightsWithFrontEnd(
    const std::vector<int>& conv_channels);

// Kernel offset t (0..kConvKernel - 1) of a layer of `length` points: output
// point l reads input point l + shift, for l in [begin, end) (the others
// read the zero padding).
struct KernelSpan {
  int shift, begin, end;
};
inline KernelSpan SpanOf(int t, int length) {
  const int shift = t - kConvKernel / 2;
  return {shift, shift < 0 ? -shift : 0, shift > 0 ? length - shift : length};
}

// One front-end layer on one window: `in` holds layer.in_channels rows of
// `length` points (channel-major), `pre_activation` receives the convolution
// (out_channels x length) and `out` the pooled ReLU (out_channels x length /
// 2). `argmax`, if not null, receives for each pooled point the index in
// `pre_activation` it came from (the first of a tie). Sums run in a fixed
// order (input channel, then kernel offset), so the result does not depend
// on the CPU; the trainer and the reference pass share this function.
void ConvForward(const ConvLayer& layer, const double* in, int length,
                 double* pre_activation, double* out, int* argmax);

// Rounds every parameter to the nearest float, the precision of the ONNX
// file, so that the reference pass and the exported model share weights.
void RoundToFloat(HapticNetWeights& weights);

// Logits of one window, computed in double with Eigen.
std::array<double, kHapticClasses> ReferenceLogits(
    const HapticNetWeights& weights,
    const std::array<float, kHapticInputs>& inputs);

// Softmax of ReferenceLogits.
std::array<double, kHapticClasses> ReferenceProbabilities(
    const HapticNetWeights& weights,
    const std::array<float, kHapticInputs>& inputs);

// The serialized ONNX model (opset 11, IR version 6): Sub and Div for the
// normalisation, three Gemm layers with Relu between them ("logits"), and a
// Softmax ("probabilities"). `metadata` goes into metadata_props (training
// seed, accuracy, ...). Serialization is deterministic, so equal weights
// give equal bytes.
std::string HapticNetToOnnx(const HapticNetWeights& weights,
                            const std::map<std::string, std::string>& metadata);

// The weights of a single HapticNet file written by HapticNetToOnnx (for
// assembling an ensemble from separately trained members). INVALID_ARGUMENT
// naming `source` and the initializer for anything else.
absl::StatusOr<HapticNetWeights> HapticNetWeightsFromOnnx(
    const std::string& bytes, const std::string& source);

// An ensemble of members (HapticNet's ensemble over stories): the mean of
// their ReferenceProbabilities.
std::array<double, kHapticClasses> ReferenceEnsembleProbabilities(
    const std::vector<HapticNetWeights>& members,
    const std::array<float, kHapticInputs>& inputs);

// One ONNX file holding every member (names prefixed m0., m1., ...): each
// member's softmax, their mean, "logits" = its log and "probabilities" =
// Softmax(logits), the same mean. So it keeps the graph contract of one
// model and the service needs nothing new. With one member, exactly
// HapticNetToOnnx's graph.
std::string HapticEnsembleToOnnx(
    const std::vector<HapticNetWeights>& members,
    const std::map<std::string, std::string>& metadata);

}  // namespace bitewise::haptic

#endif  // BITEWISE_SERVICES_HAPTIC_TRAINING_HAPTIC_NET_WEIGHTS_H_
