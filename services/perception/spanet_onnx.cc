#include "services/perception/spanet_onnx.h"

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "absl/strings/string_view.h"
#include "onnx/onnx_pb.h"

namespace bitewise::perception {
namespace {

// Builds the graph node by node, keeping the weights' random stream in
// one place so that the file depends on the seed only.
class SpanetGraphBuilder {
 public:
  SpanetGraphBuilder(onnx::GraphProto* graph, uint64_t seed)
      : graph_(graph), rng_(seed) {}

  // Conv2d(in, out, k, padding k/2) named like PyTorch's module `name`.
  std::string Conv(const std::string& input, const std::string& name, int in,
                   int out, int kernel) {
    const int fan_in = in * kernel * kernel;
    Weights(name + ".weight", {out, in, kernel, kernel}, HeLimit(fan_in));
    Weights(name + ".bias", {out}, 1.0 / std::sqrt(fan_in));
    return ConvWith(input, name, kernel);
  }

  // A second use of an existing Conv's weights (SPANet reuses
  // conv_layers_bot three times).
  std::string ConvWith(const std::string& input, const std::string& name,
                       int kernel) {
    const int pad = kernel / 2;
    onnx::NodeProto* node =
        Node("Conv", {input, name + ".weight", name + ".bias"});
    IntsAttribute(node, "kernel_shape", {kernel, kernel});
    IntsAttribute(node, "pads", {pad, pad, pad, pad});
    IntsAttribute(node, "strides", {1, 1});
    return node->output(0);
  }

  // BatchNorm (eval mode: running statistics) named like PyTorch's.
  std::string BatchNorm(const std::string& input, const std::string& name,
                        int channels, bool create = true) {
    if (create) {
      Weights(name + ".weight", {channels}, 0.2, 1.0);
      Weights(name + ".bias", {channels}, 0.1);
      Weights(name + ".running_mean", {channels}, 0.1);
      Weights(name + ".running_var", {channels}, 0.5, 1.0);
    }
    onnx::NodeProto* node = Node(
        "BatchNormalization", {input, name + ".weight", name + ".bias",
                               name + ".running_mean", name + ".running_var"});
    FloatAttribute(node, "epsilon", 1e-5f);
    return node->output(0);
  }

  std::string Relu(const std::string& input, const std::string& output = "") {
    return Node("Relu", {input}, output)->output(0);
  }

  std::string MaxPool(const std::string& input) {
    onnx::NodeProto* node = Node("MaxPool", {input});
    IntsAttribute(node, "kernel_shape", {2, 2});
    IntsAttribute(node, "strides", {2, 2});
    return node->output(0);
  }

  std::string Add(const std::string& a, const std::string& b) {
    return Node("Add", {a, b})->output(0);
  }

  std::string Flatten(const std::string& input) {
    onnx::NodeProto* node = Node("Flatten", {input});
    IntAttribute(node, "axis", 1);
    return node->output(0);
  }

  std::string Concat(const std::string& a, const std::string& b) {
    onnx::NodeProto* node = Node("Concat", {a, b});
    IntAttribute(node, "axis", 1);
    return node->output(0);
  }

  // nn.Linear(in, out) as Gemm with the weight stored [out, in].
  std::string Linear(const std::string& input, const std::string& name, int in,
                     int out, double limit) {
    Weights(name + ".weight", {out, in}, limit);
    Weights(name + ".bias", {out}, 1.0 / std::sqrt(in));
    onnx::NodeProto* node =
        Node("Gemm", {input, name + ".weight", name + ".bias"});
    IntAttribute(node, "transB", 1);
    return node->output(0);
  }

  std::string Sigmoid(const std::string& input, const std::string& output) {
    return Node("Sigmoid", {input}, output)->output(0);
  }

  // He-uniform: keeps activations at a stable scale through ReLU layers,
  // so the untrained network's features are neither vanishing nor huge.
  static double HeLimit(int fan_in) { return std::sqrt(6.0 / fan_in); }

 private:
  // Uniform in [centre - half, centre + half), from the raw 64-bit stream
  // (std:: distributions are not specified bit for bit across libraries).
  double Uniform(double half, double centre) {
    const double unit = static_cast<double>(rng_() >> 11) * 0x1.0p-53;
    return centre + half * (2.0 * unit - 1.0);
  }

  void Weights(const std::string& name, const std::vector<int64_t>& dims,
               double half, double centre = 0.0) {
    onnx::TensorProto* tensor = graph_->add_initializer();
    tensor->set_name(name);
    tensor->set_data_type(onnx::TensorProto::FLOAT);
    int64_t count = 1;
    for (int64_t d : dims) {
      tensor->add_dims(d);
      count *= d;
    }
    std::vector<float> values(static_cast<size_t>(count));
    for (float& v : values) v = static_cast<float>(Uniform(half, centre));
    // raw_data is little-endian by the ONNX spec, as on every supported
    // build machine.
    tensor->set_raw_data(
        std::string(reinterpret_cast<const char*>(values.data()),
                    values.size() * sizeof(float)));
  }

