// The familiarity score (services/haptic/core/familiarity.h): fitted on one
// story's windows it calls fresh items of that story familiar and a trace
// unlike any food unfamiliar; the file round-trips and a malformed one is a
// clear error naming the file and line; the shipped file loads and the
// classifier reports the score only when it has a model.
#include "services/haptic/core/familiarity.h"

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <limits>
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

void ExpectParseError(const std::string& text, const std::string& message) {
  absl::StatusOr<FamiliarityModel> read =
      FamiliarityModel::FromText(text, "some/model.onnx.familiarity");
  ASSERT_FALSE(read.ok()) << message;
  EXPECT_EQ(read.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(read.status().message(),
              HasSubstr("familiarity file some/model.onnx.familiarity"));
  EXPECT_THAT(read.status().message(), HasSubstr(message));
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
  // A precision matrix of zeros: every distance 0, every trace familiar.
  std::string zero_precision = text;
  {
    const size_t at = zero_precision.find("\nprecision 0 ") + 1;
    const size_t end = zero_precision.find('\n', at);
    std::string zeros = "precision 0";
    for (int i = 0; i < kFamiliarityFeatures * kFamiliarityFeatures; ++i) {
      zeros += " 0";
    }
    zero_precision.replace(at, end - at, zeros);
  }
  const std::vector<Case> cases = {
      {"", "line 1: the file is empty"},
      {zero_precision,
       "line 6: the precision matrix of class 0 is not symmetric positive "
       "definite"},
      {"hello\n",
       "line 1: expected \"bitewise-haptic-familiarity 1\" or "
       "\"bitewise-haptic-familiarity 2\""},
      {text.substr(0, text.size() / 2), "lines"},
      {bad_number, "line 7: not a finite number"},
      {bad_threshold, "line 3: threshold 7 is outside [0, 1]"},
  };
  for (const Case& c : cases) {
    ExpectParseError(c.text, c.message);
  }
  absl::StatusOr<FamiliarityModel> missing =
      FamiliarityModel::FromFile("/nonexistent/x.onnx.familiarity");
  EXPECT_EQ(missing.status().code(), absl::StatusCode::kNotFound);
  EXPECT_THAT(missing.status().message(),
              HasSubstr("/nonexistent/x.onnx.familiarity"));
}

// Windows of world and mechanics, each tagged with its story's name.
struct TwoStories {
  std::vector<FamiliarityVector> features;
  std::vector<int> labels;
  std::vector<std::string> sources;
};

TwoStories WorldAndMechanics(int per_class, uint64_t seed) {
  TwoStories out;
  for (TraceStory story : {TraceStory::kWorld, TraceStory::kMechanics}) {
    const LabelledWindows w = Windows(story, per_class, seed);
    for (size_t i = 0; i < w.inputs.size(); ++i) {
      out.features.push_back(FamiliarityFeatures(w.inputs[i]));
      out.labels.push_back(w.labels[i]);
      out.sources.push_back(TraceStoryName(story));
      // WindowsFromTraces carries each trace's story.
      EXPECT_EQ(w.sources[i], static_cast<int>(story));
    }
  }
  return out;
}

// The squared Mahalanobis distance, written out densely.
double Mahalanobis(const FamiliarityComponent& g, const FamiliarityVector& x) {
  double sum = 0.0;
  for (int i = 0; i < kFamiliarityFeatures; ++i) {
    for (int j = 0; j < kFamiliarityFeatures; ++j) {
      sum += (x[i] - g.mean[i]) * g.precision[i * kFamiliarityFeatures + j] *
             (x[j] - g.mean[j]);
    }
  }
  return sum;
}

TEST(FamiliarityTest, OneGaussianPerClassAndStoryScoresByTheNearest) {
  const TwoStories train = WorldAndMechanics(60, 1);
  const TwoStories calibration = WorldAndMechanics(30, 2);
  absl::StatusOr<FamiliarityModel> model = FamiliarityModel::FitPerSource(
      train.features, train.labels, train.sources, calibration.features, 0.05,
      0.1, "world,mechanics");
  ASSERT_TRUE(model.ok()) << model.status();
  ASSERT_EQ(model->components().size(), 8u);
  EXPECT_EQ(model->left_out(), 0);
  for (size_t k = 0; k < 8; ++k) {
    EXPECT_EQ(model->components()[k].label, static_cast<int>(k / 2));
    // Within a class, in source name order.
    EXPECT_EQ(model->components()[k].source, k % 2 ? "world" : "mechanics");
  }
  const std::string text = model->ToText();
  EXPECT_EQ(text.rfind("bitewise-haptic-familiarity 2\n", 0), 0u);
  absl::StatusOr<FamiliarityModel> read =
      FamiliarityModel::FromText(text, "per_story.familiarity");
  ASSERT_TRUE(read.ok()) << read.status();
  EXPECT_EQ(read->ToText(), text);

  const TwoStories fresh = WorldAndMechanics(10, 3);
  for (const FamiliarityVector& f : fresh.features) {
    std::array<double, kHapticClasses> want;
    want.fill(std::numeric_limits<double>::infinity());
    for (const FamiliarityComponent& g : model->components()) {
      want[g.label] = std::min(want[g.label], Mahalanobis(g, f));
    }
    const FamiliarityScore score = read->Score(f);
    for (int c = 0; c < kHapticClasses; ++c) {
      EXPECT_NEAR(score.class_distances[c], want[c], 1e-9 * (1 + want[c]));
    }
    EXPECT_EQ(score.distance, *std::min_element(score.class_distances.begin(),
                                                score.class_distances.end()));
    EXPECT_EQ(score.familiarity, model->Score(f).familiarity);
  }
}

// The reason for a Gaussian per story: one Gaussian over two stories' hard
// items also covers the space between them, where neither story's items
// lie.
TEST(FamiliarityTest, TheSpaceBetweenTwoStoriesIsFamiliarToOneGaussianOnly) {
  const TwoStories train = WorldAndMechanics(60, 1);
  const TwoStories calibration = WorldAndMechanics(30, 2);
  absl::StatusOr<FamiliarityModel> pooled = FamiliarityModel::Fit(
      train.features, train.labels, calibration.features, 0.05, 0.1, "w,m");
  absl::StatusOr<FamiliarityModel> per_story = FamiliarityModel::FitPerSource(
      train.features, train.labels, train.sources, calibration.features, 0.05,
      0.1, "w,m");
  ASSERT_TRUE(pooled.ok() && per_story.ok());
  const auto& g = per_story->components();
  // Hard items: components 0 (mechanics) and 1 (world).
  FamiliarityVector between;
  for (int i = 0; i < kFamiliarityFeatures; ++i) {
    between[i] = 0.5 * (g[0].mean[i] + g[1].mean[i]);
  }
  EXPECT_GT(per_story->Distance(between), 2.0 * pooled->Distance(between));
  EXPECT_LT(per_story->Score(between).familiarity,
            pooled->Score(between).familiarity);
}

TEST(FamiliarityTest, ASourceWithFewWindowsIsPooledOrLeftOut) {
  TwoStories train = WorldAndMechanics(60, 1);
  const TwoStories calibration = WorldAndMechanics(30, 2);
  // 12 windows of each class from each of two small recordings: under 20
  // each, 24 pooled per class.
  const LabelledWindows small = Windows(TraceStory::kPiecewise, 24, 5);
  for (size_t i = 0; i < small.inputs.size(); ++i) {
    train.features.push_back(FamiliarityFeatures(small.inputs[i]));
    train.labels.push_back(small.labels[i]);
    train.sources.push_back(i < small.inputs.size() / 2 ? "recordings"
                                                        : "lab-b");
  }
  auto fit = [&] {
    return FamiliarityModel::FitPerSource(train.features, train.labels,
                                          train.sources, calibration.features,
                                          0.05, 0.1, "w,m,rec");
  };
  absl::StatusOr<FamiliarityModel> model = fit();
  ASSERT_TRUE(model.ok()) << model.status();
  ASSERT_EQ(model->components().size(), 12u);
  EXPECT_EQ(model->components()[2].source, "pooled");
  EXPECT_EQ(model->left_out(), 0);
  // One recording alone: 12 a class, too few even pooled.
  train.features.resize(train.features.size() - small.inputs.size() / 2);
  train.labels.resize(train.features.size());
  train.sources.resize(train.features.size());
  model = fit();
  ASSERT_TRUE(model.ok()) << model.status();
  EXPECT_EQ(model->components().size(), 8u);
  EXPECT_EQ(model->left_out(), 48);
  // Repeated ten times (the trainer's --traces_repeat), they are still 12
  // distinct windows a class: weight, not information.
  const size_t once = train.features.size();
  for (int r = 1; r < 10; ++r) {
    for (size_t i = once - small.inputs.size() / 2; i < once; ++i) {
      train.features.push_back(train.features[i]);
      train.labels.push_back(train.labels[i]);
      train.sources.push_back(train.sources[i]);
    }
  }
  model = fit();
  ASSERT_TRUE(model.ok()) << model.status();
  EXPECT_EQ(model->components().size(), 8u);
  EXPECT_EQ(model->left_out(), 480);
}

TEST(FamiliarityTest, AMalformedPerStoryFileIsAClearErrorNamingTheLine) {
  const TwoStories train = WorldAndMechanics(60, 1);
  absl::StatusOr<FamiliarityModel> model = FamiliarityModel::FitPerSource(
      train.features, train.labels, train.sources, train.features, 0.05, 0.1,
      "world,mechanics");
  ASSERT_TRUE(model.ok()) << model.status();
  const std::string text = model->ToText();
  auto replaced = [&](const std::string& from, const std::string& to) {
    std::string out = text;
    out.replace(out.find(from), from.size(), to);
    return out;
  };
  ExpectParseError(replaced("components 8", "components 9"), "lines");
  ExpectParseError(replaced("components 8", "components 2"),
                   "line 5: expected \"components N\" with N from 4");
  ExpectParseError(replaced("components 8", "components 99999999"),
                   "line 5: expected \"components N\"");
  ExpectParseError(replaced("precision 0 world", "precision 0 mechanics"),
                   "line 9: expected \"precision 0 world ...\"");
  ExpectParseError(replaced("mean 3 world", "mean 5 world"),
                   "line 20: expected \"mean CLASS SOURCE ...\" with a class");
  // A calibration count far beyond its numbers is refused before anything
  // is allocated for it.
  const size_t at = text.find("calibration ") + 12;
  std::string huge = text;
  huge.replace(at, huge.find(' ', at) - at, "2000000000");
  ExpectParseError(huge, "expected 2000000000 numbers");
  // Every Gaussian of hard-skin relabelled: no class 3 left.
  std::string no_hard_skin = text;
  for (const std::string from : {"mean 3 ", "precision 3 "}) {
    for (size_t at; (at = no_hard_skin.find(from)) != std::string::npos;) {
      no_hard_skin[at + from.size() - 2] = '2';
    }
  }
  ExpectParseError(no_hard_skin, "no Gaussian of class 3");
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
  std::vector<std::string> sources(f.size(), "world");
  EXPECT_TRUE(FamiliarityModel::FitPerSource(f, train.labels, sources, f, 0.05,
                                             0.1, "w")
                  .ok());
  EXPECT_THAT(
      FamiliarityModel::FitPerSource(f, labels, sources, f, 0.05, 0.1, "w")
          .status()
          .message(),
      HasSubstr("label 7"));
  sources.pop_back();
  EXPECT_THAT(FamiliarityModel::FitPerSource(f, train.labels, sources, f, 0.05,
                                             0.1, "w")
                  .status()
                  .message(),
              HasSubstr("sources"));
  for (const std::string bad : {"two words", "tab\there", "", "pooled"}) {
    sources.push_back(bad);
    EXPECT_THAT(FamiliarityModel::FitPerSource(f, train.labels, sources, f,
                                               0.05, 0.1, "w")
                    .status()
                    .message(),
                HasSubstr("\"" + bad + "\" of window"));
    sources.pop_back();
  }
  // One Gaussian per class is the version 1 file.
  absl::StatusOr<FamiliarityModel> one =
      FamiliarityModel::Fit(f, train.labels, f, 0.05, 0.1, "w");
  ASSERT_TRUE(one.ok());
  EXPECT_EQ(one->ToText().rfind("bitewise-haptic-familiarity 1\n", 0), 0u);
  // A class with no Gaussian: hard items only from a source too small.
  std::vector<std::string> one_small(f.size(), "world");
  std::vector<FamiliarityVector> few;
  std::vector<int> few_labels;
  std::vector<std::string> few_sources;
  int hard = 0;
  for (size_t i = 0; i < f.size(); ++i) {
    if (train.labels[i] == 0 && ++hard > 5) continue;
    few.push_back(f[i]);
    few_labels.push_back(train.labels[i]);
    few_sources.push_back("world");
  }
  EXPECT_THAT(FamiliarityModel::FitPerSource(few, few_labels, few_sources, f,
                                             0.05, 0.1, "w")
                  .status()
                  .message(),
              HasSubstr("class 0 has 5 windows, 5 of them distinct, need at "
                        "least 20 distinct"));
}

TEST(FamiliarityTest, TheShippedFileLoadsAndTheClassifierReportsIt) {
  absl::StatusOr<FamiliarityModel> shipped = FamiliarityModel::FromText(
      DefaultHapticFamiliarity(), kDefaultHapticFamiliaritySource);
  ASSERT_TRUE(shipped.ok()) << shipped.status();
  EXPECT_EQ(shipped->trained_on(),
            "world,piecewise,mechanics,compliant,puncture,poroelastic");
  EXPECT_EQ(shipped->threshold(), 0.05);
  // One Gaussian per class and story (docs/haptic.md, "One Gaussian per
  // class and story").
  ASSERT_EQ(shipped->components().size(), 24u);
  EXPECT_EQ(shipped->components()[0].source, "compliant");
  EXPECT_EQ(shipped->components()[5].source, "world");
  EXPECT_EQ(shipped->components()[23].label, 3);

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
