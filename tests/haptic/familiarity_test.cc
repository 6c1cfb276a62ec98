// The familiarity score (services/haptic/core/familiarity.h): fitted on one
// story's windows it calls fresh items of that story familiar and a trace
// unlike any food unfamiliar; the file round-trips and a malformed one is a
// clear error naming the file and line; the shipped file loads and the
// classifier reports the score only when it has a model.
#include "services/haptic/core/familiarity.h"

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "services/haptic/core/haptic_classifier.h"
#include "services/haptic/default_model.h"
#include "services/haptic/training/haptic_trainer.h"
#include "services/haptic/training/labelled_traces.h"

namespace bitewise::haptic {
namespace {

using ::testing::HasSubstr;

LabelledWindows Windows(TraceStory story, int per_class, uint64_t seed) {
  int skipped = 0;
  return WindowsFromTraces(StoryTraces(story, per_class, seed),
                           HapticPipelineOptions(), &skipped);
}

std::vector<FamiliarityVector> Features(const LabelledWindows& windows) {
  std::vector<FamiliarityVector> out;
  for (const auto& w : windows.inputs) out.push_back(FamiliarityFeatures(w));
  return out;
}

FamiliarityModel FitWorld() {
  const LabelledWindows train = Windows(TraceStory::kWorld, 100, 1);
  const LabelledWindows calibration = Windows(TraceStory::kWorld, 50, 2);
  absl::StatusOr<FamiliarityModel> model = FamiliarityModel::Fit(
      Features(train), train.labels, Features(calibration), 0.05, 0.1, "world");
  EXPECT_TRUE(model.ok()) << model.status();
  return *std::move(model);
}

// A window no food makes: 40 N of sideways force ringing at 200 Hz, with a
// large twist.
std::array<float, kHapticInputs> RingingSidewaysWindow() {
  std::array<float, kHapticInputs> window{};
  for (int k = 0; k < kWindowPoints; ++k) {
    const double t = 0.05 * k / (kWindowPoints - 1);
    window[0 * kWindowPoints + k] =
        static_cast<float>(40.0 * std::sin(2 * M_PI * 200.0 * t));
    window[2 * kWindowPoints + k] = 0.5f;
    window[5 * kWindowPoints + k] = 3.0f;
  }
  return window;
}

TEST(FamiliarityTest, FeaturesOfAHardItemPeakHighAndOfASoftItemLow) {
  const LabelledWindows windows = Windows(TraceStory::kWorld, 5, 3);
  for (size_t i = 0; i < windows.inputs.size(); ++i) {
    const FamiliarityVector f = FamiliarityFeatures(windows.inputs[i]);
    for (double v : f) EXPECT_TRUE(std::isfinite(v));
    EXPECT_GE(f[2], 0.0);  // the largest drop is a fraction
    EXPECT_LE(f[2], 1.0);
    if (windows.labels[i] == static_cast<int>(HapticClass::kHard)) {
      EXPECT_GT(std::exp(f[0]), 5.0);  // peak force, N
    }
    if (windows.labels[i] == static_cast<int>(HapticClass::kSoft)) {
      EXPECT_LT(std::exp(f[0]), 4.0);
    }
  }
}

TEST(FamiliarityTest, FreshItemsOfTheTrainingStoryAreFamiliar) {
  const FamiliarityModel model = FitWorld();
  const LabelledWindows fresh = Windows(TraceStory::kWorld, 50, 3);
  int flagged = 0;
  for (const auto& w : fresh.inputs) {
    const FamiliarityScore score = model.Score(FamiliarityFeatures(w));
    EXPECT_GE(score.familiarity, 0.0);
    EXPECT_LE(score.familiarity, 1.0);
    flagged += score.unfamiliar;
  }
  // 5% by construction on the calibration items; fresh ones may differ a
  // little.
  EXPECT_LT(flagged, 0.15 * fresh.inputs.size());
}

TEST(FamiliarityTest,
     EachClassDistanceIsToItsOwnClassAndTheNearestIsTheDistance) {
  const FamiliarityModel model = FitWorld();
  const LabelledWindows fresh = Windows(TraceStory::kWorld, 50, 3);
  int nearest_is_true = 0;
  for (size_t i = 0; i < fresh.inputs.size(); ++i) {
    const FamiliarityScore score =
        model.Score(FamiliarityFeatures(fresh.inputs[i]));
    const auto nearest = std::min_element(score.class_distances.begin(),
                                          score.class_distances.end());
    EXPECT_EQ(*nearest, score.distance);
    nearest_is_true +=
        (nearest - score.class_distances.begin()) == fresh.labels[i];
  }
  // The world story's classes are far apart in the summaries (peak force,
  // drop), so the nearest Gaussian is mostly the item's own class: the
  // distances are in class order.
  EXPECT_GT(nearest_is_true, 0.9 * fresh.inputs.size());
}

TEST(FamiliarityTest, ATraceUnlikeAnyFoodIsUnfamiliar) {
  const FamiliarityModel model = FitWorld();
  const FamiliarityScore score =
      model.Score(FamiliarityFeatures(RingingSidewaysWindow()));
  EXPECT_TRUE(score.unfamiliar);
  EXPECT_EQ(score.familiarity, 0.0);
  EXPECT_GT(score.distance, 100.0);
}

TEST(FamiliarityTest, TheFileRoundTrips) {
  const FamiliarityModel model = FitWorld();
  const std::string path =
      ::testing::TempDir() + "/round_trip.onnx.familiarity";
  {
    std::ofstream out(path);
    out << model.ToText();
  }
  absl::StatusOr<FamiliarityModel> read = FamiliarityModel::FromFile(path);
  ASSERT_TRUE(read.ok()) << read.status();
  EXPECT_EQ(read->ToText(), model.ToText());
  EXPECT_EQ(read->trained_on(), "world");
  EXPECT_EQ(read->threshold(), 0.05);
  const LabelledWindows fresh = Windows(TraceStory::kPiecewise, 5, 4);
  for (const auto& w : fresh.inputs) {
    const FamiliarityVector f = FamiliarityFeatures(w);
    EXPECT_DOUBLE_EQ(read->Distance(f), model.Distance(f));
    EXPECT_EQ(read->Score(f).familiarity, model.Score(f).familiarity);
  }
  std::remove(path.c_str());
}

TEST(FamiliarityTest, AMalformedFileIsAClearErrorNamingTheFileAndLine) {
  const std::string text = FitWorld().ToText();
  struct Case {
    std::string text;
    std::string message;
  };
  std::string bad_number = text;
  bad_number.replace(bad_number.find("mean 1 ") + 7, 1, "x");
  std::string bad_threshold = text;
  bad_threshold.replace(
      bad_threshold.find("threshold "),
      bad_threshold.find('\n', bad_threshold.find("threshold ")) -
          bad_threshold.find("threshold "),
      "threshold 7");
  const std::vector<Case> cases = {
      {"", "line 1: the file is empty"},
      {"hello\n", "line 1: expected \"bitewise-haptic-familiarity 1\""},
      {text.substr(0, text.size() / 2), "lines"},
      {bad_number, "line 7: not a finite number"},
      {bad_threshold, "line 3: threshold 7 is outside [0, 1]"},
  };
  for (const Case& c : cases) {
    absl::StatusOr<FamiliarityModel> read =
        FamiliarityModel::FromText(c.text, "some/model.onnx.familiarity");
    ASSERT_FALSE(read.ok());
    EXPECT_EQ(read.status().code(), absl::StatusCode::kInvalidArgument);
    EXPECT_THAT(read.status().message(),
                HasSubstr("familiarity file some/model.onnx.familiarity"));
    EXPECT_THAT(read.status().message(), HasSubstr(c.message));
  }
  absl::StatusOr<FamiliarityModel> missing =
      FamiliarityModel::FromFile("/nonexistent/x.onnx.familiarity");
  EXPECT_EQ(missing.status().code(), absl::StatusCode::kNotFound);
  EXPECT_THAT(missing.status().message(),
              HasSubstr("/nonexistent/x.onnx.familiarity"));
}

TEST(FamiliarityTest, FitRejectsBadInput) {
  const LabelledWindows train = Windows(TraceStory::kWorld, 100, 1);
  const std::vector<FamiliarityVector> f = Features(train);
  EXPECT_FALSE(FamiliarityModel::Fit(f, train.labels, {}, 0.05, 0.1, "w").ok());
  EXPECT_FALSE(FamiliarityModel::Fit(f, train.labels, f, 1.5, 0.1, "w").ok());
  std::vector<int> labels = train.labels;
  labels[0] = 7;
  EXPECT_THAT(
      FamiliarityModel::Fit(f, labels, f, 0.05, 0.1, "w").status().message(),
      HasSubstr("label 7"));
}

TEST(FamiliarityTest, TheShippedFileLoadsAndTheClassifierReportsIt) {
  absl::StatusOr<FamiliarityModel> shipped = FamiliarityModel::FromText(
      DefaultHapticFamiliarity(), kDefaultHapticFamiliaritySource);
  ASSERT_TRUE(shipped.ok()) << shipped.status();
  EXPECT_EQ(shipped->trained_on(),
            "world,piecewise,mechanics,compliant,puncture,poroelastic");
  EXPECT_EQ(shipped->threshold(), 0.05);

  const LabelledTrace trace = StoryTraces(TraceStory::kWorld, 1, 5).front();
  for (bool with : {false, true}) {
    auto net = HapticNet::FromOnnxBytes(DefaultHapticNetOnnx(),
                                        kDefaultHapticNetSource);
    ASSERT_TRUE(net.ok()) << net.status();
    const HapticClassifier classifier(
        std::move(net).value(), HapticPipelineOptions(),
        with ? std::make_unique<FamiliarityModel>(*shipped) : nullptr);
    absl::StatusOr<HapticClassification> result =
        classifier.Classify(trace.samples);
    ASSERT_TRUE(result.ok()) << result.status();
    EXPECT_EQ(result->has_familiarity, with);
    if (with) {
      absl::StatusOr<HapticFeatures> features =
          ExtractHapticFeatures(trace.samples, HapticPipelineOptions());
      ASSERT_TRUE(features.ok());
      EXPECT_EQ(result->familiarity.familiarity,
                shipped->Score(FamiliarityFeatures(features->window.inputs))
                    .familiarity);
    }
  }
}

TEST(FamiliarityTest, AurocCountsPairsAndTies) {
  EXPECT_DOUBLE_EQ(Auroc({3.0, 4.0}, {1.0, 2.0}), 1.0);
  EXPECT_DOUBLE_EQ(Auroc({1.0, 2.0}, {3.0, 4.0}), 0.0);
  EXPECT_DOUBLE_EQ(Auroc({2.0}, {2.0}), 0.5);
  EXPECT_DOUBLE_EQ(Auroc({}, {1.0}), 0.5);
}

}  // namespace
}  // namespace bitewise::haptic