  onnx::NodeProto* Node(const std::string& op,
                        const std::vector<std::string>& inputs,
                        const std::string& output = "") {
    onnx::NodeProto* node = graph_->add_node();
    node->set_op_type(op);
    node->set_name(absl::StrCat(op, "_", next_id_));
    for (const std::string& in : inputs) node->add_input(in);
    node->add_output(output.empty() ? absl::StrCat("t", next_id_) : output);
    ++next_id_;
    return node;
  }

  static void IntsAttribute(onnx::NodeProto* node, const std::string& name,
                            const std::vector<int64_t>& values) {
    onnx::AttributeProto* a = node->add_attribute();
    a->set_name(name);
    a->set_type(onnx::AttributeProto::INTS);
    for (int64_t v : values) a->add_ints(v);
  }
  static void IntAttribute(onnx::NodeProto* node, const std::string& name,
                           int64_t value) {
    onnx::AttributeProto* a = node->add_attribute();
    a->set_name(name);
    a->set_type(onnx::AttributeProto::INT);
    a->set_i(value);
  }
  static void FloatAttribute(onnx::NodeProto* node, const std::string& name,
                             float value) {
    onnx::AttributeProto* a = node->add_attribute();
    a->set_name(name);
    a->set_type(onnx::AttributeProto::FLOAT);
    a->set_f(value);
  }

  onnx::GraphProto* graph_;
  std::mt19937_64 rng_;
  int next_id_ = 0;
};

void AddInput(onnx::GraphProto* graph, const std::string& name,
              const std::vector<int64_t>& dims) {
  onnx::ValueInfoProto* info = graph->add_input();
  info->set_name(name);
  onnx::TypeProto::Tensor* t = info->mutable_type()->mutable_tensor_type();
  t->set_elem_type(onnx::TensorProto::FLOAT);
  onnx::TensorShapeProto* shape = t->mutable_shape();
  shape->add_dim()->set_dim_value(1);
  for (int64_t d : dims) shape->add_dim()->set_dim_value(d);
}

void AddOutput(onnx::GraphProto* graph, const std::string& name, int64_t dim) {
  onnx::ValueInfoProto* info = graph->add_output();
  info->set_name(name);
  onnx::TypeProto::Tensor* t = info->mutable_type()->mutable_tensor_type();
  t->set_elem_type(onnx::TensorProto::FLOAT);
  t->mutable_shape()->add_dim()->set_dim_value(1);
  t->mutable_shape()->add_dim()->set_dim_value(dim);
}

}  // namespace

absl::Status WriteSpanetOnnx(const std::string& path,
                             const SpanetOnnxOptions& options) {
  if (options.hidden_features <= 0) {
    return absl::InvalidArgumentError(absl::StrCat(
        "hidden_features must be > 0 (got ", options.hidden_features, ")"));
  }
  onnx::ModelProto model;
  model.set_ir_version(7);
  model.set_producer_name("bitewise-spanet-onnx");
  model.set_doc_string(absl::StrCat(
      "SPANet (RGB, with location one-hot), untrained; seeded weights, seed ",
      options.seed));
  onnx::OperatorSetIdProto* opset = model.add_opset_import();
  opset->set_domain("");
  opset->set_version(11);
  onnx::GraphProto* graph = model.mutable_graph();
  graph->set_name("spanet");
  AddInput(graph, "rgb", {3, 144, 144});
  AddInput(graph, "loc_type", {3});

  SpanetGraphBuilder b(graph, options.seed);
  // conv_init_rgb: 144x144x3 -> 72x72x32.
  std::string x = b.Conv("rgb", "conv_init_rgb.0", 3, 16, 7);
  x = b.Relu(b.BatchNorm(x, "conv_init_rgb.1", 16));
  x = b.Conv(x, "conv_init_rgb.3", 16, 32, 3);
  x = b.Relu(b.MaxPool(b.BatchNorm(x, "conv_init_rgb.4", 32)));
  // conv_layers_top: 72 -> 36 -> 18 -> 9, 32 -> 64 -> 128 -> 256 channels.
  const int channels[] = {32, 64, 128, 256};
  for (int i = 0; i < 3; ++i) {
    const std::string conv = absl::StrCat("conv_layers_top.", 4 * i);
    const std::string bn = absl::StrCat("conv_layers_top.", 4 * i + 1);
    x = b.Conv(x, conv, channels[i], channels[i + 1], 3);
    x = b.Relu(b.MaxPool(b.BatchNorm(x, bn, channels[i + 1])));
  }
  // conv_layers_bot, three residual applications of the same weights.
  for (int i = 0; i < 3; ++i) {
    const std::string y = i == 0 ? b.Conv(x, "conv_layers_bot.0", 256, 256, 3)
                                 : b.ConvWith(x, "conv_layers_bot.0", 3);
    x = b.Add(b.Relu(b.BatchNorm(y, "conv_layers_bot.1", 256, i == 0)), x);
  }
  x = b.Concat(b.Flatten(x), "loc_type");
  const int flat = 9 * 9 * 256 + 3;
  const int hidden = options.hidden_features;
  x = b.Linear(x, "linear_layers.0", flat, hidden,
               SpanetGraphBuilder::HeLimit(flat));
  x = b.Relu(b.BatchNorm(x, "linear_layers.1", hidden));
  x = b.Linear(x, "linear_layers.3", hidden, hidden,
               SpanetGraphBuilder::HeLimit(hidden));
  x = b.Relu(b.BatchNorm(x, "linear_layers.4", hidden), "features");
  // Glorot-uniform head scaled by 1/8: the untrained features have an RMS
  // of about 8 (He init through three residual blocks), and this keeps the
  // sigmoid's inputs of order one, so the scores spread over (0, 1) instead
  // of saturating.
  x = b.Linear(x, "final", hidden, 10, std::sqrt(6.0 / (hidden + 10)) / 8);
  b.Sigmoid(x, "scores");
  AddOutput(graph, "features", hidden);
  AddOutput(graph, "scores", 10);

  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) {
    return absl::FailedPreconditionError(
        absl::StrCat("cannot open \"", path, "\" for writing"));
  }
  if (!model.SerializeToOstream(&out) || !out.flush()) {
    return absl::FailedPreconditionError(
        absl::StrCat("writing the SPANet model to \"", path, "\" failed"));
  }
  return absl::OkStatus();
}

