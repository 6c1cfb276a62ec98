// The whole pipeline with the shipped model: simulated traces of each
// category come out right with consistent probabilities, and bad traces get
// the documented statuses.
#include "services/haptic/core/haptic_classifier.h"

#include <array>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "services/haptic/default_model.h"
#include "services/haptic/training/haptic_trainer.h"
#include "tests/haptic/haptic_test_traces.h"

namespace bitewise::haptic {
namespace {

using ::testing::HasSubstr;

class HapticClassifierTest : public ::testing::Test {
 protected:
  void SetUp() override {
    auto net = HapticNet::FromOnnxBytes(DefaultHapticNetOnnx(),
                                        kDefaultHapticNetSource);
    ASSERT_TRUE(net.ok()) << net.status();
    classifier_ = std::make_unique<HapticClassifier>(std::move(net).value(),
                                                     HapticPipelineOptions());
  }
  std::unique_ptr<HapticClassifier> classifier_;
};

// The shipped model was trained on six stories (world, piecewise,
// mechanics, compliant, puncture, poroelastic; models/hapticnet metadata,
// docs/haptic.md), and holds lattice out, which no model meets the targets
// on. The targets, through the service's own path, on the report
// items docs/haptic.md shows (500 per class, seed 20261123): every category
// at least 90 % right and calibration error at most 0.05 on the three
// stories whose classes the window tells apart (on compliant, puncture and
// poroelastic medium items it does not: 60-71 %, docs/haptic.md).
TEST_F(HapticClassifierTest,
       MeetsTheTargetsOnTheStoriesWhoseClassesItTellsApart) {
  for (TraceStory story :
       {TraceStory::kWorld, TraceStory::kPiecewise, TraceStory::kMechanics}) {
    std::vector<std::array<double, kHapticClasses>> probabilities;
    std::vector<int> labels;
    int rejected = 0;
    for (const LabelledTrace& trace : StoryTraces(story, 500, 20261123)) {
      absl::StatusOr<HapticClassification> result =
          classifier_->Classify(trace.samples);
      if (!result.ok()) {
        ++rejected;
        continue;
      }
      probabilities.push_back(result->probabilities);
      labels.push_back(static_cast<int>(trace.label));
    }
    EXPECT_LE(rejected, 10);  // soft items too weak to register as contact
    const ProbabilisticScore score = ScorePredictions(probabilities, labels);
    for (int k = 0; k < kHapticClasses; ++k) {
      EXPECT_GE(score.confusion.Recall(k), 0.90)
          << TraceStoryName(story) << " "
          << HapticClassName(static_cast<HapticClass>(k)) << "\n"
          << score.confusion.ToString();
    }
    EXPECT_LE(score.expected_calibration_error, 0.05) << TraceStoryName(story);
  }
}

TEST_F(HapticClassifierTest, ClassifiesSimulatedItemsOfEveryCategory) {
  std::mt19937_64 rng(99);
  int correct = 0, total = 0;
  for (double rate_hz : {100.0, 1000.0}) {
    for (int item = 0; item < 25; ++item) {
      for (int k = 0; k < kHapticClasses; ++k) {
        const auto trace =
            SimulatedTrace(static_cast<HapticClass>(k), rng, rate_hz);
        absl::StatusOr<HapticClassification> result =
            classifier_->Classify(trace);
        ASSERT_TRUE(result.ok()) << result.status();
        double sum = 0.0;
        for (int j = 0; j < kHapticClasses; ++j) {
          sum += result->probabilities[j];
          // Trained with label smoothing: no class of a typical trace is
          // near-impossible (docs/haptic.md: smallest about -5 to -6).
          EXPECT_GT(result->log_probabilities[j], -8.0);
          EXPECT_NEAR(std::log(result->probabilities[j]),
                      result->log_probabilities[j],
                      1e-4 + 1e-5 * std::abs(result->log_probabilities[j]));
        }
        EXPECT_NEAR(sum, 1.0, 1e-5);
        EXPECT_NEAR(result->contact_time_s, 0.3, 3.5 / rate_hz + 0.012);
        correct += static_cast<int>(result->category) == k;
        ++total;
      }
    }
  }
  EXPECT_GE(correct, 0.95 * total) << correct << " of " << total;
}

TEST_F(HapticClassifierTest, TooFewSamplesIsInvalid) {
  std::vector<TimedWrench> trace(7);
  for (int i = 0; i < 7; ++i) trace[i].t_s = i * 0.001;
  absl::StatusOr<HapticClassification> result = classifier_->Classify(trace);
  ASSERT_EQ(result.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(result.status().message(),
              HasSubstr("7 samples, need at least 8"));
  EXPECT_EQ(classifier_->Classify({}).status().code(),
            absl::StatusCode::kInvalidArgument);
}

TEST_F(HapticClassifierTest, NonIncreasingTimestampsAreInvalid) {
  std::mt19937_64 rng(1);
  auto trace = SimulatedTrace(HapticClass::kHard, rng);
  trace[100].t_s = trace[99].t_s;
  absl::StatusOr<HapticClassification> result = classifier_->Classify(trace);
  ASSERT_EQ(result.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(result.status().message(), HasSubstr("samples[100].t_s"));
  EXPECT_THAT(result.status().message(), HasSubstr("strictly increasing"));
}

TEST_F(HapticClassifierTest, NanAndInfAreInvalidAndNamed) {
  std::mt19937_64 rng(2);
  auto trace = SimulatedTrace(HapticClass::kSoft, rng);
  Channel(trace[42].wrench, 4) = std::numeric_limits<double>::quiet_NaN();
  absl::StatusOr<HapticClassification> result = classifier_->Classify(trace);
  ASSERT_EQ(result.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(result.status().message(), HasSubstr("samples[42].ty_nm"));
  Channel(trace[42].wrench, 4) = 0.0;
  trace[7].t_s = std::numeric_limits<double>::infinity();
  result = classifier_->Classify(trace);
  ASSERT_EQ(result.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(result.status().message(), HasSubstr("samples[7].t_s"));
}

TEST_F(HapticClassifierTest,
       HugeValuesAndRatesOutsideTheTrainedRangeAreInvalid) {
  std::mt19937_64 rng(3);
  auto trace = SimulatedTrace(HapticClass::kMedium, rng);
  Channel(trace[30].wrench, 2) = 1e300;  // finite, but no sensor's
  absl::StatusOr<HapticClassification> result = classifier_->Classify(trace);
  ASSERT_EQ(result.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(result.status().message(),
              HasSubstr("samples[30].fz_n = 1e+300 is beyond"));
  trace = SimulatedTrace(HapticClass::kMedium, rng);
  for (size_t i = 0; i < trace.size(); ++i)
    trace[i].t_s = static_cast<double>(i);
  result = classifier_->Classify(trace);  // the same samples at 1 Hz
  ASSERT_EQ(result.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(result.status().message(), HasSubstr(" Hz on average"));
  EXPECT_THAT(result.status().message(), HasSubstr("90-7700 Hz"));
}

TEST_F(HapticClassifierTest, NoContactIsFailedPreconditionWithPeakForce) {
  // Free motion only: sensor noise around a 1.5 N offset.
  std::mt19937_64 rng(3);
  std::normal_distribution<double> noise(0.0, 0.08);
  std::vector<TimedWrench> trace;
  for (int i = 0; i < 500; ++i) {
    trace.push_back(
        {i * 0.001,
         {{noise(rng), noise(rng), 1.5 + noise(rng)}, {0.0, 0.0, 0.0}}});
  }
  absl::StatusOr<HapticClassification> result = classifier_->Classify(trace);
  ASSERT_EQ(result.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(result.status().message(), HasSubstr("no contact"));
  EXPECT_THAT(result.status().message(), HasSubstr("peak force 0."));
}

TEST(ExtractHapticFeaturesTest, TraceEndingAtContactIsInvalid) {
  // A clean 5000 N/s ramp from t = 0.1 s at 1 kHz that stops at 0.104 s:
  // contact is found, but only 4 samples follow it.
  std::vector<TimedWrench> trace;
  for (int i = 0; i <= 104; ++i) {
    const double t = i * 0.001;
    trace.push_back({t, {{0.0, 0.0, 5000.0 * std::max(0.0, t - 0.1)}, {}}});
  }
  HapticPipelineOptions options;
  options.contact.min_contact_s = 0.001;
  absl::StatusOr<HapticFeatures> features =
      ExtractHapticFeatures(trace, options);
  ASSERT_EQ(features.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(features.status().message(),
              HasSubstr("only 4 samples after the contact"));
  // Two more samples and the window is there.
  for (int i = 105; i <= 106; ++i) {
    trace.push_back(
        {i * 0.001, {0.0, 0.0, 5000.0 * (i * 0.001 - 0.1), 0, 0, 0}});
  }
  features = ExtractHapticFeatures(trace, options);
  ASSERT_TRUE(features.ok()) << features.status();
  EXPECT_NEAR(features->contact.contact_time_s, 0.1, 1e-9);
}

}  // namespace
}  // namespace bitewise::haptic
