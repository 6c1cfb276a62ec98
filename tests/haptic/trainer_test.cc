// The trainer: bit-identical models from the same seed, a model that
// actually learns the simulated categories, the CSV trace format, and
// rejection of bad training sets.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>

#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "services/haptic/training/haptic_net_weights.h"
#include "services/haptic/training/haptic_trainer.h"
#include "services/haptic/training/labelled_traces.h"

namespace bitewise::haptic {
namespace {

using ::testing::HasSubstr;

struct SmallData {
  LabelledWindows train, validation, test;
};

SmallData MakeData(int per_class) {
  const HapticPipelineOptions pipeline;
  SmallData data;
  data.train = WindowsFromTraces(
      SimulateLabelledTraces(per_class, TrainingConditions(), 21), pipeline,
      nullptr);
  data.validation = WindowsFromTraces(
      SimulateLabelledTraces(per_class / 4, TrainingConditions(), 22), pipeline,
      nullptr);
  data.test = WindowsFromTraces(
      SimulateLabelledTraces(per_class / 2, SimulationConditions(), 23),
      pipeline, nullptr);
  return data;
}

// The reference pass of `weights` on the test windows, scored.
ProbabilisticScore ScoreOnTest(const HapticNetWeights& weights,
                               const SmallData& data) {
  std::vector<std::array<double, kHapticClasses>> probabilities;
  for (const auto& x : data.test.inputs) {
    probabilities.push_back(ReferenceProbabilities(weights, x));
  }
  return ScorePredictions(probabilities, data.test.labels);
}

TEST(TrainerTest, SameSeedGivesIdenticalModelBytes) {
  const SmallData data = MakeData(40);
  TrainerOptions options;
  options.max_epochs = 3;
  auto a = TrainHapticNet(data.train, data.validation, options);
  auto b = TrainHapticNet(data.train, data.validation, options);
  options.seed = 2;
  auto c = TrainHapticNet(data.train, data.validation, options);
  ASSERT_TRUE(a.ok() && b.ok() && c.ok());
  const std::string bytes_a = HapticNetToOnnx(a->weights, {});
  EXPECT_TRUE(bytes_a == HapticNetToOnnx(b->weights, {}));
  EXPECT_FALSE(bytes_a == HapticNetToOnnx(c->weights, {}));
}

TEST(TrainerTest, LearnsTheSimulatedCategories) {
  const SmallData data = MakeData(200);
  ASSERT_EQ(data.train.inputs.size(), 800u);
  TrainerOptions options;
  options.max_epochs = 15;
  std::vector<EpochLog> seen;
  auto result =
      TrainHapticNet(data.train, data.validation, options,
                     [&](const EpochLog& log) { seen.push_back(log); });
  ASSERT_TRUE(result.ok()) << result.status();
  EXPECT_EQ(seen.size(), result->epochs.size());
  EXPECT_GE(result->best_epoch, 1);
  EXPECT_LE(result->best_epoch, static_cast<int>(result->epochs.size()));
  EXPECT_LT(result->epochs[result->best_epoch - 1].validation_loss,
            result->epochs[0].validation_loss);
  const ProbabilisticScore score = ScoreOnTest(result->weights, data);
  // A chance-level model would score 25 %.
  EXPECT_GT(score.confusion.Accuracy(), 0.9) << score.confusion.ToString();
  EXPECT_LT(score.mean_log_loss, 0.4);
  // The temperature may only soften the label-smoothed model.
  EXPECT_GE(result->temperature, TrainerOptions().min_temperature);
}

TEST(TrainerTest, ConvolutionalFrontEndLearnsDeterministically) {
  const SmallData data = MakeData(200);
  TrainerOptions options;
  options.max_epochs = 15;
  options.conv_channels = {8, 16};
  auto result = TrainHapticNet(data.train, data.validation, options);
  ASSERT_TRUE(result.ok()) << result.status();
  ASSERT_EQ(result->weights.conv.size(), 2u);
  EXPECT_EQ(result->weights.w1.rows(), 16 * 16);
  EXPECT_LT(result->epochs[result->best_epoch - 1].validation_loss,
            result->epochs[0].validation_loss);
  const ProbabilisticScore score = ScoreOnTest(result->weights, data);
  EXPECT_GT(score.confusion.Accuracy(), 0.9) << score.confusion.ToString();
  options.max_epochs = 2;
  auto a = TrainHapticNet(data.train, data.validation, options);
  auto b = TrainHapticNet(data.train, data.validation, options);
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_TRUE(HapticNetToOnnx(a->weights, {}) ==
              HapticNetToOnnx(b->weights, {}));
  options.conv_channels = {8, 0};
  EXPECT_EQ(
      TrainHapticNet(data.train, data.validation, options).status().code(),
      absl::StatusCode::kInvalidArgument);
}

// The smoothed cross-entropy from the reference pass, written out here.
double ReferenceLoss(const HapticNetWeights& w, const LabelledWindows& data,
                     double smoothing) {
  double sum = 0.0;
  for (size_t i = 0; i < data.inputs.size(); ++i) {
    const auto logits = ReferenceLogits(w, data.inputs[i]);
    double normaliser = 0.0;
    for (double v : logits) normaliser += std::exp(v);
    for (int k = 0; k < kHapticClasses; ++k) {
      const double target = (k == data.labels[i] ? 1.0 - smoothing : 0.0) +
                            smoothing / kHapticClasses;
      sum -= target * (logits[k] - std::log(normaliser));
    }
  }
  return sum / data.inputs.size();
}

TEST(TrainerTest, BackPropagationMatchesFiniteDifferences) {
  const SmallData data = MakeData(8);
  for (const std::vector<int>& channels :
       std::vector<std::vector<int>>{{}, {3, 4}}) {
    // Start from a briefly trained model so that the losses are not flat.
    TrainerOptions options;
    options.max_epochs = 1;
    options.conv_channels = channels;
    auto trained = TrainHapticNet(data.train, data.validation, options);
    ASSERT_TRUE(trained.ok()) << trained.status();
    HapticNetWeights w = trained->weights;
    auto analytic = SmoothedLossGradient(w, data.train, 0.04);
    ASSERT_TRUE(analytic.ok()) << analytic.status();
    EXPECT_NEAR(analytic->loss, ReferenceLoss(w, data.train, 0.04), 1e-10);
    // Central differences on parameters of every kind.
    std::vector<std::pair<double*, double>> probes;
    for (size_t i = 0; i < w.conv.size(); ++i) {
      for (size_t j = 0; j < w.conv[i].weight.size(); j += 7) {
        probes.push_back(
            {&w.conv[i].weight[j], analytic->gradient.conv[i].weight[j]});
      }
      for (size_t j = 0; j < w.conv[i].bias.size(); ++j) {
        probes.push_back(
            {&w.conv[i].bias[j], analytic->gradient.conv[i].bias[j]});
      }
    }
    for (Eigen::Index j = 0; j < w.w1.size(); j += 997) {
      probes.push_back({w.w1.data() + j, analytic->gradient.w1.data()[j]});
    }
    for (Eigen::Index j = 0; j < w.b1.size(); j += 13) {
      probes.push_back({w.b1.data() + j, analytic->gradient.b1.data()[j]});
    }
    for (Eigen::Index j = 0; j < w.w2.size(); j += 1009) {
      probes.push_back({w.w2.data() + j, analytic->gradient.w2.data()[j]});
    }
    for (Eigen::Index j = 0; j < w.w3.size(); j += 17) {
      probes.push_back({w.w3.data() + j, analytic->gradient.w3.data()[j]});
    }
    for (Eigen::Index j = 0; j < w.b3.size(); ++j) {
      probes.push_back({w.b3.data() + j, analytic->gradient.b3.data()[j]});
    }
    int checked = 0;
    for (auto& [parameter, expected] : probes) {
      const double saved = *parameter;
      constexpr double kStep = 1e-6;
      *parameter = saved + kStep;
      const double up = ReferenceLoss(w, data.train, 0.04);
      *parameter = saved - kStep;
      const double down = ReferenceLoss(w, data.train, 0.04);
      *parameter = saved;
      const double numeric = (up - down) / (2 * kStep);
      EXPECT_NEAR(expected, numeric, 1e-6 + 1e-4 * std::abs(numeric))
          << channels.size() << " front-end layers, probe " << checked;
      ++checked;
    }
    EXPECT_GT(checked, channels.empty() ? 30 : 60);
  }
}

// Mean over windows of the smallest log-probability (the least likely
// class) of a model trained with `label_smoothing`.
double MeanSmallestLogProbability(const SmallData& data,
                                  double label_smoothing) {
  TrainerOptions options;
  options.max_epochs = 15;
  options.label_smoothing = label_smoothing;
  auto result = TrainHapticNet(data.train, data.validation, options);
  EXPECT_TRUE(result.ok()) << result.status();
  if (!result.ok()) return 0.0;
  double sum = 0.0;
  for (const auto& x : data.test.inputs) {
    const auto p = ReferenceProbabilities(result->weights, x);
    sum += std::log(*std::min_element(p.begin(), p.end()));
  }
  return sum / data.test.inputs.size();
}

TEST(TrainerTest, LabelSmoothingKeepsUnlikelyClassesAwayFromZero) {
  const SmallData data = MakeData(200);
  const double smoothed = MeanSmallestLogProbability(data, 0.04);
  const double sharp = MeanSmallestLogProbability(data, 0.0);
  // Smoothing 0.04 targets 0.01 (log -4.6) for the other classes.
  EXPECT_GT(smoothed, -7.0);
  EXPECT_GT(smoothed, sharp + 2.0)
      << "smoothed " << smoothed << ", sharp " << sharp;
}

TEST(TrainerTest, RejectsBadSmoothingAndTemperatureBounds) {
  LabelledWindows one;
  one.inputs.resize(1);
  one.labels = {0};
  TrainerOptions options;
  options.label_smoothing = 1.0;
  EXPECT_EQ(TrainHapticNet(one, one, options).status().code(),
            absl::StatusCode::kInvalidArgument);
  options = TrainerOptions();
  options.min_temperature = 2.0;
  options.max_temperature = 1.0;
  EXPECT_EQ(TrainHapticNet(one, one, options).status().code(),
            absl::StatusCode::kInvalidArgument);
}

TEST(LabelledTracesTest, AugmentationIsSeededAndOffByDefault) {
  EXPECT_FALSE(SimulationConditions().Augmented());
  EXPECT_TRUE(TrainingConditions().Augmented());
  const auto a = SimulateLabelledTraces(3, TrainingConditions(), 7);
  const auto b = SimulateLabelledTraces(3, TrainingConditions(), 7);
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].label, b[i].label);
    ASSERT_EQ(a[i].samples.size(), b[i].samples.size());
    for (size_t j = 0; j < a[i].samples.size(); ++j) {
      EXPECT_EQ(a[i].samples[j].t_s, b[i].samples[j].t_s);
      EXPECT_EQ(Channels(a[i].samples[j].wrench),
                Channels(b[i].samples[j].wrench));
    }
  }
}