absl::Status CheckSpanetOnnxGraph(const std::string& path) {
  const auto fail = [&path](absl::string_view what) {
    return absl::FailedPreconditionError(
        absl::StrCat("SPANet model file \"", path, "\" ", what));
  };
  std::error_code error;
  if (std::filesystem::is_directory(path, error)) {
    return fail("is a directory, not an ONNX file");
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) return fail("cannot be opened");
  // An empty file parses as an empty model, which would be said to lack
  // SPANet's inputs.
  if (in.peek() == std::ifstream::traits_type::eof()) {
    return fail("is empty (0 bytes): not an ONNX model");
  }
  onnx::ModelProto model;
  if (!model.ParseFromIstream(&in))
    return fail("is not a loadable ONNX model: it does not parse as ONNX");
  const onnx::GraphProto& graph = model.graph();
  // First, as the likeliest cause of everything else that differs (a
  // training-mode export also needs a batch of two or more).
  for (const auto& node : graph.node()) {
    if (node.op_type() != "BatchNormalization") continue;
    bool training = node.output_size() > 1;
    for (const auto& a : node.attribute()) {
      training |= a.name() == "training_mode" && a.i() != 0;
    }
    if (training) {
      return fail(absl::StrCat(
          "was exported with BatchNorm in training mode (node \"", node.name(),
          "\" uses batch statistics); export after model.eval() "
          "(scripts/spanet/export_onnx.py does)"));
    }
  }
  const auto shape_of = [](const onnx::ValueInfoProto& info) {
    std::vector<int64_t> dims;
    for (const auto& d : info.type().tensor_type().shape().dim()) {
      dims.push_back(d.has_dim_value() ? d.dim_value() : -1);
    }
    return dims;
  };
  const std::vector<std::pair<std::string, std::vector<int64_t>>> inputs = {
      {"rgb", {1, 3, 144, 144}}, {"loc_type", {1, 3}}};
  for (const auto& [name, want] : inputs) {
    const onnx::ValueInfoProto* found = nullptr;
    for (const auto& info : graph.input()) {
      if (info.name() == name) found = &info;
    }
    if (found == nullptr) {
      return fail(absl::StrCat("has no input \"", name, "\""));
    }
    if (shape_of(*found) != want) {
      return fail(
          absl::StrCat("input \"", name, "\" has shape [",
                       absl::StrJoin(shape_of(*found), ","), "]; SPANet's is [",
                       absl::StrJoin(want, ","),
                       "] (batch fixed at 1; -1 is a symbolic dimension)"));
    }
  }
  for (const char* name : {"features", "scores"}) {
    bool found = false;
    for (const auto& info : graph.output()) found |= info.name() == name;
    if (!found) return fail(absl::StrCat("has no output \"", name, "\""));
  }
  return absl::OkStatus();
}

}  // namespace bitewise::perception
