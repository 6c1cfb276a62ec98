// The domain vocabulary every process shares (services/domain): the six
// skewering actions, the haptic classes' two spellings, the person-id rule,
// the new user's context ridge and the wrench's channels.
#include <cmath>
#include <set>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "services/domain/context_ridge.h"
#include "services/domain/haptic_class.h"
#include "services/domain/posthoc_context.h"
#include "services/domain/skewering_actions.h"
#include "services/domain/user_id.h"
#include "services/domain/wrench.h"

namespace bitewise::domain {
namespace {

using ::testing::HasSubstr;

TEST(SkeweringActionsTest, TheSixOfThePaperInTheirOrder) {
  const char* const names[] = {"VS0", "VS90", "TV0", "TV90", "TA0", "TA90"};
  std::set<std::string> seen;
  for (int i = 0; i < kNumActions; ++i) {
    const SkeweringAction& a = kSkeweringActions[i];
    EXPECT_STREQ(a.name, names[i]);
    seen.insert(a.name);
    // "90" is the roll a quarter turn, "0" none; the force limit is
    // positive and the people-facing texts are there.
    const bool turned = std::string(a.name).find("90") != std::string::npos;
    EXPECT_EQ(a.roll_rad, turned ? kQuarterTurnRad : 0.0) << a.name;
    EXPECT_GT(a.max_force_n, 0.0) << a.name;
    EXPECT_GT(std::string(a.title).size(), 0u) << a.name;
    EXPECT_THAT(a.description,
                HasSubstr(absl::StrCat(static_cast<int>(a.max_force_n), " N")))
        << a.name;
  }
  EXPECT_EQ(seen.size(), static_cast<size_t>(kNumActions));
  // Each pair differs only by the roll.
  for (int i = 0; i < kNumActions; i += 2) {
    EXPECT_EQ(kSkeweringActions[i].pitch_rad,
              kSkeweringActions[i + 1].pitch_rad);
    EXPECT_EQ(kSkeweringActions[i].max_force_n,
              kSkeweringActions[i + 1].max_force_n);
  }
}

TEST(HapticClassTest, IdentifierAndPeopleSpellings) {
  EXPECT_STREQ(HapticClassName(HapticClass::kHard), "hard");
  EXPECT_STREQ(HapticClassName(HapticClass::kMedium), "medium");
  EXPECT_STREQ(HapticClassName(HapticClass::kSoft), "soft");
  EXPECT_STREQ(HapticClassName(HapticClass::kHardSkin), "hard_skin");
  EXPECT_STREQ(HapticClassLabel(HapticClass::kHardSkin), "hard-skin");
  EXPECT_STREQ(HapticClassLabel(HapticClass::kSoft), "soft");
  // HapticNet's output order.
  EXPECT_EQ(static_cast<int>(HapticClass::kHardSkin), kHapticClasses - 1);
}

TEST(UserIdTest, OnlyCharactersThatNeedNoEscaping) {
  EXPECT_TRUE(ValidateUserId("alice").ok());
  EXPECT_TRUE(ValidateUserId("A.b_c-9").ok());
  EXPECT_TRUE(ValidateUserId(std::string(128, 'x')).ok());
  const absl::Status empty = ValidateUserId("");
  EXPECT_EQ(empty.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(empty.message(), HasSubstr("user_id: must be 1-128"));
  EXPECT_THAT(ValidateUserId(std::string(129, 'x')).message(),
              HasSubstr("got 129"));
  EXPECT_THAT(ValidateUserId("-alice").message(),
              HasSubstr("must start with a letter or digit"));
  for (const char* bad : {"a b", "a/b", "a%2F", "a\xc3\xa9", "a\nb"}) {
    const absl::Status status = ValidateUserId(bad);
    EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument) << bad;
    EXPECT_THAT(status.message(), HasSubstr("only letters, digits")) << bad;
  }
  EXPECT_THAT(ValidateId("meal_id", "").message(), HasSubstr("meal_id:"));
}

TEST(WrenchTest, ChannelsInHapticNetsOrderBothWays) {
  Wrench w;
  w.force_n = {1.0, 2.0, 3.0};
  w.torque_nm = {0.1, 0.2, 0.3};
  const std::array<double, kWrenchChannels> want = {1.0, 2.0, 3.0,
                                                    0.1, 0.2, 0.3};
  EXPECT_EQ(Channels(w), want);
  for (int k = 0; k < kWrenchChannels; ++k) EXPECT_EQ(Channel(w, k), want[k]);
  Channel(w, 4) = -7.0;  // ty
  EXPECT_EQ(w.torque_nm[1], -7.0);
  const Wrench back = WrenchFromChannels(Channels(w));
  EXPECT_EQ(back.force_n, w.force_n);
  EXPECT_EQ(back.torque_nm, w.torque_nm);
}

TEST(ContextRidgeTest, ExplicitThenScaleRuleThenTheServiceDefault) {
  EXPECT_EQ(NewUserContextRidge(5.0, 3.0, 100.0), 5.0);
  EXPECT_EQ(NewUserContextRidge(0.0, 3.0, 100.0), 300.0);
  EXPECT_EQ(NewUserContextRidge(0.0, 3.0, 0.0), 0.0);
  EXPECT_EQ(NewUserContextRidge(-1.0, 0.5, 8.0), 4.0);
}

TEST(PosthocContextTest, AFamiliarBiteSendsHapticNetsAnswer) {
  const std::vector<double> log_p = {-0.1, -2.5, -4.6, -4.6};
  for (UnfamiliarPosthoc rule :
       {UnfamiliarPosthoc::kAsIs, UnfamiliarPosthoc::kUniform,
        UnfamiliarPosthoc::kZero}) {
    EXPECT_EQ(PosthocContext(log_p, true, /*unfamiliar=*/false, rule), log_p);
  }
  EXPECT_EQ(PosthocContext(log_p, true, true, UnfamiliarPosthoc::kAsIs), log_p);
}

TEST(PosthocContextTest, AnUnfamiliarBiteSendsWhatTheRuleSays) {
  const std::vector<double> p = {0.9, 0.05, 0.03, 0.02};
  EXPECT_EQ(PosthocContext(p, false, true, UnfamiliarPosthoc::kUniform),
            std::vector<double>(4, 0.25));
  EXPECT_EQ(PosthocContext(p, true, true, UnfamiliarPosthoc::kUniform),
            std::vector<double>(4, std::log(0.25)));
  EXPECT_EQ(PosthocContext(p, true, true, UnfamiliarPosthoc::kZero),
            std::vector<double>(4, 0.0));
}

TEST(PosthocContextTest, RuleNamesRoundTripAndABadOneNamesTheChoices) {
  for (UnfamiliarPosthoc rule :
       {UnfamiliarPosthoc::kAsIs, UnfamiliarPosthoc::kUniform,
        UnfamiliarPosthoc::kZero}) {
    absl::StatusOr<UnfamiliarPosthoc> parsed =
        ParseUnfamiliarPosthoc(UnfamiliarPosthocName(rule));
    ASSERT_TRUE(parsed.ok());
    EXPECT_EQ(*parsed, rule);
  }
  absl::StatusOr<UnfamiliarPosthoc> bad = ParseUnfamiliarPosthoc("flat");
  EXPECT_EQ(bad.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(bad.status().message(),
              ::testing::HasSubstr("expected asis, uniform or zero"));
}

}  // namespace
}  // namespace bitewise::domain
