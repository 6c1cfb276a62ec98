// The featurizers: SPANet's preprocessing geometry, SPANet through OpenCV
// DNN on the generated ONNX model (shape, determinism, sensitivity to the
// crop and the location, model checks at load), and the default
// featurizer's dimension, determinism and discrimination.
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "onnx/onnx_pb.h"
#include "services/perception/context_scale.h"
#include "services/perception/default_featurizer.h"
#include "services/perception/lanczos_resize.h"
#include "services/perception/spanet_featurizer.h"
#include "services/perception/spanet_onnx.h"
#include "tests/perception/test_frames.h"

namespace bitewise::perception {
namespace {

using ::testing::HasSubstr;

TEST(SpanetCanvasTest, WideCropBecomes144x72Centred) {
  const SpanetPlacement p = SpanetPlacementFor(200, 100);
  EXPECT_EQ(p.width, 144);
  EXPECT_EQ(p.height, 72);
  EXPECT_EQ(p.offset_x, 0);
  EXPECT_EQ(p.offset_y, 36);

  cv::Mat crop(100, 200, CV_8UC3, cv::Scalar(255, 128, 0));
  const cv::Mat canvas = SpanetCanvas(crop);
  ASSERT_EQ(canvas.rows, 144);
  ASSERT_EQ(canvas.cols, 144);
  ASSERT_EQ(canvas.type(), CV_32FC3);
  for (int v = 0; v < 144; ++v) {
    for (int u = 0; u < 144; ++u) {
      const cv::Vec3f px = canvas.at<cv::Vec3f>(v, u);
      if (v >= 36 && v < 108) {
        // RGB order and [0, 1] scale, no mean or std.
        EXPECT_FLOAT_EQ(px[0], 1.0f);
        EXPECT_FLOAT_EQ(px[1], 128.0f / 255.0f);
        EXPECT_FLOAT_EQ(px[2], 0.0f);
      } else {
        EXPECT_EQ(px, cv::Vec3f(0, 0, 0)) << "row " << v;
      }
    }
  }
}

TEST(SpanetCanvasTest, TallAndSmallCropsKeepTheirAspect) {
  SpanetPlacement p = SpanetPlacementFor(30, 90);
  EXPECT_EQ(p.width, 48);
  EXPECT_EQ(p.height, 144);
  EXPECT_EQ(p.offset_x, 48);
  EXPECT_EQ(p.offset_y, 0);
  p = SpanetPlacementFor(7, 3);  // enlarged: 144 x floor(3 * 144 / 7) = 61
  EXPECT_EQ(p.width, 144);
  EXPECT_EQ(p.height, 61);
  EXPECT_EQ(p.offset_y, 41);
  p = SpanetPlacementFor(1000, 1);
  EXPECT_EQ(p.height, 1);
}

class SpanetTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    auto loaded = SpanetFeaturizer::Load(BITEWISE_SPANET_MODEL);
    ASSERT_TRUE(loaded.ok()) << loaded.status();
    spanet_ = loaded->release();
    scene_ = new testing::TestScene(testing::RenderTestScene(11, 8, true));
  }
  static void TearDownTestSuite() {
    delete spanet_;
    delete scene_;
  }
  PixelBox Box(int i) const {
    const sim::ItemTruth& t = scene_->rendered.truth[i];
    return {t.x, t.y, t.width, t.height};
  }
  static SpanetFeaturizer* spanet_;
  static testing::TestScene* scene_;
};
SpanetFeaturizer* SpanetTest::spanet_ = nullptr;
testing::TestScene* SpanetTest::scene_ = nullptr;

TEST_F(SpanetTest, OutputsHaveSpanetsShape) {
  const DecodedFrame frame = testing::ToDecoded(scene_->rendered);
  absl::StatusOr<Features> f =
      spanet_->Featurize(frame, Box(0), FoodLocation::kIsolated);
  ASSERT_TRUE(f.ok()) << f.status();
  EXPECT_EQ(spanet_->dimension(), 2048);
  ASSERT_EQ(f->context.size(), 2048u);
  ASSERT_EQ(f->skewer_points.size(), 2u);
  ASSERT_EQ(f->action_scores.size(), 6u);
  int positive = 0;
  for (double c : f->context) {
    ASSERT_TRUE(std::isfinite(c));
    EXPECT_GE(c, 0.0);  // after ReLU
    positive += c > 0;
  }
  // A live network, not a dead one: a good share of units fire.
  EXPECT_GT(positive, 200);
  for (double s : f->action_scores) {
    EXPECT_GT(s, 0.0);
    EXPECT_LT(s, 1.0);
  }
}