TEST(LabelledTracesTest, AugmentedClassesKeepTheirSignatures) {
  // Peak tared Fz in the first 50 ms after the true contact, over many
  // augmented items: hard stays the highest, soft the lowest.
  SimulationConditions conditions = TrainingConditions();
  conditions.min_rate_hz = conditions.max_rate_hz = 7000.0;
  conditions.random_bias_n = 0.0;
  conditions.min_noise_scale = conditions.max_noise_scale = 0.0;
  conditions.min_contact_s = conditions.max_contact_s = 0.1;
  std::array<double, kHapticClasses> lowest, highest;
  lowest.fill(1e9);
  highest.fill(0.0);
  for (const LabelledTrace& trace :
       SimulateLabelledTraces(200, conditions, 11)) {
    double peak = 0.0;
    for (const TimedWrench& s : trace.samples) {
      if (s.t_s <= 0.15) peak = std::max(peak, Channel(s.wrench, 2));
    }
    const int k = static_cast<int>(trace.label);
    lowest[k] = std::min(lowest[k], peak);
    highest[k] = std::max(highest[k], peak);
  }
  const int hard = static_cast<int>(HapticClass::kHard);
  const int soft = static_cast<int>(HapticClass::kSoft);
  EXPECT_GT(lowest[hard], 6.0);
  EXPECT_LT(highest[soft], 3.5);
  EXPECT_GT(lowest[hard], highest[soft]);
}

