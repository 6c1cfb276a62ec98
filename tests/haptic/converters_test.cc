// The HapticService's proto conversions (services/haptic/converters.h): a
// trace crosses the wire and back sample for sample, each class has its own
// category, and a classification reaches the response field by field.
#include "services/haptic/converters.h"

#include <vector>

#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace bitewise::haptic {
namespace {

using ::testing::ElementsAre;

TEST(HapticConvertersTest, ATraceCrossesTheWireAndBackSampleForSample) {
  const std::vector<TimedWrench> trace = {
      {0.25, {{0.5, -1.5, 12.0}, {0.01, -0.02, 0.03}}},
      {0.2505, {{-7.0, 2.25, -0.125}, {1e-5, 0.0, -0.5}}},
      {0.251, {{0.0, 0.0, 0.0}, {0.0, 0.0, 0.0}}}};
  v1::ClassifyRequest request;
  TraceToProto(trace, &request);
  ASSERT_EQ(request.samples_size(), 3);
  // The wire's field names, read by hand for the second sample.
  const v1::WrenchSample& s = request.samples(1);
  EXPECT_EQ(s.t_s(), 0.2505);
  EXPECT_EQ(s.fx_n(), -7.0);
  EXPECT_EQ(s.fy_n(), 2.25);
  EXPECT_EQ(s.fz_n(), -0.125);
  EXPECT_EQ(s.tx_nm(), 1e-5);
  EXPECT_EQ(s.ty_nm(), 0.0);
  EXPECT_EQ(s.tz_nm(), -0.5);

  const std::vector<TimedWrench> back = TraceFromProto(request);
  ASSERT_EQ(back.size(), trace.size());
  for (size_t i = 0; i < trace.size(); ++i) {
    EXPECT_EQ(back[i].t_s, trace[i].t_s);
    for (int c = 0; c < kWrenchChannels; ++c) {
      EXPECT_EQ(Channel(back[i].wrench, c), Channel(trace[i].wrench, c))
          << "sample " << i << " channel " << c;
    }
  }
}

TEST(HapticConvertersTest, TraceToProtoAppendsToTheSamplesAlreadyThere) {
  v1::ClassifyRequest request;
  request.add_samples()->set_t_s(0.1);
  TraceToProto({{0.2, {}}, {0.3, {}}}, &request);
  ASSERT_EQ(request.samples_size(), 3);
  EXPECT_EQ(request.samples(0).t_s(), 0.1);
  EXPECT_EQ(request.samples(2).t_s(), 0.3);
  EXPECT_TRUE(TraceFromProto(v1::ClassifyRequest()).empty());
}

TEST(HapticConvertersTest, EachClassHasItsOwnCategory) {
  EXPECT_EQ(CategoryToProto(HapticClass::kHard), v1::HAPTIC_CATEGORY_HARD);
  EXPECT_EQ(CategoryToProto(HapticClass::kMedium), v1::HAPTIC_CATEGORY_MEDIUM);
  EXPECT_EQ(CategoryToProto(HapticClass::kSoft), v1::HAPTIC_CATEGORY_SOFT);
  EXPECT_EQ(CategoryToProto(HapticClass::kHardSkin),
            v1::HAPTIC_CATEGORY_HARD_SKIN);
}

TEST(HapticConvertersTest, AClassificationReachesTheResponseFieldByField) {
  HapticClassification result;
  result.probabilities = {0.1, 0.2, 0.3, 0.4};
  result.log_probabilities = {-2.3, -1.6, -1.2, -0.9};
  result.category = HapticClass::kHardSkin;
  result.contact_time_s = 0.125;
  result.peak_force_n = 6.5;
  v1::ClassifyResponse response;
  ClassificationToProto(result, "sha256:abc", &response);
  EXPECT_THAT(response.probabilities(), ElementsAre(0.1, 0.2, 0.3, 0.4));
  EXPECT_THAT(response.log_probabilities(),
              ElementsAre(-2.3, -1.6, -1.2, -0.9));
  EXPECT_EQ(response.category(), v1::HAPTIC_CATEGORY_HARD_SKIN);
  EXPECT_EQ(response.contact_time_s(), 0.125);
  EXPECT_EQ(response.peak_force_n(), 6.5);
  EXPECT_EQ(response.model_fingerprint(), "sha256:abc");
  // No familiarity model: the field is absent, and nothing is unfamiliar.
  EXPECT_FALSE(response.has_familiarity());
  EXPECT_FALSE(response.unfamiliar());
}

TEST(HapticConvertersTest, TheFamiliarityScoreReachesTheResponse) {
  HapticClassification result;
  result.probabilities = {0.25, 0.25, 0.25, 0.25};
  result.log_probabilities = {-1.39, -1.39, -1.39, -1.39};
  result.has_familiarity = true;
  result.familiarity.familiarity = 0.0125;
  result.familiarity.unfamiliar = true;
  v1::ClassifyResponse response;
  ClassificationToProto(result, "fnv1a64:0", &response);
  ASSERT_TRUE(response.has_familiarity());
  EXPECT_EQ(response.familiarity(), 0.0125);
  EXPECT_TRUE(response.unfamiliar());

  result.familiarity = {3.0, 0.5, false};
  v1::ClassifyResponse familiar;
  ClassificationToProto(result, "fnv1a64:0", &familiar);
  ASSERT_TRUE(familiar.has_familiarity());
  EXPECT_EQ(familiar.familiarity(), 0.5);
  EXPECT_FALSE(familiar.unfamiliar());
}

}  // namespace
}  // namespace bitewise::haptic
