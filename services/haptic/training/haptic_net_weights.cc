#include "services/haptic/training/haptic_net_weights.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "google/protobuf/io/coded_stream.h"
#include "google/protobuf/io/zero_copy_stream_impl_lite.h"
#include "onnx/onnx_pb.h"
#include "services/haptic/core/haptic_net.h"

namespace bitewise::haptic {
namespace {

template <typename Matrix>
void RoundMatrix(Matrix& m) {
  for (Eigen::Index i = 0; i < m.size(); ++i) {
    m.data()[i] = static_cast<double>(static_cast<float>(m.data()[i]));
  }
}

void AddFloatTensor(onnx::GraphProto* graph, const std::string& name,
                    const std::vector<int64_t>& dims, const double* values,
                    int64_t count) {
  onnx::TensorProto* tensor = graph->add_initializer();
  tensor->set_name(name);
  tensor->set_data_type(onnx::TensorProto::FLOAT);
  for (int64_t d : dims) tensor->add_dims(d);
  tensor->mutable_float_data()->Reserve(static_cast<int>(count));
  for (int64_t i = 0; i < count; ++i) {
    tensor->add_float_data(static_cast<float>(values[i]));
  }
}

onnx::NodeProto* AddNode(onnx::GraphProto* graph, const std::string& op,
                         const std::vector<std::string>& inputs,
                         const std::string& output) {
  onnx::NodeProto* node = graph->add_node();
  node->set_op_type(op);
  node->set_name(output);
  for (const std::string& input : inputs) node->add_input(input);
  node->add_output(output);
  return node;
}

// Initializers `name`.weight ([fan_out, fan_in]) and `name`.bias.
void AddGemmWeights(onnx::GraphProto* graph, const std::string& name,
                    const RowMatrix& w, const Eigen::RowVectorXd& b) {
  const RowMatrix transposed = w.transpose();
  AddFloatTensor(graph, name + ".weight", {w.cols(), w.rows()},
                 transposed.data(), transposed.size());
  AddFloatTensor(graph, name + ".bias", {b.size()}, b.data(), b.size());
}

void AddGemm(onnx::GraphProto* graph, const std::string& input,
             const std::string& layer, const std::string& output) {
  onnx::NodeProto* node = AddNode(
      graph, "Gemm", {input, layer + ".weight", layer + ".bias"}, output);
  onnx::AttributeProto* trans_b = node->add_attribute();
  trans_b->set_name("transB");
  trans_b->set_type(onnx::AttributeProto::INT);
  trans_b->set_i(1);
}

void SetFloatShape(onnx::ValueInfoProto* value, const std::string& name,
                   int64_t rows, int64_t cols) {
  value->set_name(name);
  onnx::TypeProto_Tensor* tensor = value->mutable_type()->mutable_tensor_type();
  tensor->set_elem_type(onnx::TensorProto::FLOAT);
  tensor->mutable_shape()->add_dim()->set_dim_value(rows);
  tensor->mutable_shape()->add_dim()->set_dim_value(cols);
}

void AddInt64Tensor(onnx::GraphProto* graph, const std::string& name,
                    const std::vector<int64_t>& values) {
  onnx::TensorProto* tensor = graph->add_initializer();
  tensor->set_name(name);
  tensor->set_data_type(onnx::TensorProto::INT64);
  tensor->add_dims(static_cast<int64_t>(values.size()));
  for (int64_t v : values) tensor->add_int64_data(v);
}

void SetIntsAttribute(onnx::NodeProto* node, const char* name,
                      const std::vector<int64_t>& values) {
  onnx::AttributeProto* attribute = node->add_attribute();
  attribute->set_name(name);
  attribute->set_type(onnx::AttributeProto::INTS);
  for (int64_t v : values) attribute->add_ints(v);
}

void RoundVector(std::vector<double>& v) {
  for (double& x : v) x = static_cast<double>(static_cast<float>(x));
}

}  // namespace

int FrontEndOutputs(const std::vector<ConvLayer>& conv) {
  if (conv.empty()) return kHapticInputs;
  return conv.back().out_channels * (kWindowPoints >> conv.size());
}

absl::StatusOr<HapticNetWeights> WeightsWithFrontEnd(
    const std::vector<int>& conv_channels) {
  // 64 points halve to 1 after six layers.
  if (conv_channels.size() > 6) {
    return absl::InvalidArgumentError(
        absl::StrCat("a convolutional front end of ", conv_channels.size(),
                     " layers: at most 6 (each halves the 64 points)"));
  }
  HapticNetWeights weights;
  int in_channels = kWrenchChannels;
  for (int out_channels : conv_channels) {
    if (out_channels < 1) {
      return absl::InvalidArgumentError(absl::StrCat(
          "a convolutional layer of ", out_channels, " channels: need >= 1"));
    }
    ConvLayer layer;
    layer.in_channels = in_channels;
    layer.out_channels = out_channels;
    layer.weight.assign(
        static_cast<size_t>(in_channels) * kConvKernel * out_channels, 0.0);
    layer.bias.assign(out_channels, 0.0);
    weights.conv.push_back(std::move(layer));
    in_channels = out_channels;
  }
  weights.w1 = RowMatrix::Zero(FrontEndOutputs(weights.conv), kHapticHidden);
  return weights;
}

void ConvForward(const ConvLayer& layer, const double* in, int length,
                 double* pre_activation, double* out, int* argmax) {
  const int outs = layer.out_channels;
  for (int co = 0; co < outs; ++co) {
    std::fill(pre_activation + static_cast<size_t>(co) * length,
              pre_activation + static_cast<size_t>(co + 1) * length,
              layer.bias[co]);
  }
  for (int ci = 0; ci < layer.in_channels; ++ci) {
    const double* x = in + static_cast<size_t>(ci) * length;
    for (int t = 0; t < kConvKernel; ++t) {
      const auto [shift, begin, end] = SpanOf(t, length);
      const double* w = layer.weight.data() +
                        static_cast<size_t>(ci * kConvKernel + t) * outs;
      for (int co = 0; co < outs; ++co) {
        const double w_co = w[co];
        double* z = pre_activation + static_cast<size_t>(co) * length;
        for (int l = begin; l < end; ++l) z[l] += w_co * x[l + shift];
      }
    }
  }
  const int half = length / 2;
  for (int co = 0; co < outs; ++co) {
    const double* z = pre_activation + static_cast<size_t>(co) * length;
    for (int j = 0; j < half; ++j) {
      const double a = std::max(z[2 * j], 0.0);
      const double b = std::max(z[2 * j + 1], 0.0);
      const int from = b > a ? 2 * j + 1 : 2 * j;
      out[static_cast<size_t>(co) * half + j] = std::max(a, b);
      if (argmax != nullptr) {
        argmax[static_cast<size_t>(co) * half + j] = co * length + from;
      }
    }
  }
}

void RoundToFloat(HapticNetWeights& weights) {
  for (ConvLayer& layer : weights.conv) {
    RoundVector(layer.weight);
    RoundVector(layer.bias);
  }
  RoundMatrix(weights.input_mean);
  RoundMatrix(weights.input_stddev);
  RoundMatrix(weights.w1);
  RoundMatrix(weights.b1);
  RoundMatrix(weights.w2);
  RoundMatrix(weights.b2);
  RoundMatrix(weights.w3);
  RoundMatrix(weights.b3);
}

std::array<double, kHapticClasses> ReferenceLogits(
    const HapticNetWeights& weights,
    const std::array<float, kHapticInputs>& inputs) {
  Eigen::RowVectorXd x(kHapticInputs);
  for (int i = 0; i < kHapticInputs; ++i) x[i] = inputs[i];
  Eigen::RowVectorXd features =
      (x - weights.input_mean).cwiseQuotient(weights.input_stddev);
  int length = kWindowPoints;
  for (const ConvLayer& layer : weights.conv) {
    std::vector<double> pre(static_cast<size_t>(layer.out_channels) * length);
    Eigen::RowVectorXd pooled(layer.out_channels * (length / 2));
    ConvForward(layer, features.data(), length, pre.data(), pooled.data(),
                nullptr);
    features = std::move(pooled);
    length /= 2;
  }
  const Eigen::RowVectorXd h1 =
      (features * weights.w1 + weights.b1).cwiseMax(0.0);
  const Eigen::RowVectorXd h2 = (h1 * weights.w2 + weights.b2).cwiseMax(0.0);
  const Eigen::RowVectorXd logits = h2 * weights.w3 + weights.b3;
  std::array<double, kHapticClasses> out;
  for (int k = 0; k < kHapticClasses; ++k) out[k] = logits[k];
  return out;
}

std::array<double, kHapticClasses> ReferenceProbabilities(
    const HapticNetWeights& weights,
    const std::array<float, kHapticInputs>& inputs) {
  std::array<double, kHapticClasses> p = ReferenceLogits(weights, inputs);
  double max_logit = p[0];
  for (double v : p) max_logit = std::max(max_logit, v);
  double sum = 0.0;
  for (double& v : p) {
    v = std::exp(v - max_logit);
    sum += v;
  }
  for (double& v : p) v /= sum;
  return p;
}

namespace {

void SetIntAttribute(onnx::NodeProto* node, const char* name, int64_t value) {
  onnx::AttributeProto* attribute = node->add_attribute();
  attribute->set_name(name);
  attribute->set_type(onnx::AttributeProto::INT);
  attribute->set_i(value);
}

// One member's layers, names prefixed by `prefix`, from the input window
// to `logits`.
void AddMember(onnx::GraphProto* graph, const HapticNetWeights& weights,
               const std::string& prefix, const std::string& logits) {
  AddFloatTensor(graph, prefix + "input_mean", {1, kHapticInputs},
                 weights.input_mean.data(), kHapticInputs);
  AddFloatTensor(graph, prefix + "input_stddev", {1, kHapticInputs},
                 weights.input_stddev.data(), kHapticInputs);
  // Gemm weights go out as [fan_out, fan_in] with transB = 1, PyTorch's
  // export convention: OpenCV 4.6's importer mishandles transB = 0.
  AddGemmWeights(graph, prefix + "fc1", weights.w1, weights.b1);
  AddGemmWeights(graph, prefix + "fc2", weights.w2, weights.b2);
  AddGemmWeights(graph, prefix + "fc3", weights.w3, weights.b3);

  AddNode(graph, "Sub", {kHapticNetInputName, prefix + "input_mean"},
          prefix + "centred");
  AddNode(graph, "Div", {prefix + "centred", prefix + "input_stddev"},
          prefix + "normalised");
  std::string fc1_input = prefix + "normalised";
  if (!weights.conv.empty()) {
    // The window as an image of 6 channels, 1 row and 64 columns, so that
    // Conv and MaxPool are the 2-D operators every importer knows.
    AddInt64Tensor(graph, prefix + "window_shape",
                   {1, kWrenchChannels, 1, kWindowPoints});
    AddNode(graph, "Reshape", {fc1_input, prefix + "window_shape"},
            prefix + "window");
    std::string input = prefix + "window";
    for (size_t i = 0; i < weights.conv.size(); ++i) {
      const ConvLayer& layer = weights.conv[i];
      const std::string name = absl::StrCat(prefix, "conv", i + 1);
      // ONNX holds the kernel [out, in, 1, kConvKernel].
      std::vector<double> kernel(layer.weight.size());
      for (int co = 0; co < layer.out_channels; ++co) {
        for (int ci = 0; ci < layer.in_channels; ++ci) {
          for (int t = 0; t < kConvKernel; ++t) {
            kernel[(static_cast<size_t>(co) * layer.in_channels + ci) *
                       kConvKernel +
                   t] = layer.weight[static_cast<size_t>(ci * kConvKernel + t) *
                                         layer.out_channels +
                                     co];
          }
        }
      }
      AddFloatTensor(graph, name + ".weight",
                     {layer.out_channels, layer.in_channels, 1, kConvKernel},
                     kernel.data(), static_cast<int64_t>(kernel.size()));
      AddFloatTensor(graph, name + ".bias", {layer.out_channels},
                     layer.bias.data(), layer.out_channels);
      onnx::NodeProto* conv = AddNode(
          graph, "Conv", {input, name + ".weight", name + ".bias"}, name);
      SetIntsAttribute(conv, "kernel_shape", {1, kConvKernel});
      SetIntsAttribute(conv, "pads", {0, kConvKernel / 2, 0, kConvKernel / 2});
      SetIntsAttribute(conv, "strides", {1, 1});
      AddNode(graph, "Relu", {name}, name + ".relu");
      onnx::NodeProto* pool =
          AddNode(graph, "MaxPool", {name + ".relu"}, name + ".pool");
      SetIntsAttribute(pool, "kernel_shape", {1, 2});
      SetIntsAttribute(pool, "strides", {1, 2});
      input = name + ".pool";
    }
    AddInt64Tensor(graph, prefix + "features_shape",
                   {1, FrontEndOutputs(weights.conv)});
    AddNode(graph, "Reshape", {input, prefix + "features_shape"},
            prefix + "features");
    fc1_input = prefix + "features";
  }
  AddGemm(graph, fc1_input, prefix + "fc1", prefix + "fc1");
  AddNode(graph, "Relu", {prefix + "fc1"}, prefix + "relu1");
  AddGemm(graph, prefix + "relu1", prefix + "fc2", prefix + "fc2");
  AddNode(graph, "Relu", {prefix + "fc2"}, prefix + "relu2");
  AddGemm(graph, prefix + "relu2", prefix + "fc3", logits);
}

}  // namespace

std::string HapticNetToOnnx(
    const HapticNetWeights& weights,
    const std::map<std::string, std::string>& metadata) {
  return HapticEnsembleToOnnx({weights}, metadata);
}

absl::StatusOr<HapticNetWeights> HapticNetWeightsFromOnnx(
    const std::string& bytes, const std::string& source) {
  onnx::ModelProto model;
  if (!model.ParseFromString(bytes)) {
    return absl::InvalidArgumentError(
        absl::StrCat(source, " is not an ONNX model"));
  }
  std::map<std::string, const onnx::TensorProto*> tensors;
  for (const onnx::TensorProto& tensor : model.graph().initializer()) {
    tensors[tensor.name()] = &tensor;
  }
  HapticNetWeights weights;
  // Reads initializer `name` (float_data or raw little-endian floats) of
  // `rows` x `cols` values into `out`, transposed when the file holds it
  // [cols, rows] (the Gemm weights).
  auto read = [&](const std::string& name, int64_t count,
                  std::vector<double>* out) -> absl::Status {
    const auto it = tensors.find(name);
    if (it == tensors.end()) {
      return absl::InvalidArgumentError(absl::StrCat(
          source, " has no initializer \"", name,
          "\" (not a single HapticNet written by bitewise-haptic-train)"));
    }
    const onnx::TensorProto& tensor = *it->second;
    out->clear();
    if (tensor.float_data_size() > 0) {
      for (float v : tensor.float_data()) out->push_back(v);
    } else {
      const std::string& raw = tensor.raw_data();
      for (size_t i = 0; i + 4 <= raw.size(); i += 4) {
        float v;
        std::memcpy(&v, raw.data() + i, 4);
        out->push_back(v);
      }
    }
    if (static_cast<int64_t>(out->size()) != count) {
      return absl::InvalidArgumentError(
          absl::StrCat(source, ": initializer \"", name, "\" holds ",
                       out->size(), " values, expected ", count));
    }
    return absl::OkStatus();
  };
  std::vector<double> v;
  absl::Status status = read("input_mean", kHapticInputs, &v);
  if (!status.ok()) return status;
  for (int i = 0; i < kHapticInputs; ++i) weights.input_mean[i] = v[i];
  status = read("input_stddev", kHapticInputs, &v);
  if (!status.ok()) return status;
  for (int i = 0; i < kHapticInputs; ++i) weights.input_stddev[i] = v[i];
  // The front end, if any: conv1, conv2, ... as long as they exist.
  int in_channels = kWrenchChannels;
  for (int i = 1; tensors.count(absl::StrCat("conv", i, ".weight")) > 0; ++i) {
    const std::string name = absl::StrCat("conv", i);
    const onnx::TensorProto& kernel = *tensors[name + ".weight"];
    if (kernel.dims_size() != 4 || kernel.dims(1) != in_channels ||
        kernel.dims(2) != 1 || kernel.dims(3) != kConvKernel ||
        kernel.dims(0) < 1 || i > 6) {
      return absl::InvalidArgumentError(absl::StrCat(
          source, ": initializer \"", name, ".weight\" is not a kernel [out, ",
          in_channels, ", 1, ", kConvKernel, "] of HapticNet's front end"));
    }
    ConvLayer layer;
    layer.in_channels = in_channels;
    layer.out_channels = static_cast<int>(kernel.dims(0));
    status = read(
        name + ".weight",
        static_cast<int64_t>(layer.out_channels) * in_channels * kConvKernel,
        &v);
    if (!status.ok()) return status;
    layer.weight.resize(v.size());
    for (int co = 0; co < layer.out_channels; ++co) {
      for (int ci = 0; ci < in_channels; ++ci) {
        for (int t = 0; t < kConvKernel; ++t) {
          layer.weight[static_cast<size_t>(ci * kConvKernel + t) *
                           layer.out_channels +
                       co] =
              v[(static_cast<size_t>(co) * in_channels + ci) * kConvKernel + t];
        }
      }
    }
    status = read(name + ".bias", layer.out_channels, &layer.bias);
    if (!status.ok()) return status;
    in_channels = layer.out_channels;
    weights.conv.push_back(std::move(layer));
  }
  weights.w1 = RowMatrix::Zero(FrontEndOutputs(weights.conv), kHapticHidden);
  struct Layer {
    const char* name;
    RowMatrix* w;
    Eigen::RowVectorXd* b;
  };
  for (const Layer& layer : {Layer{"fc1", &weights.w1, &weights.b1},
                             Layer{"fc2", &weights.w2, &weights.b2},
                             Layer{"fc3", &weights.w3, &weights.b3}}) {
    const int64_t in = layer.w->rows(), out = layer.w->cols();
    status = read(absl::StrCat(layer.name, ".weight"), in * out, &v);
    if (!status.ok()) return status;
    for (int64_t o = 0; o < out; ++o) {  // stored [fan_out, fan_in]
      for (int64_t i = 0; i < in; ++i) (*layer.w)(i, o) = v[o * in + i];
    }
    status = read(absl::StrCat(layer.name, ".bias"), out, &v);
    if (!status.ok()) return status;
    for (int64_t o = 0; o < out; ++o) (*layer.b)[o] = v[o];
  }
  return weights;
}

std::array<double, kHapticClasses> ReferenceEnsembleProbabilities(
    const std::vector<HapticNetWeights>& members,
    const std::array<float, kHapticInputs>& inputs) {
  std::array<double, kHapticClasses> mean{};
  for (const HapticNetWeights& member : members) {
    const std::array<double, kHapticClasses> p =
        ReferenceProbabilities(member, inputs);
    for (int k = 0; k < kHapticClasses; ++k) {
      mean[k] += p[k] / static_cast<double>(members.size());
    }
  }
  return mean;
}

std::string HapticEnsembleToOnnx(
    const std::vector<HapticNetWeights>& members,
    const std::map<std::string, std::string>& metadata) {
  onnx::ModelProto model;
  // IR version 6 goes with opset 11, which OpenCV 4.6's importer covers.
  model.set_ir_version(6);
  model.set_producer_name("bitewise-haptic-train");
  model.set_domain("bitewise.haptic");
  model.set_model_version(1);
  model.set_doc_string(
      members.size() == 1
          ? absl::StrCat(
                "HapticNet: tared force/torque window (6 channels fx fy fz tx "
                "ty tz, each resampled to 64 points, channel-major) -> 4 "
                "classes hard, medium, soft, hard_skin. Normalisation (x - "
                "input_mean) / input_stddev is part of the graph.",
                members[0].conv.empty()
                    ? ""
                    : " A convolutional front end (Conv of kernel 5, Relu, "
                      "MaxPool by 2, per layer) feeds fc1.")
          : "HapticNet ensemble: members m0, m1, ... each a HapticNet "
            "(normalisation and three Gemm layers); logits = log of the mean "
            "of the members' softmax, probabilities = softmax(logits), the "
            "same mean.");
  onnx::OperatorSetIdProto* opset = model.add_opset_import();
  opset->set_domain("");
  opset->set_version(11);
  for (const auto& [key, value] : metadata) {
    onnx::StringStringEntryProto* entry = model.add_metadata_props();
    entry->set_key(key);
    entry->set_value(value);
  }

  onnx::GraphProto* graph = model.mutable_graph();
  graph->set_name("hapticnet");
  if (members.size() == 1) {
    // A single model keeps the names of the original graph.
    AddMember(graph, members[0], "", kHapticNetLogitsName);
  } else {
    std::vector<std::string> member_probabilities;
    for (size_t m = 0; m < members.size(); ++m) {
      const std::string prefix = absl::StrCat("m", m, ".");
      AddMember(graph, members[m], prefix, prefix + "logits");
      onnx::NodeProto* softmax = AddNode(graph, "Softmax", {prefix + "logits"},
                                         prefix + "probabilities");
      SetIntAttribute(softmax, "axis", 1);
      member_probabilities.push_back(prefix + "probabilities");
    }
    const std::vector<double> share(kHapticClasses, 1.0 / members.size());
    AddFloatTensor(graph, "member_share", {1, kHapticClasses}, share.data(),
                   kHapticClasses);
    AddNode(graph, "Sum", member_probabilities, "member_sum");
    AddNode(graph, "Mul", {"member_sum", "member_share"}, "mean_probabilities");
    AddNode(graph, "Log", {"mean_probabilities"}, kHapticNetLogitsName);
  }
  onnx::NodeProto* softmax = AddNode(graph, "Softmax", {kHapticNetLogitsName},
                                     kHapticNetProbabilitiesName);
  SetIntAttribute(softmax, "axis", 1);

  SetFloatShape(graph->add_input(), kHapticNetInputName, 1, kHapticInputs);
  SetFloatShape(graph->add_output(), kHapticNetLogitsName, 1, kHapticClasses);
  SetFloatShape(graph->add_output(), kHapticNetProbabilitiesName, 1,
                kHapticClasses);

  std::string bytes;
  {
    google::protobuf::io::StringOutputStream stream(&bytes);
    google::protobuf::io::CodedOutputStream coded(&stream);
    coded.SetSerializationDeterministic(true);
    model.SerializeToCodedStream(&coded);
  }
  return bytes;
}

}  // namespace bitewise::haptic
