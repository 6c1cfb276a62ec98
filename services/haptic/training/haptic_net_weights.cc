#include "services/haptic/training/haptic_net_weights.h"

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

}  // namespace

void RoundToFloat(HapticNetWeights& weights) {
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
  const Eigen::RowVectorXd normalised =
      (x - weights.input_mean).cwiseQuotient(weights.input_stddev);
  const Eigen::RowVectorXd h1 =
      (normalised * weights.w1 + weights.b1).cwiseMax(0.0);
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
  AddGemm(graph, prefix + "normalised", prefix + "fc1", prefix + "fc1");
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
          ? "HapticNet: tared force/torque window (6 channels fx fy fz tx ty "
            "tz, each resampled to 64 points, channel-major) -> 4 classes "
            "hard, medium, soft, hard_skin. Normalisation (x - input_mean) / "
            "input_stddev is part of the graph."
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
