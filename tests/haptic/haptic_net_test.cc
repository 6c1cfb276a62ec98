// The ONNX round trip: weights written by the trainer's exporter and run by
// OpenCV's DNN module give the outputs of the trainer's own double-precision
// pass, to 1e-5. Plus load-time rejection of files that are not HapticNet
// models, and the embedded default model being the one in the repository.
#include "services/haptic/core/haptic_net.h"

#include <cmath>
#include <fstream>
#include <random>
#include <sstream>
#include <string>

#include "absl/strings/match.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "onnx/onnx_pb.h"
#include "services/haptic/default_model.h"
#include "services/haptic/model_loading.h"
#include "services/haptic/training/haptic_net_weights.h"
#include "services/haptic/training/haptic_trainer.h"
#include "services/haptic/training/labelled_traces.h"

namespace bitewise::haptic {
namespace {

using ::testing::HasSubstr;

// Seeded weights with non-trivial normalisation, so every node of the
// graph matters.
HapticNetWeights RandomWeights(uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  HapticNetWeights w;
  for (int c = 0; c < kWrenchChannels; ++c) {
    const double mean = 2.0 * normal(rng);
    const double stddev = 0.5 + std::abs(normal(rng));
    for (int k = 0; k < kWindowPoints; ++k) {
      w.input_mean[c * kWindowPoints + k] = mean;
      w.input_stddev[c * kWindowPoints + k] = stddev;
    }
  }
  auto fill = [&](auto& m, double scale) {
    for (Eigen::Index i = 0; i < m.size(); ++i) {
      m.data()[i] = scale * normal(rng);
    }
  };
  fill(w.w1, std::sqrt(2.0 / kHapticInputs));
  fill(w.b1, 0.1);
  fill(w.w2, std::sqrt(2.0 / kHapticHidden));
  fill(w.b2, 0.1);
  fill(w.w3, std::sqrt(2.0 / kHapticHidden));
  fill(w.b3, 0.1);
  RoundToFloat(w);
  return w;
}

// RandomWeights behind a seeded convolutional front end of `channels`.
HapticNetWeights RandomConvWeights(uint64_t seed,
                                   const std::vector<int>& channels) {
  HapticNetWeights w = RandomWeights(seed);
  absl::StatusOr<HapticNetWeights> shaped = WeightsWithFrontEnd(channels);
  EXPECT_TRUE(shaped.ok()) << shaped.status();
  w.conv = shaped->conv;
  std::mt19937_64 rng(seed + 1000);
  std::normal_distribution<double> normal(0.0, 1.0);
  for (ConvLayer& layer : w.conv) {
    const double scale = std::sqrt(2.0 / (layer.in_channels * kConvKernel));
    for (double& v : layer.weight) v = scale * normal(rng);
    for (double& v : layer.bias) v = 0.1 * normal(rng);
  }
  w.w1 = RowMatrix(FrontEndOutputs(w.conv), kHapticHidden);
  for (Eigen::Index i = 0; i < w.w1.size(); ++i) {
    w.w1.data()[i] = std::sqrt(2.0 / w.w1.rows()) * normal(rng);
  }
  RoundToFloat(w);
  return w;
}

std::array<float, kHapticInputs> RandomInput(std::mt19937_64& rng) {
  std::normal_distribution<double> normal(0.0, 3.0);
  std::array<float, kHapticInputs> x;
  for (float& v : x) v = static_cast<float>(normal(rng));
  return x;
}

void ExpectSameOutputs(
    const HapticNetWeights& weights, const HapticNet& net,
    const std::vector<std::array<float, kHapticInputs>>& inputs) {
  for (const auto& x : inputs) {
    absl::StatusOr<HapticNetOutput> out = net.Run(x);
    ASSERT_TRUE(out.ok()) << out.status();
    const auto probabilities = ReferenceProbabilities(weights, x);
    const auto logits = ReferenceLogits(weights, x);
    double log_normaliser = 0.0;
    for (double v : logits) log_normaliser += std::exp(v);
    log_normaliser = std::log(log_normaliser);
    for (int k = 0; k < kHapticClasses; ++k) {
      EXPECT_NEAR(out->probabilities[k], probabilities[k], 1e-5);
      EXPECT_NEAR(out->log_probabilities[k], logits[k] - log_normaliser,
                  1e-5 * std::max(1.0, std::abs(logits[k])));
    }
  }
}

TEST(HapticNetTest, OnnxRoundTripOfSeededWeights) {
  const HapticNetWeights weights = RandomWeights(11);
  absl::StatusOr<std::unique_ptr<HapticNet>> net =
      HapticNet::FromOnnxBytes(HapticNetToOnnx(weights, {}), "test");
  ASSERT_TRUE(net.ok()) << net.status();
  std::mt19937_64 rng(12);
  std::vector<std::array<float, kHapticInputs>> inputs;
  for (int i = 0; i < 50; ++i) inputs.push_back(RandomInput(rng));
  ExpectSameOutputs(weights, **net, inputs);
}

TEST(HapticNetTest, OnnxRoundTripOfTrainedWeightsOnRealWindows) {
  const HapticPipelineOptions pipeline;
  const LabelledWindows train = WindowsFromTraces(
      SimulateLabelledTraces(40, TrainingConditions(), 3), pipeline, nullptr);
  const LabelledWindows validation = WindowsFromTraces(
      SimulateLabelledTraces(10, TrainingConditions(), 4), pipeline, nullptr);
  TrainerOptions options;
  options.max_epochs = 3;
  absl::StatusOr<TrainingResult> result =
      TrainHapticNet(train, validation, options);
  ASSERT_TRUE(result.ok()) << result.status();
  absl::StatusOr<std::unique_ptr<HapticNet>> net =
      HapticNet::FromOnnxBytes(HapticNetToOnnx(result->weights, {}), "test");
  ASSERT_TRUE(net.ok()) << net.status();
  ExpectSameOutputs(result->weights, **net, validation.inputs);
}

// The front end written out from its definition, one multiply at a time
// (zero padding, ReLU, the larger of each pair), independent of
// ConvForward's loop order.
std::array<double, kHapticClasses> DenseConvLogits(
    const HapticNetWeights& w, const std::array<float, kHapticInputs>& x) {
  std::vector<double> a(kHapticInputs);
  for (int i = 0; i < kHapticInputs; ++i) {
    a[i] = (x[i] - w.input_mean[i]) / w.input_stddev[i];
  }
  int length = kWindowPoints;
  for (const ConvLayer& layer : w.conv) {
    std::vector<double> pooled(layer.out_channels * (length / 2));
    for (int co = 0; co < layer.out_channels; ++co) {
      auto at = [&](int l) {
        double z = layer.bias[co];
        for (int ci = 0; ci < layer.in_channels; ++ci) {
          for (int t = 0; t < kConvKernel; ++t) {
            const int m = l + t - kConvKernel / 2;
            if (m < 0 || m >= length) continue;
            z +=
                layer.weight[(ci * kConvKernel + t) * layer.out_channels + co] *
                a[ci * length + m];
          }
        }
        return std::max(z, 0.0);
      };
      for (int j = 0; j < length / 2; ++j) {
        pooled[co * (length / 2) + j] = std::max(at(2 * j), at(2 * j + 1));
      }
    }
    a = pooled;
    length /= 2;
  }
  auto dense = [](const std::vector<double>& in, const RowMatrix& m,
                  const Eigen::RowVectorXd& b, bool relu) {
    std::vector<double> out(m.cols());
    for (Eigen::Index o = 0; o < m.cols(); ++o) {
      double z = b[o];
      for (Eigen::Index i = 0; i < m.rows(); ++i) z += in[i] * m(i, o);
      out[o] = relu ? std::max(z, 0.0) : z;
    }
    return out;
  };
  const std::vector<double> logits = dense(
      dense(dense(a, w.w1, w.b1, true), w.w2, w.b2, true), w.w3, w.b3, false);
  return {logits[0], logits[1], logits[2], logits[3]};
}

TEST(HapticNetTest, ConvolutionalFrontEndMatchesItsDefinitionAndOpenCv) {
  for (const std::vector<int>& channels :
       std::vector<std::vector<int>>{{16, 32}, {8}, {4, 6, 5}}) {
    const HapticNetWeights weights = RandomConvWeights(41, channels);
    ASSERT_EQ(weights.w1.rows(), FrontEndOutputs(weights.conv));
    absl::StatusOr<std::unique_ptr<HapticNet>> net =
        HapticNet::FromOnnxBytes(HapticNetToOnnx(weights, {}), "conv.onnx");
    ASSERT_TRUE(net.ok()) << net.status();
    std::mt19937_64 rng(42);
    std::vector<std::array<float, kHapticInputs>> inputs;
    for (int i = 0; i < 30; ++i) inputs.push_back(RandomInput(rng));
    for (const auto& x : inputs) {
      const auto reference = ReferenceLogits(weights, x);
      const auto dense = DenseConvLogits(weights, x);
      for (int k = 0; k < kHapticClasses; ++k) {
        EXPECT_NEAR(reference[k], dense[k], 1e-10 * (1.0 + std::abs(dense[k])))
            << channels.size() << " layers";
      }
    }
    ExpectSameOutputs(weights, **net, inputs);
  }
}

TEST(HapticNetTest, ConvolutionalWeightsReadBackFromTheFileExactly) {
  const HapticNetWeights weights = RandomConvWeights(51, {16, 32});
  absl::StatusOr<HapticNetWeights> read =
      HapticNetWeightsFromOnnx(HapticNetToOnnx(weights, {}), "conv.onnx");
  ASSERT_TRUE(read.ok()) << read.status();
  ASSERT_EQ(read->conv.size(), 2u);
  for (size_t i = 0; i < 2; ++i) {
    EXPECT_EQ(read->conv[i].in_channels, weights.conv[i].in_channels);
    EXPECT_EQ(read->conv[i].out_channels, weights.conv[i].out_channels);
    EXPECT_EQ(read->conv[i].weight, weights.conv[i].weight);
    EXPECT_EQ(read->conv[i].bias, weights.conv[i].bias);
  }
  EXPECT_EQ(read->w1, weights.w1);
  EXPECT_EQ(read->w3, weights.w3);
  // An ensemble of such members keeps the contract.
  const std::vector<HapticNetWeights> members = {
      weights, RandomConvWeights(52, {16, 32}), RandomWeights(53)};
  absl::StatusOr<std::unique_ptr<HapticNet>> net = HapticNet::FromOnnxBytes(
      HapticEnsembleToOnnx(members, {}), "conv-ensemble.onnx");
  ASSERT_TRUE(net.ok()) << net.status();
  std::mt19937_64 rng(54);
  const auto x = RandomInput(rng);
  absl::StatusOr<HapticNetOutput> out = (*net)->Run(x);
  ASSERT_TRUE(out.ok()) << out.status();
  const auto mean = ReferenceEnsembleProbabilities(members, x);
  for (int k = 0; k < kHapticClasses; ++k) {
    EXPECT_NEAR(out->probabilities[k], mean[k], 1e-5);
  }
}

TEST(HapticNetTest, RejectsAFrontEndItCannotBuild) {
  EXPECT_EQ(WeightsWithFrontEnd({16, 0}).status().code(),
            absl::StatusCode::kInvalidArgument);
  const absl::Status too_deep =
      WeightsWithFrontEnd({2, 2, 2, 2, 2, 2, 2}).status();
  EXPECT_EQ(too_deep.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(too_deep.message(), HasSubstr("at most 6"));
}

TEST(HapticNetTest, WeightsReadBackFromTheFileExactly) {
  const HapticNetWeights weights = RandomWeights(21);
  absl::StatusOr<HapticNetWeights> read =
      HapticNetWeightsFromOnnx(HapticNetToOnnx(weights, {}), "test");
  ASSERT_TRUE(read.ok()) << read.status();
  EXPECT_EQ(read->input_mean, weights.input_mean);
  EXPECT_EQ(read->input_stddev, weights.input_stddev);
  EXPECT_EQ(read->w1, weights.w1);
  EXPECT_EQ(read->b1, weights.b1);
  EXPECT_EQ(read->w2, weights.w2);
  EXPECT_EQ(read->b2, weights.b2);
  EXPECT_EQ(read->w3, weights.w3);
  EXPECT_EQ(read->b3, weights.b3);
}

TEST(HapticNetTest, AnEnsembleFileIsTheMeanOfItsMembersUnderTheSameContract) {
  const std::vector<HapticNetWeights> members = {
      RandomWeights(31), RandomWeights(32), RandomWeights(33)};
  const std::string bytes = HapticEnsembleToOnnx(members, {});
  absl::StatusOr<std::unique_ptr<HapticNet>> net =
      HapticNet::FromOnnxBytes(bytes, "ensemble");
  ASSERT_TRUE(net.ok()) << net.status();
  std::mt19937_64 rng(34);
  for (int i = 0; i < 50; ++i) {
    const auto x = RandomInput(rng);
    absl::StatusOr<HapticNetOutput> out = (*net)->Run(x);
    ASSERT_TRUE(out.ok()) << out.status();
    // The reference: a dense double mean of the members' softmax.
    std::array<double, kHapticClasses> mean{};
    for (const HapticNetWeights& m : members) {
      const auto p = ReferenceProbabilities(m, x);
      for (int k = 0; k < kHapticClasses; ++k) mean[k] += p[k] / 3.0;
    }
    const auto reference = ReferenceEnsembleProbabilities(members, x);
    for (int k = 0; k < kHapticClasses; ++k) {
      EXPECT_NEAR(reference[k], mean[k], 1e-15);
      EXPECT_NEAR(out->probabilities[k], mean[k], 1e-5);
      EXPECT_NEAR(out->log_probabilities[k], std::log(mean[k]),
                  1e-5 * std::max(1.0, std::abs(std::log(mean[k]))));
    }
  }
  // An ensemble file is not one member: reading weights from it says so.
  const absl::Status not_one =
      HapticNetWeightsFromOnnx(bytes, "ensemble.onnx").status();
  EXPECT_EQ(not_one.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(not_one.message(),
              HasSubstr("ensemble.onnx has no initializer \"input_mean\""));
  // One member gives exactly the single model's bytes.
  EXPECT_EQ(HapticEnsembleToOnnx({members[0]}, {}),
            HapticNetToOnnx(members[0], {}));
}

TEST(HapticNetTest, RejectsBytesThatAreNotOnnx) {
  absl::StatusOr<std::unique_ptr<HapticNet>> net =
      HapticNet::FromOnnxBytes("this is not a model", "garbage.onnx");
  ASSERT_EQ(net.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(net.status().message(), HasSubstr("garbage.onnx"));
  EXPECT_EQ(HapticNet::FromOnnxBytes("", "empty.onnx").status().code(),
            absl::StatusCode::kInvalidArgument);
}

TEST(HapticNetTest, RejectsAModelThatBreaksTheGraphContract) {
  onnx::ModelProto model;
  ASSERT_TRUE(model.ParseFromString(HapticNetToOnnx(RandomWeights(5), {})));
  // Rename the probabilities output: a valid ONNX graph, not HapticNet's.
  onnx::GraphProto* graph = model.mutable_graph();
  for (auto& node : *graph->mutable_node()) {
    if (node.output(0) == kHapticNetProbabilitiesName) {
      node.set_output(0, "scores");
    }
  }
  graph->mutable_output(1)->set_name("scores");
  absl::StatusOr<std::unique_ptr<HapticNet>> net =
      HapticNet::FromOnnxBytes(model.SerializeAsString(), "renamed.onnx");
  ASSERT_EQ(net.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(net.status().message(), HasSubstr("graph contract"));
}

// An export in the style of the original research code, normalising
// outside the graph, runs (OpenCV takes it) but would answer nonsense on
// raw windows: refused at load, naming the contract. Without the Sub and
// Div, fc1 reads the input directly; and with a Sub by another tensor.
TEST(HapticNetTest, RejectsAModelThatDoesNotNormaliseItsInput) {
  onnx::ModelProto model;
  ASSERT_TRUE(model.ParseFromString(HapticNetToOnnx(RandomWeights(5), {})));
  onnx::ModelProto bare = model;
  onnx::GraphProto* graph = bare.mutable_graph();
  std::string normalised;
  for (int i = graph->node_size() - 1; i >= 0; --i) {
    const std::string op = graph->node(i).op_type();
    if (op == "Div") normalised = graph->node(i).output(0);
    if (op == "Sub" || op == "Div") graph->mutable_node()->DeleteSubrange(i, 1);
  }
  ASSERT_FALSE(normalised.empty());
  for (auto& node : *graph->mutable_node()) {
    for (auto& input : *node.mutable_input()) {
      if (input == normalised) input = kHapticNetInputName;
    }
  }
  absl::StatusOr<std::unique_ptr<HapticNet>> net =
      HapticNet::FromOnnxBytes(bare.SerializeAsString(), "bare.onnx");
  ASSERT_EQ(net.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(net.status().message(),
              HasSubstr("bare.onnx does not normalise its input in the graph"));
  EXPECT_THAT(net.status().message(), HasSubstr("Gemm"));

  onnx::ModelProto other = model;
  for (auto& node : *other.mutable_graph()->mutable_node()) {
    if (node.op_type() == "Sub") {
      // Subtract the stddev instead: the wrong statistic.
      for (const auto& t : other.graph().initializer()) {
        if (absl::EndsWith(t.name(), "input_stddev")) {
          node.set_input(1, t.name());
        }
      }
    }
  }
  net = HapticNet::FromOnnxBytes(other.SerializeAsString(), "other.onnx");
  ASSERT_EQ(net.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(net.status().message(), HasSubstr("goes into a Sub node"));
  // The model as written loads.
  EXPECT_TRUE(
      HapticNet::FromOnnxBytes(model.SerializeAsString(), "ok.onnx").ok());
}

// The shipped model's bytes with its "bitewise.window_s" entry set to
// `value`, or removed when `value` is empty.
std::string ShippedModelWithWindow(const std::string& value) {
  onnx::ModelProto model;
  EXPECT_TRUE(model.ParseFromString(std::string(DefaultHapticNetOnnx())));
  auto* props = model.mutable_metadata_props();
  for (int i = props->size() - 1; i >= 0; --i) {
    if (props->Get(i).key() == kHapticNetWindowKey) props->DeleteSubrange(i, 1);
  }
  if (!value.empty()) {
    onnx::StringStringEntryProto* entry = model.add_metadata_props();
    entry->set_key(kHapticNetWindowKey);
    entry->set_value(value);
  }
  return model.SerializeAsString();
}

TEST(HapticNetTest, ReadsTheWindowTheModelWasTrainedOn) {
  absl::StatusOr<std::unique_ptr<HapticNet>> shipped =
      HapticNet::FromOnnxBytes(DefaultHapticNetOnnx(), kDefaultHapticNetSource);
  ASSERT_TRUE(shipped.ok()) << shipped.status();
  EXPECT_EQ((*shipped)->window_s(), std::optional<double>(0.05));

  absl::StatusOr<std::unique_ptr<HapticNet>> longer =
      HapticNet::FromOnnxBytes(ShippedModelWithWindow("0.1"), "w100.onnx");
  ASSERT_TRUE(longer.ok()) << longer.status();
  EXPECT_EQ((*longer)->window_s(), std::optional<double>(0.1));

  absl::StatusOr<std::unique_ptr<HapticNet>> none =
      HapticNet::FromOnnxBytes(ShippedModelWithWindow(""), "old.onnx");
  ASSERT_TRUE(none.ok()) << none.status();
  EXPECT_EQ((*none)->window_s(), std::nullopt);
}

TEST(HapticNetTest, RejectsAWindowThatIsNotSeconds) {
  for (const std::string value : {"fifty", "0", "-0.05", "nan", "2"}) {
    absl::StatusOr<std::unique_ptr<HapticNet>> net =
        HapticNet::FromOnnxBytes(ShippedModelWithWindow(value), "bad.onnx");
    ASSERT_EQ(net.status().code(), absl::StatusCode::kInvalidArgument) << value;
    EXPECT_THAT(net.status().message(), HasSubstr("bad.onnx")) << value;
    EXPECT_THAT(net.status().message(), HasSubstr("bitewise.window_s"))
        << value;
  }
}

// The service and the evaluator run a model on its own window; a flag may
// only repeat it, and a model that records none runs on the flag or 0.05 s.
TEST(HapticNetTest, ModelWindowIsTheModelsOwn) {
  auto longer =
      HapticNet::FromOnnxBytes(ShippedModelWithWindow("0.1"), "w100.onnx");
  auto none = HapticNet::FromOnnxBytes(ShippedModelWithWindow(""), "old.onnx");
  ASSERT_TRUE(longer.ok() && none.ok());
  EXPECT_EQ(ModelWindow(**longer, 0.0, "w100.onnx").value(), 0.1);
  EXPECT_EQ(ModelWindow(**longer, 0.1, "w100.onnx").value(), 0.1);
  EXPECT_EQ(ModelWindow(**none, 0.0, "old.onnx").value(), 0.05);
  EXPECT_EQ(ModelWindow(**none, 0.08, "old.onnx").value(), 0.08);

  absl::StatusOr<double> mismatch = ModelWindow(**longer, 0.05, "w100.onnx");
  ASSERT_EQ(mismatch.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(mismatch.status().message(), HasSubstr("w100.onnx"));
  EXPECT_THAT(mismatch.status().message(), HasSubstr("0.1 s window"));
  EXPECT_THAT(mismatch.status().message(), HasSubstr("--window_s=0.05"));
  EXPECT_EQ(ModelWindow(**none, -1.0, "old.onnx").status().code(),
            absl::StatusCode::kInvalidArgument);
}

TEST(HapticNetTest, MissingFileIsNotFound) {
  absl::StatusOr<std::unique_ptr<HapticNet>> net =
      HapticNet::FromOnnxFile(::testing::TempDir() + "/no_such_model.onnx");
  ASSERT_EQ(net.status().code(), absl::StatusCode::kNotFound);
  EXPECT_THAT(net.status().message(), HasSubstr("no_such_model.onnx"));
}

TEST(HapticNetTest, EmbeddedModelIsTheShippedFile) {
  std::ifstream in(BITEWISE_HAPTIC_MODEL_FILE, std::ios::binary);
  ASSERT_TRUE(in) << BITEWISE_HAPTIC_MODEL_FILE;
  std::ostringstream bytes;
  bytes << in.rdbuf();
  EXPECT_TRUE(bytes.str() == DefaultHapticNetOnnx());
  absl::StatusOr<std::unique_ptr<HapticNet>> from_file =
      HapticNet::FromOnnxFile(BITEWISE_HAPTIC_MODEL_FILE);
  absl::StatusOr<std::unique_ptr<HapticNet>> embedded =
      HapticNet::FromOnnxBytes(DefaultHapticNetOnnx(), kDefaultHapticNetSource);
  ASSERT_TRUE(from_file.ok()) << from_file.status();
  ASSERT_TRUE(embedded.ok()) << embedded.status();
  EXPECT_EQ((*from_file)->fingerprint(), (*embedded)->fingerprint());
}

}  // namespace
}  // namespace bitewise::haptic