TEST(TrainerTest, RejectsBadTrainingSets) {
  LabelledWindows empty;
  LabelledWindows one;
  one.inputs.resize(1);
  one.labels = {0};
  EXPECT_THAT(TrainHapticNet(empty, one, TrainerOptions()).status().message(),
              HasSubstr("training set: no windows"));
  LabelledWindows bad_label = one;
  bad_label.labels = {7};
  EXPECT_THAT(
      TrainHapticNet(bad_label, one, TrainerOptions()).status().message(),
      HasSubstr("label 7"));
  TrainerOptions options;
  options.batch_size = 0;
  EXPECT_EQ(TrainHapticNet(one, one, options).status().code(),
            absl::StatusCode::kInvalidArgument);
}

TEST(ConfusionMatrixTest, AccuracyAndCalibrationByHand) {
  // Two windows: class 0 predicted with 0.9 (right), class 1 predicted as 0
  // with 0.6 (wrong).
  const ProbabilisticScore score =
      ScorePredictions({{0.9, 0.1, 0.0, 0.0}, {0.6, 0.4, 0.0, 0.0}}, {0, 1});
  EXPECT_EQ(score.confusion.counts[0][0], 1);
  EXPECT_EQ(score.confusion.counts[1][0], 1);
  EXPECT_DOUBLE_EQ(score.confusion.Accuracy(), 0.5);
  EXPECT_NEAR(score.mean_log_loss, -(std::log(0.9) + std::log(0.4)) / 2, 1e-12);
  // Bins: 0.9 right (gap 0.1), 0.6 wrong (gap 0.6); ECE = (0.1 + 0.6) / 2.
  EXPECT_NEAR(score.expected_calibration_error, 0.35, 1e-12);
}