TEST_F(SpanetTest, IsDeterministicAndSeesTheCropAndLocation) {
  const DecodedFrame frame = testing::ToDecoded(scene_->rendered);
  auto a = spanet_->Featurize(frame, Box(0), FoodLocation::kIsolated);
  auto b = spanet_->Featurize(frame, Box(0), FoodLocation::kIsolated);
  auto other = spanet_->Featurize(frame, Box(1), FoodLocation::kIsolated);
  auto wall = spanet_->Featurize(frame, Box(0), FoodLocation::kWall);
  ASSERT_TRUE(a.ok() && b.ok() && other.ok() && wall.ok());
  EXPECT_EQ(a->context, b->context);
  EXPECT_EQ(a->action_scores, b->action_scores);
  double diff_item = 0, diff_wall = 0;
  for (int i = 0; i < 2048; ++i) {
    diff_item += std::abs(a->context[i] - other->context[i]);
    diff_wall += std::abs(a->context[i] - wall->context[i]);
  }
  EXPECT_GT(diff_item, 1e-3);
  EXPECT_GT(diff_wall, 1e-6);
}

TEST_F(SpanetTest, BadBoxesAreInvalidArgument) {
  const DecodedFrame frame = testing::ToDecoded(scene_->rendered);
  EXPECT_EQ(
      spanet_->Featurize(frame, {630, 10, 20, 20}, FoodLocation::kIsolated)
          .status()
          .code(),
      absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(spanet_->Featurize(frame, {10, 10, 0, 20}, FoodLocation::kIsolated)
                .status()
                .code(),
            absl::StatusCode::kInvalidArgument);
}

std::string TempPath(const std::string& name) {
  return ::testing::TempDir() + "/" + name;
}

TEST(SpanetLoadTest, MissingFileIsNotFound) {
  auto loaded = SpanetFeaturizer::Load(TempPath("no_such_model.onnx"));
  EXPECT_EQ(loaded.status().code(), absl::StatusCode::kNotFound);
  EXPECT_THAT(loaded.status().message(), HasSubstr("no_such_model.onnx"));
}

TEST_F(SpanetTest, ReportsTheContextScaleShippedBesideTheModel) {
  absl::StatusOr<double> shipped =
      ReadContextScaleFile(ContextScalePathFor(BITEWISE_SPANET_MODEL));
  ASSERT_TRUE(shipped.ok()) << shipped.status();
  EXPECT_GT(*shipped, 0.0);
  EXPECT_EQ(spanet_->context_mean_squared_norm(), *shipped);
}

TEST(SpanetLoadTest, MalformedContextScaleIsFailedPreconditionNamingIt) {
  const std::string path = TempPath("scaled.onnx");
  std::remove(path.c_str());
  ASSERT_EQ(symlink(BITEWISE_SPANET_MODEL, path.c_str()), 0);
  std::ofstream(ContextScalePathFor(path))
      << "version 1\nmean_squared_norm -3\n";
  auto loaded = SpanetFeaturizer::Load(path);
  EXPECT_EQ(loaded.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(loaded.status().message(), HasSubstr("scaled.onnx.stats"));
  EXPECT_THAT(loaded.status().message(), HasSubstr("line 2"));
  std::remove(ContextScalePathFor(path).c_str());
  auto unscaled = SpanetFeaturizer::Load(path);  // no .stats: unknown
  ASSERT_TRUE(unscaled.ok()) << unscaled.status();
  EXPECT_EQ((*unscaled)->context_mean_squared_norm(), 0.0);
  std::remove(path.c_str());
}

TEST(ContextScaleTest, ParsesAndRejectsNamingTheLine) {
  EXPECT_EQ(*ParseContextScale(FormatContextScale(123.5, "a\nb")), 123.5);
  const std::vector<std::pair<std::string, std::string>> bad = {
      {"version 1\n", "needs a version line and a mean_squared_norm"},
      {"mean_squared_norm 4\n", "needs a version line"},
      {"version 1\nmean_squared_norm nan\n", "line 2"},
      {"version 0\nmean_squared_norm 4\n", "line 1"},
      {"version 1\nmean_squared_norm 4\nextra 1\n", "line 3"},
  };
  for (const auto& [text, expected] : bad) {
    absl::StatusOr<double> parsed = ParseContextScale(text);
    EXPECT_EQ(parsed.status().code(), absl::StatusCode::kInvalidArgument);
    EXPECT_THAT(parsed.status().message(), HasSubstr(expected)) << text;
  }
  EXPECT_EQ(ReadContextScaleFile(TempPath("absent.stats")).status().code(),
            absl::StatusCode::kNotFound);
}

TEST(SpanetLoadTest, GarbageFileIsFailedPrecondition) {
  const std::string path = TempPath("garbage.onnx");
  std::ofstream(path) << "this is not a protobuf, let alone ONNX";
  auto loaded = SpanetFeaturizer::Load(path);
  EXPECT_EQ(loaded.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(loaded.status().message(), HasSubstr("garbage.onnx"));
}

TEST(SpanetLoadTest, AnEmptyFileOrADirectoryIsSaidToBeOne) {
  const std::string empty = TempPath("empty.onnx");
  std::ofstream(empty).close();
  auto loaded = SpanetFeaturizer::Load(empty);
  EXPECT_EQ(loaded.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(std::string(loaded.status().message()),
              HasSubstr("empty.onnx\" is empty (0 bytes)"));
  const std::string dir = TempPath("a_directory.onnx");
  std::filesystem::create_directories(dir);
  loaded = SpanetFeaturizer::Load(dir);
  EXPECT_EQ(loaded.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(std::string(loaded.status().message()),
              HasSubstr("a_directory.onnx\" is a directory"));
}

TEST(SpanetLoadTest, TruncatedModelIsFailedPrecondition) {
  std::ifstream in(BITEWISE_SPANET_MODEL, std::ios::binary);
  std::string head(1 << 20, '\0');
  in.read(head.data(), head.size());
  const std::string path = TempPath("truncated.onnx");
  std::ofstream(path, std::ios::binary) << head;
  auto loaded = SpanetFeaturizer::Load(path);
  EXPECT_EQ(loaded.status().code(), absl::StatusCode::kFailedPrecondition);
}

// Rewrites a small generated model through `edit` and loads it.
absl::Status LoadEdited(const std::string& name,
                        const std::function<void(onnx::ModelProto*)>& edit) {
  const std::string path = TempPath(name);
  SpanetOnnxOptions options;
  options.hidden_features = 8;
  if (absl::Status s = WriteSpanetOnnx(path, options); !s.ok()) return s;
  onnx::ModelProto model;
  {
    std::ifstream in(path, std::ios::binary);
    if (!model.ParseFromIstream(&in)) return absl::InternalError("reparse");
  }
  edit(&model);
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    model.SerializeToOstream(&out);
  }
  return SpanetFeaturizer::Load(path).status();
}

// A model whose weights are not numbers loads as ONNX and has SPANet's
// interface, but every context it gave would be NaN: the start stops. (The
// build's model with the first value of each weight set to NaN.)
TEST(SpanetLoadTest, NonFiniteWeightsAreRefusedAtLoad) {
  onnx::ModelProto model;
  {
    std::ifstream in(BITEWISE_SPANET_MODEL, std::ios::binary);
    ASSERT_TRUE(model.ParseFromIstream(&in));
  }
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (onnx::TensorProto& w : *model.mutable_graph()->mutable_initializer()) {
    if (w.data_type() != onnx::TensorProto::FLOAT) continue;
    if (w.raw_data().size() >= sizeof(float)) {
      std::memcpy(&(*w.mutable_raw_data())[0], &nan, sizeof(float));
    } else if (w.float_data_size() > 0) {
      w.set_float_data(0, nan);
    }
  }
  const std::string path = TempPath("nan.onnx");
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    ASSERT_TRUE(model.SerializeToOstream(&out));
  }
  model.Clear();
  auto loaded = SpanetFeaturizer::Load(path);
  std::remove(path.c_str());
  ASSERT_FALSE(loaded.ok());
  EXPECT_EQ(loaded.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(std::string(loaded.status().message()),
              HasSubstr("nan.onnx\" gives outputs that are not finite"));
}

// SPANet's head ends in a sigmoid: skewer points in the crop's unit square,
// action success rates. A model exported without it (raw logits) used to
// load and report points and rates well outside [0, 1].
TEST(SpanetLoadTest, ScoresOutsideZeroToOneAreRefusedAtLoad) {
  onnx::ModelProto model;
  {
    std::ifstream in(BITEWISE_SPANET_MODEL, std::ios::binary);
    ASSERT_TRUE(model.ParseFromIstream(&in));
  }
  int replaced = 0;
  for (onnx::NodeProto& node : *model.mutable_graph()->mutable_node()) {
    // exp(logit): finite, positive, and above 1 wherever the logit is.
    if (node.op_type() == "Sigmoid") {
      node.set_op_type("Exp");
      ++replaced;
    }
  }
  ASSERT_EQ(replaced, 1);
  const std::string path = TempPath("raw_scores.onnx");
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    ASSERT_TRUE(model.SerializeToOstream(&out));
  }
  const absl::Status raw = SpanetFeaturizer::Load(path).status();
  std::remove(path.c_str());
  EXPECT_EQ(raw.code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(std::string(raw.message()),
              HasSubstr("raw_scores.onnx\" gives \"scores\" outside [0, 1]"));
}

TEST(SpanetLoadTest, GraphExportedInTrainingModeIsRefusedNamingTheNode) {
  // A BatchNormalization that outputs its batch statistics (opset < 14).
  absl::Status five_outputs = LoadEdited("train5.onnx", [](auto* m) {
    onnx::NodeProto* bn = nullptr;
    for (auto& node : *m->mutable_graph()->mutable_node()) {
      if (node.op_type() == "BatchNormalization" && bn == nullptr) bn = &node;
    }
    for (const char* out : {"rm", "rv", "sm", "sv"}) bn->add_output(out);
  });
  EXPECT_EQ(five_outputs.code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(five_outputs.message(),
              HasSubstr("exported with BatchNorm in training mode"));
  EXPECT_THAT(five_outputs.message(), HasSubstr("BatchNormalization_"));
  // training_mode = 1 (opset 14 and later).
  absl::Status attribute = LoadEdited("train14.onnx", [](auto* m) {
    for (auto& node : *m->mutable_graph()->mutable_node()) {
      if (node.op_type() != "BatchNormalization") continue;
      onnx::AttributeProto* a = node.add_attribute();
      a->set_name("training_mode");
      a->set_type(onnx::AttributeProto::INT);
      a->set_i(1);
    }
  });
  EXPECT_THAT(attribute.message(),
              HasSubstr("exported with BatchNorm in training mode"));
}

TEST(SpanetLoadTest, SymbolicBatchOrMissingOutputIsRefusedNamingIt) {
  absl::Status symbolic = LoadEdited("dynamic.onnx", [](auto* m) {
    m->mutable_graph()
        ->mutable_input(0)
        ->mutable_type()
        ->mutable_tensor_type()
        ->mutable_shape()
        ->mutable_dim(0)
        ->set_dim_param("batch");
  });
  EXPECT_EQ(symbolic.code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(symbolic.message(),
              HasSubstr("input \"rgb\" has shape [-1,3,144,144]"));
  absl::Status no_scores = LoadEdited("noscores.onnx", [](auto* m) {
    m->mutable_graph()->mutable_output()->RemoveLast();
  });
  EXPECT_THAT(no_scores.message(), HasSubstr("has no output \"scores\""));
}

TEST(LanczosResizeTest, KeepsConstantsAndCopiesWhenTheSizeIsUnchanged) {
  const cv::Mat grey(37, 53, CV_8UC3, cv::Scalar(90, 17, 250));
  for (const cv::Size size : {cv::Size(144, 99), cv::Size(11, 8),
                              cv::Size(53, 144), cv::Size(144, 37)}) {
    const cv::Mat out = ResizeLanczosAsPil(grey, size);
    ASSERT_EQ(out.size(), size);
    cv::Mat expected(size, CV_8UC3, cv::Scalar(90, 17, 250));
    EXPECT_EQ(cv::norm(out, expected, cv::NORM_INF), 0.0) << size;
  }
  const cv::Mat same = ResizeLanczosAsPil(grey, grey.size());
  EXPECT_NE(same.data, grey.data);
  EXPECT_EQ(cv::norm(same, grey, cv::NORM_INF), 0.0);
}

TEST(LanczosResizeTest, ShrinkingAveragesAndEnlargingRingsLikeLanczos) {
  // A one-pixel-wide white line on black: shrunk 4x it spreads to about a
  // quarter of its value; enlarged 4x it keeps about its peak, and
  // Lanczos' negative lobe, clipped, leaves black one input pixel beside
  // it. (Byte-exactness against PIL itself is spanet_pytorch_test's.)
  cv::Mat line(1, 64, CV_8UC1, cv::Scalar(0));
  line.at<uint8_t>(0, 32) = 255;
  const cv::Mat small = ResizeLanczosAsPil(line, cv::Size(16, 1));
  double peak = 0.0;
  cv::minMaxLoc(small, nullptr, &peak);
  EXPECT_NEAR(peak, 255.0 / 4, 255.0 / 8);
  const cv::Mat big = ResizeLanczosAsPil(line, cv::Size(256, 1));
  cv::minMaxLoc(big, nullptr, &peak);
  EXPECT_GE(peak, 240.0);
  EXPECT_EQ(big.at<uint8_t>(0, 4 * 32 + 2 - 5), 0);
  EXPECT_EQ(big.at<uint8_t>(0, 4 * 32 + 2 + 5), 0);
}

TEST(SpanetLoadTest, ModelWithAnotherInterfaceIsFailedPrecondition) {
  const std::string path = TempPath("narrow.onnx");
  SpanetOnnxOptions options;
  options.hidden_features = 16;
  ASSERT_TRUE(WriteSpanetOnnx(path, options).ok());
  auto loaded = SpanetFeaturizer::Load(path);
  EXPECT_EQ(loaded.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(loaded.status().message(), HasSubstr("16 features"));
}

TEST(SpanetOnnxTest, SameSeedWritesTheSameFile) {
  SpanetOnnxOptions options;
  options.hidden_features = 8;
  options.seed = 5;
  ASSERT_TRUE(WriteSpanetOnnx(TempPath("a.onnx"), options).ok());
  ASSERT_TRUE(WriteSpanetOnnx(TempPath("b.onnx"), options).ok());
  options.seed = 6;
  ASSERT_TRUE(WriteSpanetOnnx(TempPath("c.onnx"), options).ok());
  auto read = [](const std::string& p) {
    std::ifstream in(p, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  EXPECT_EQ(read(TempPath("a.onnx")), read(TempPath("b.onnx")));
  EXPECT_NE(read(TempPath("a.onnx")), read(TempPath("c.onnx")));
  EXPECT_EQ(WriteSpanetOnnx("/nonexistent-dir/x.onnx", options).code(),
            absl::StatusCode::kFailedPrecondition);
}

TEST(DefaultFeaturizerTest, DimensionDeterminismAndDiscrimination) {
  testing::TestScene scene = testing::RenderTestScene(21, 8, false);
  const DecodedFrame frame = testing::ToDecoded(scene.rendered);
  DefaultFeaturizerOptions raw;
  raw.standardize = false;  // the layout of the raw features
  const DefaultFeaturizer featurizer(raw);
  EXPECT_EQ(featurizer.dimension(), kDefaultFeatureDim);
  std::vector<std::vector<double>> contexts;
  for (const sim::ItemTruth& t : scene.rendered.truth) {
    const PixelBox box{t.x, t.y, t.width, t.height};
    auto a = featurizer.Featurize(frame, box, FoodLocation::kLettuce);
    auto b = featurizer.Featurize(frame, box, FoodLocation::kLettuce);
    ASSERT_TRUE(a.ok() && b.ok());
    ASSERT_EQ(a->context.size(), 64u);
    EXPECT_EQ(a->context, b->context);
    EXPECT_TRUE(a->skewer_points.empty());
    EXPECT_TRUE(a->action_scores.empty());
    for (double c : a->context) EXPECT_TRUE(std::isfinite(c));
    EXPECT_EQ(a->context[62], 1.0);  // lettuce
    EXPECT_EQ(a->context[63], 1.0);  // intercept
    double hue_sum = 0;
    for (int i = 0; i < 16; ++i) hue_sum += a->context[i];
    EXPECT_NEAR(hue_sum, 1.0, 1e-9);
    contexts.push_back(a->context);
  }
  // Different foods get different descriptions.
  for (size_t i = 0; i < contexts.size(); ++i) {
    for (size_t j = i + 1; j < contexts.size(); ++j) {
      double d = 0;
      for (int k = 0; k < 64; ++k)
        d += std::abs(contexts[i][k] - contexts[j][k]);
      EXPECT_GT(d, 0.05) << i << " vs " << j;
    }
  }
}

TEST(DefaultFeaturizerTest, SizeAndHeightAreInMetres) {
  testing::TestScene scene = testing::RenderTestScene(5, 1, false);
  const DecodedFrame frame = testing::ToDecoded(scene.rendered);
  const sim::ItemTruth& t = scene.rendered.truth[0];
  const sim::SceneItem& item = scene.plate.items[0];
  DefaultFeaturizerOptions raw;
  raw.standardize = false;
  auto f = DefaultFeaturizer(raw).Featurize(
      frame, {t.x, t.y, t.width, t.height}, FoodLocation::kIsolated);
  ASSERT_TRUE(f.ok()) << f.status();
  EXPECT_NEAR(f->context[48] * 0.1, item.length_m, 0.25 * item.length_m);
  EXPECT_NEAR(f->context[49] * 0.1, item.width_m, 0.3 * item.width_m);
  EXPECT_NEAR(f->context[56] * 0.05, item.height_m, 0.3 * item.height_m);
}

TEST(DefaultFeaturizerTest, StandardisedIsTheRawThroughTheShippedStatistics) {
  testing::TestScene scene = testing::RenderTestScene(21, 8, false);
  const DecodedFrame frame = testing::ToDecoded(scene.rendered);
  DefaultFeaturizerOptions raw_options;
  raw_options.standardize = false;
  const DefaultFeaturizer raw(raw_options);
  const DefaultFeaturizer standardised;
  const DefaultFeaturizerStats& stats = ShippedDefaultFeaturizerStats();
  EXPECT_GE(stats.version, 1);
  EXPECT_EQ(standardised.context_mean_squared_norm(), stats.mean_squared_norm);
  EXPECT_EQ(raw.context_mean_squared_norm(), 0.0);  // unknown for raw
  for (const sim::ItemTruth& t : scene.rendered.truth) {
    const PixelBox box{t.x, t.y, t.width, t.height};
    auto r = raw.Featurize(frame, box, FoodLocation::kWall);
    auto z = standardised.Featurize(frame, box, FoodLocation::kWall);
    ASSERT_TRUE(r.ok() && z.ok());
    std::vector<double> expected = r->context;
    StandardizeDefaultFeatures(stats, &expected);
    EXPECT_EQ(z->context, expected);
    for (int k = 0; k < 60; ++k) {
      EXPECT_LE(std::abs(z->context[k]), kStandardClip);
    }
    EXPECT_EQ(z->context[61], 1.0);  // wall, unchanged
    EXPECT_EQ(z->context[63], 1.0);  // intercept, unchanged
  }
}

TEST(DefaultFeaturizerTest, MalformedStatisticsAreRejectedNamingTheLine) {
  std::string good = "version 1\nmean_squared_norm 40\n";
  for (int k = 0; k < kDefaultFeatureDim; ++k) {
    good += "feature " + std::to_string(k) + " 0.5 0.25\n";
  }
  ASSERT_TRUE(ParseDefaultFeaturizerStats(good).ok());
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"version 1\nmean_squared_norm 40\n", "feature 0 is missing"},
      {good + "feature 64 0 1\n", "line 67"},
      {good + "feature 3 nan 1\n", "feature <0-63>"},
      {good + "feature 3 0 -1\n", "sd >= 0"},
      {good + "bogus\n", "unknown entry"},
      {good.substr(10), "no version line"},
      {"version 1\n" + good.substr(good.find("feature")),
       "no mean_squared_norm"},
  };
  for (const auto& [text, expected] : cases) {
    absl::StatusOr<DefaultFeaturizerStats> parsed =
        ParseDefaultFeaturizerStats(text);
    EXPECT_EQ(parsed.status().code(), absl::StatusCode::kInvalidArgument)
        << expected;
    EXPECT_THAT(std::string(parsed.status().message()),
                ::testing::HasSubstr(expected));
  }
}

}  // namespace
}  // namespace bitewise::perception
