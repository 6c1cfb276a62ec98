#include "services/haptic/core/haptic_net.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <map>
#include <sstream>
#include <utility>
#include <vector>

#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "onnx/onnx_pb.h"

namespace bitewise::haptic {
namespace {

std::string Fingerprint(absl::string_view bytes) {
  uint64_t hash = 14695981039346656037ull;
  for (unsigned char byte : bytes) {
    hash ^= byte;
    hash *= 1099511628211ull;
  }
  return absl::StrFormat("fnv1a64:%016x", hash);
}

// One forward pass; `net` must be guarded by the caller.
absl::StatusOr<HapticNetOutput> Forward(
    cv::dnn::Net& net, const std::array<float, kHapticInputs>& inputs) {
  std::vector<cv::Mat> outputs;
  try {
    cv::Mat blob(1, kHapticInputs, CV_32F, const_cast<float*>(inputs.data()));
    net.setInput(blob, kHapticNetInputName);
    net.forward(outputs, std::vector<std::string>{kHapticNetLogitsName,
                                                  kHapticNetProbabilitiesName});
  } catch (const cv::Exception& e) {
    return absl::InternalError(
        absl::StrCat("HapticNet forward pass failed: ", e.what()));
  }
  if (outputs.size() != 2 || outputs[0].total() != kHapticClasses ||
      outputs[1].total() != kHapticClasses || outputs[0].type() != CV_32F ||
      outputs[1].type() != CV_32F) {
    return absl::InternalError(
        absl::StrCat("HapticNet outputs \"", kHapticNetLogitsName, "\" and \"",
                     kHapticNetProbabilitiesName, "\" must each hold ",
                     kHapticClasses, " floats"));
  }
  const float* logits = outputs[0].ptr<float>();
  const float* probabilities = outputs[1].ptr<float>();
  double max_logit = logits[0];
  for (int k = 0; k < kHapticClasses; ++k) {
    if (!std::isfinite(logits[k]) || !std::isfinite(probabilities[k])) {
      return absl::InternalError("HapticNet produced a non-finite output");
    }
    max_logit = std::max(max_logit, static_cast<double>(logits[k]));
  }
  double sum = 0.0;
  for (int k = 0; k < kHapticClasses; ++k) {
    sum += std::exp(logits[k] - max_logit);
  }
  const double log_normaliser = max_logit + std::log(sum);
  HapticNetOutput out;
  for (int k = 0; k < kHapticClasses; ++k) {
    out.log_probabilities[k] = logits[k] - log_normaliser;
    out.probabilities[k] = std::exp(out.log_probabilities[k]);
    // The graph's float softmax must agree; a model whose "probabilities"
    // output is not the softmax of its "logits" breaks the contract.
    if (std::abs(out.probabilities[k] - probabilities[k]) > 1e-4) {
      return absl::InternalError(absl::StrFormat(
          "HapticNet output \"%s\" is not the softmax of \"%s\" (class %d: "
          "%g vs %g)",
          kHapticNetProbabilitiesName, kHapticNetLogitsName, k,
          probabilities[k], out.probabilities[k]));
    }
  }
  return out;
}

// The graph contract's normalisation: the raw window goes only into
// Sub(<...>input_mean) and on into Div(<...>input_stddev), both [1, 384]
// initializers (an ensemble's members each have their own). A model
// exported without them (the original research code normalised outside
// the graph) would run on raw windows and answer nonsense with confidence.
absl::Status CheckNormalisation(const onnx::ModelProto& model,
                                const std::string& source) {
  const onnx::GraphProto& graph = model.graph();
  std::map<std::string, int64_t> initializer_size;
  for (const onnx::TensorProto& t : graph.initializer()) {
    int64_t size = 1;
    for (int64_t d : t.dims()) size *= d;
    initializer_size[t.name()] = size;
  }
  const auto is_statistic = [&](const std::string& name,
                                absl::string_view suffix) {
    const auto it = initializer_size.find(name);
    return absl::EndsWith(name, suffix) && it != initializer_size.end() &&
           it->second == kHapticInputs;
  };
  const auto refuse = [&](const std::string& why) {
    return absl::InvalidArgumentError(
        absl::StrCat("HapticNet model ", source,
                     " does not normalise its input in the "
                     "graph (docs/haptic.md, graph contract: \"",
                     kHapticNetInputName,
                     "\" -> Sub(input_mean) -> Div(input_stddev), both [1, ",
                     kHapticInputs, "] initializers): ", why));
  };
  int users = 0;
  for (const onnx::NodeProto& node : graph.node()) {
    if (std::find(node.input().begin(), node.input().end(),
                  kHapticNetInputName) == node.input().end()) {
      continue;
    }
    ++users;
    if (node.op_type() != "Sub" || node.input_size() != 2 ||
        node.input(0) != kHapticNetInputName ||
        !is_statistic(node.input(1), "input_mean") || node.output_size() != 1) {
      return refuse(absl::StrCat("the input goes into a ", node.op_type(),
                                 " node \"", node.name(), "\""));
    }
    bool divided = false;
    for (const onnx::NodeProto& next : graph.node()) {
      if (std::find(next.input().begin(), next.input().end(), node.output(0)) ==
          next.input().end()) {
        continue;
      }
      if (next.op_type() != "Div" || next.input_size() != 2 ||
          next.input(0) != node.output(0) ||
          !is_statistic(next.input(1), "input_stddev")) {
        return refuse(absl::StrCat("after input_mean comes a ", next.op_type(),
                                   " node \"", next.name(), "\""));
      }
      divided = true;
    }
    if (!divided) return refuse("nothing divides by input_stddev");
  }
  if (users == 0) return refuse("no node reads the input");
  return absl::OkStatus();
}

// The model's "bitewise.window_s" metadata entry, if any, after the
// normalisation check.
absl::StatusOr<std::optional<double>> DeclaredWindow(
    absl::string_view bytes, const std::string& source) {
  onnx::ModelProto model;
  if (!model.ParseFromArray(bytes.data(), static_cast<int>(bytes.size()))) {
    return absl::InvalidArgumentError(absl::StrCat(
        "HapticNet model ", source, " is not a parsable ONNX ModelProto"));
  }
  if (absl::Status normalised = CheckNormalisation(model, source);
      !normalised.ok()) {
    return normalised;
  }
  for (const onnx::StringStringEntryProto& entry : model.metadata_props()) {
    if (entry.key() != kHapticNetWindowKey) continue;
    double window_s = 0.0;
    if (!absl::SimpleAtod(entry.value(), &window_s) ||
        !std::isfinite(window_s) || window_s <= 0.0 || window_s > 1.0) {
      return absl::InvalidArgumentError(absl::StrCat(
          "HapticNet model ", source, ": metadata ", kHapticNetWindowKey,
          " is \"", entry.value(), "\", not a window of seconds in (0, 1]"));
    }
    return window_s;
  }
  return std::nullopt;
}

}  // namespace

absl::StatusOr<std::unique_ptr<HapticNet>> HapticNet::FromOnnxBytes(
    absl::string_view bytes, const std::string& source) {
  if (bytes.empty()) {
    return absl::InvalidArgumentError(
        absl::StrCat("HapticNet model ", source, " is empty"));
  }
  cv::dnn::Net net;
  try {
    net = cv::dnn::readNetFromONNX(bytes.data(), bytes.size());
  } catch (const cv::Exception& e) {
    return absl::InvalidArgumentError(
        absl::StrCat("HapticNet model ", source,
                     " is not a loadable ONNX model: ", e.what()));
  }
  if (net.empty()) {
    return absl::InvalidArgumentError(
        absl::StrCat("HapticNet model ", source, " has no layers"));
  }
  net.setPreferableBackend(cv::dnn::DNN_BACKEND_OPENCV);
  net.setPreferableTarget(cv::dnn::DNN_TARGET_CPU);
  // A model that parses but breaks the graph contract must fail here, at
  // start-up, not on the first request.
  std::array<float, kHapticInputs> zeros{};
  absl::StatusOr<HapticNetOutput> probe = Forward(net, zeros);
  if (!probe.ok()) {
    return absl::InvalidArgumentError(absl::StrCat(
        "HapticNet model ", source,
        " does not match the graph contract (input \"", kHapticNetInputName,
        "\" [1, ", kHapticInputs, "]; outputs \"", kHapticNetLogitsName,
        "\", \"", kHapticNetProbabilitiesName, "\" [1, ", kHapticClasses,
        "]): ", probe.status().message()));
  }
  absl::StatusOr<std::optional<double>> window_s =
      DeclaredWindow(bytes, source);
  if (!window_s.ok()) return window_s.status();
  return std::unique_ptr<HapticNet>(
      new HapticNet(std::move(net), Fingerprint(bytes), *window_s));
}

absl::StatusOr<std::unique_ptr<HapticNet>> HapticNet::FromOnnxFile(
    const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    return absl::NotFoundError(
        absl::StrCat("cannot open HapticNet model file ", path));
  }
  std::ostringstream bytes;
  bytes << in.rdbuf();
  if (in.bad()) {
    return absl::NotFoundError(
        absl::StrCat("cannot read HapticNet model file ", path));
  }
  return FromOnnxBytes(bytes.str(), path);
}

absl::StatusOr<HapticNetOutput> HapticNet::Run(
    const std::array<float, kHapticInputs>& inputs) const {
  absl::MutexLock lock(&mu_);
  return Forward(net_, inputs);
}

}  // namespace bitewise::haptic