class TraceCsvTest : public ::testing::Test {
 protected:
  std::string Path(const std::string& name) {
    return ::testing::TempDir() + "/" + name;
  }
  void WriteText(const std::string& path, const std::string& text) {
    std::ofstream(path) << text;
  }
};

TEST_F(TraceCsvTest, RoundTripIsExact) {
  SimulationConditions conditions = TrainingConditions();
  const auto traces = SimulateLabelledTraces(2, conditions, 5);
  const std::string path = Path("traces.csv");
  ASSERT_TRUE(WriteTraceCsv(path, traces).ok());
  absl::StatusOr<std::vector<LabelledTrace>> read = ReadTraceCsv(path);
  ASSERT_TRUE(read.ok()) << read.status();
  ASSERT_EQ(read->size(), traces.size());
  for (size_t i = 0; i < traces.size(); ++i) {
    EXPECT_EQ((*read)[i].label, traces[i].label);
    ASSERT_EQ((*read)[i].samples.size(), traces[i].samples.size());
    for (size_t j = 0; j < traces[i].samples.size(); ++j) {
      EXPECT_EQ((*read)[i].samples[j].t_s, traces[i].samples[j].t_s);
      EXPECT_EQ(Channels((*read)[i].samples[j].wrench),
                Channels(traces[i].samples[j].wrench));
    }
  }
}

TEST_F(TraceCsvTest, ReportsTheOffendingLine) {
  const std::string header =
      "trace,label,t_s,fx_n,fy_n,fz_n,tx_nm,ty_nm,tz_nm\n";
  const std::string path = Path("bad.csv");
  WriteText(path,
            header + "0,hard,0,0,0,0,0,0,0\n0,crunchy,0.001,0,0,0,0,0,0\n");
  EXPECT_THAT(ReadTraceCsv(path).status().message(),
              HasSubstr(":3: unknown label \"crunchy\""));
  WriteText(path, header + "0,hard,0,0,0,0,0,0,0\n0,soft,0.001,0,0,0,0,0,0\n");
  EXPECT_THAT(ReadTraceCsv(path).status().message(),
              HasSubstr(":3: trace 0 changes its label"));
  WriteText(path, header + "0,hard,0,x,0,0,0,0,0\n");
  EXPECT_THAT(ReadTraceCsv(path).status().message(),
              HasSubstr(":2: malformed number"));
  WriteText(path, "t,fx\n");
  EXPECT_THAT(ReadTraceCsv(path).status().message(),
              HasSubstr(":1: expected the header"));
  EXPECT_EQ(ReadTraceCsv(Path("missing.csv")).status().code(),
            absl::StatusCode::kNotFound);
}

}  // namespace
}  // namespace bitewise::haptic
