// The BanditService's conversions (services/bandit/converters.h): a
// request's configuration over the server's defaults with its errors, the
// per-user default seed, timestamps before and after 1970, and the records
// and results as the API sends them.
#include "services/bandit/converters.h"

#include <cstdint>
#include <limits>
#include <string>

#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "tests/common/status_matchers.h"

namespace bitewise::bandit {
namespace {

using ::bitewise::testing::IsOk;
using ::bitewise::testing::StatusIs;
using ::testing::ElementsAre;
using ::testing::HasSubstr;

BanditConfig Defaults() {
  BanditConfig defaults;
  defaults.context_dim = 6;
  defaults.alpha = 0.25;
  return defaults;
}

// The default seed: FNV-1a's step (xor the byte, multiply by the 64-bit
// FNV prime) over the id's bytes, written out here from its definition.
// Its starting value is converters.cc's 1469598103934665603, which is not
// FNV's offset basis (14695981039346656037: one digit more). Pinned as it
// is, since every user created without a seed got a seed of it: a change
// would give the same id another seed than earlier builds did.
constexpr uint64_t kSeedBasis = 1469598103934665603ull;
uint64_t DefaultSeed(const std::string& s) {
  uint64_t h = kSeedBasis;
  for (unsigned char c : s) {
    h = (h ^ c) * 0x100000001b3ull;
  }
  return h;
}

TEST(ConvertersTest, AnEmptyConfigIsTheDefaultsWithASeedOfTheUsersOwn) {
  absl::StatusOr<BanditConfig> config =
      ConfigFromProto(v1::UserConfig(), Defaults(), "alice");
  ASSERT_THAT(config, IsOk());
  EXPECT_EQ(config->learner, Learner::kPostHoc);
  EXPECT_EQ(config->strategy, Strategy::kLinUcb);
  EXPECT_EQ(config->alpha, 0.25);
  EXPECT_EQ(config->context_dim, 6);
  EXPECT_EQ(config->posthoc_dim, 4);
  EXPECT_EQ(config->action_names, DefaultActionNames());
  EXPECT_EQ(config->seed, DefaultSeed("alice"));
  EXPECT_EQ(ConfigFromProto(v1::UserConfig(), Defaults(), "")->seed,
            kSeedBasis);
  EXPECT_EQ(ConfigFromProto(v1::UserConfig(), Defaults(), "\xff\x01")->seed,
            DefaultSeed("\xff\x01"));
  EXPECT_NE(ConfigFromProto(v1::UserConfig(), Defaults(), "bob")->seed,
            config->seed);
  // A seed that is set, even 0, is kept.
  v1::UserConfig proto;
  proto.set_seed(0);
  EXPECT_EQ(ConfigFromProto(proto, Defaults(), "alice")->seed, 0u);
}

TEST(ConvertersTest, SetFieldsOverrideTheDefaultsAndRoundTrip) {
  v1::UserConfig proto;
  proto.set_learner(v1::LEARNER_CONTEXT_ONLY);
  proto.set_strategy(v1::STRATEGY_EPSILON_GREEDY);
  proto.set_alpha(0.0);  // set to zero: not the default
  proto.set_lambda_c(2.5);
  proto.set_lambda_p(3.5);
  proto.set_epsilon(0.2);
  proto.set_phi_radius(0.0);
  proto.set_context_dim(4);
  proto.set_posthoc_dim(2);
  proto.add_action_names("fork");
  proto.add_action_names("spoon");
  proto.set_seed(99);
  proto.set_importance_weighting(true);
  absl::StatusOr<BanditConfig> config =
      ConfigFromProto(proto, Defaults(), "alice");
  ASSERT_THAT(config, IsOk());
  EXPECT_EQ(config->learner, Learner::kContextOnly);
  EXPECT_EQ(config->strategy, Strategy::kEpsilonGreedy);
  EXPECT_EQ(config->alpha, 0.0);
  EXPECT_EQ(config->lambda_c, 2.5);
  EXPECT_EQ(config->lambda_p, 3.5);
  EXPECT_EQ(config->epsilon, 0.2);
  EXPECT_EQ(config->phi_radius, 0.0);
  EXPECT_EQ(config->context_dim, 4);
  EXPECT_EQ(config->posthoc_dim, 2);
  EXPECT_THAT(config->action_names, ElementsAre("fork", "spoon"));
  EXPECT_EQ(config->seed, 99u);
  EXPECT_TRUE(config->importance_weighting);

  v1::UserConfig back;
  ConfigToProto(*config, &back);
  EXPECT_EQ(back.learner(), v1::LEARNER_CONTEXT_ONLY);
  EXPECT_EQ(back.strategy(), v1::STRATEGY_EPSILON_GREEDY);
  EXPECT_TRUE(back.has_alpha());
  // No prior: its fields stay unset.
  EXPECT_EQ(back.prior_rounds(), 0.0);
  EXPECT_EQ(back.prior_pool_version(), 0);
  absl::StatusOr<BanditConfig> again =
      ConfigFromProto(back, BanditConfig(), "someone else");
  ASSERT_THAT(again, IsOk());
  EXPECT_EQ(again->learner, config->learner);
  EXPECT_EQ(again->strategy, config->strategy);
  EXPECT_EQ(again->alpha, config->alpha);
  EXPECT_EQ(again->lambda_c, config->lambda_c);
  EXPECT_EQ(again->lambda_p, config->lambda_p);
  EXPECT_EQ(again->epsilon, config->epsilon);
  EXPECT_EQ(again->phi_radius, config->phi_radius);
  EXPECT_EQ(again->context_dim, config->context_dim);
  EXPECT_EQ(again->posthoc_dim, config->posthoc_dim);
  EXPECT_EQ(again->action_names, config->action_names);
  EXPECT_EQ(again->seed, config->seed);
  EXPECT_EQ(again->importance_weighting, config->importance_weighting);

  BanditConfig with_prior = *config;
  with_prior.prior.pool_version = 3;
  with_prior.prior.rounds = 12.5;
  v1::UserConfig prior_proto;
  ConfigToProto(with_prior, &prior_proto);
  EXPECT_EQ(prior_proto.prior_rounds(), 12.5);
  EXPECT_EQ(prior_proto.prior_pool_version(), 3);
}

TEST(ConvertersTest, BadConfigsAreInvalidArgumentNamingTheField) {
  struct Case {
    const char* message;
    void (*spoil)(v1::UserConfig*);
  };
  const Case cases[] = {
      {"config.learner: unknown value 9 (known: ",
       [](v1::UserConfig* p) { p->set_learner(static_cast<v1::Learner>(9)); }},
      {"config.strategy: unknown value 6",
       [](v1::UserConfig* p) {
         p->set_strategy(static_cast<v1::Strategy>(6));
       }},
      {"config.alpha", [](v1::UserConfig* p) { p->set_alpha(-1); }},
      {"config.lambda_c", [](v1::UserConfig* p) { p->set_lambda_c(0); }},
      {"config.epsilon", [](v1::UserConfig* p) { p->set_epsilon(2); }},
      // Huge dimensions are named as sent, not clamped or wrapped negative.
      {"config.context_dim: must be in [1, 65536], got 4294967295",
       [](v1::UserConfig* p) { p->set_context_dim(0xffffffffu); }},
      {"config.posthoc_dim: must be in [0, 1024], got 2000",
       [](v1::UserConfig* p) { p->set_posthoc_dim(2000); }},
      {"config.action_names[1]: duplicate name \"a\"",
       [](v1::UserConfig* p) {
         p->add_action_names("a");
         p->add_action_names("a");
       }},
  };
  for (const Case& c : cases) {
    v1::UserConfig proto;
    c.spoil(&proto);
    EXPECT_THAT(
        ConfigFromProto(proto, Defaults(), "alice"),
        StatusIs(absl::StatusCode::kInvalidArgument, HasSubstr(c.message)))
        << c.message;
  }
  // Bad server defaults are caught too, even when the request is empty.
  BanditConfig bad_defaults = Defaults();
  bad_defaults.lambda_p = -1;
  EXPECT_THAT(ConfigFromProto(v1::UserConfig(), bad_defaults, "alice"),
              StatusIs(absl::StatusCode::kInvalidArgument,
                       HasSubstr("config.lambda_p")));
}

TEST(ConvertersTest, TimestampsBefore1970HavePositiveNanos) {
  EventRecord event;
  event.event_id = 12;
  event.selected_at = absl::FromUnixMicros(-1500001);  // -1.500001 s
  event.completed = true;
  event.updated_at = absl::FromUnixMicros(1700000000123456);
  v1::Event proto;
  EventToProto(event, &proto);
  EXPECT_EQ(proto.selected_at().seconds(), -2);
  EXPECT_EQ(proto.selected_at().nanos(), 499999000);
  EXPECT_EQ(proto.updated_at().seconds(), 1700000000);
  EXPECT_EQ(proto.updated_at().nanos(), 123456000);

  UserRecord user;
  user.created_at = absl::FromUnixMicros(-1000000);
  v1::User user_proto;
  UserToProto(user, &user_proto);
  EXPECT_EQ(user_proto.created_at().seconds(), -1);
  EXPECT_EQ(user_proto.created_at().nanos(), 0);
}

TEST(ConvertersTest, APendingEventHasNoOutcome) {
  EventRecord event;
  event.event_id = 9223372036854775807;
  event.user_id = "ann";
  event.meal_id = "lunch";
  event.item_label = "pea";
  event.context = {0.5, -1.0};
  event.action = 3;
  event.propensity = 0.25;
  event.selected_at = absl::FromUnixMicros(5);
  // Values a pending event does not have yet are not sent.
  event.loss = 1.0;
  event.posthoc = {7.0};
  event.model_version = 4;
  event.updated_at = absl::FromUnixMicros(6);
  v1::Event proto;
  EventToProto(event, &proto);
  EXPECT_EQ(proto.event_id(), "9223372036854775807");
  EXPECT_EQ(proto.user_id(), "ann");
  EXPECT_EQ(proto.meal_id(), "lunch");
  EXPECT_EQ(proto.item_label(), "pea");
  EXPECT_THAT(proto.context(), ElementsAre(0.5, -1.0));
  EXPECT_EQ(proto.action(), 3);
  EXPECT_EQ(proto.propensity(), 0.25);
  EXPECT_FALSE(proto.completed());
  EXPECT_EQ(proto.loss(), 0.0);
  EXPECT_EQ(proto.posthoc_size(), 0);
  EXPECT_EQ(proto.model_version(), 0);
  EXPECT_FALSE(proto.has_updated_at());
  EXPECT_EQ(proto.selected_at().nanos(), 5000);

  event.completed = true;
  v1::Event completed;
  EventToProto(event, &completed);
  EXPECT_EQ(completed.loss(), 1.0);
  EXPECT_THAT(completed.posthoc(), ElementsAre(7.0));
  EXPECT_EQ(completed.model_version(), 4);
  EXPECT_EQ(completed.updated_at().nanos(), 6000);
}

TEST(ConvertersTest, SelectResultsCarryEveryActionsEstimateByName) {
  SelectResult result;
  result.event_id = 41;
  result.action = 1;
  result.action_name = "spoon";
  result.propensity = 0.9;
  result.model_version = 8;
  result.action_names = {"fork", "spoon"};
  result.estimates = {{0.5, 0.1, 0.49}, {0.2, 0.3, 0.17}};
  v1::SelectResponse proto;
  SelectToProto(result, &proto);
  EXPECT_EQ(proto.event_id(), "41");
  EXPECT_EQ(*ParseEventId(proto.event_id()), 41);
  EXPECT_EQ(proto.action(), 1);
  EXPECT_EQ(proto.action_name(), "spoon");
  EXPECT_EQ(proto.propensity(), 0.9);
  EXPECT_EQ(proto.model_version(), 8);
  ASSERT_EQ(proto.estimates_size(), 2);
  EXPECT_EQ(proto.estimates(1).action(), 1);
  EXPECT_EQ(proto.estimates(1).action_name(), "spoon");
  EXPECT_EQ(proto.estimates(1).predicted_loss(), 0.2);
  EXPECT_EQ(proto.estimates(1).width(), 0.3);
  EXPECT_EQ(proto.estimates(1).lcb(), 0.17);
  EXPECT_EQ(proto.estimates(0).action_name(), "fork");
}

TEST(ConvertersTest, UpdatesTakeOnlyTheIdsSelectReturns) {
  v1::UpdateRequest request;
  request.set_event_id("17");
  request.set_loss(1.0);
  request.add_posthoc(0.5);
  absl::StatusOr<UpdateInput> input = UpdateInputFromProto(request);
  ASSERT_THAT(input, IsOk());
  EXPECT_EQ(input->event_id, 17);
  EXPECT_EQ(input->loss, 1.0);
  EXPECT_THAT(input->posthoc, ElementsAre(0.5));

  request.set_event_id(std::string(100, '9'));
  absl::StatusOr<UpdateInput> bad = UpdateInputFromProto(request);
  EXPECT_THAT(bad, StatusIs(absl::StatusCode::kInvalidArgument,
                            HasSubstr("event_id: expected the decimal id")));
  // The id is quoted, cut to 64 characters.
  EXPECT_THAT(bad.status().message(),
              HasSubstr("\"" + std::string(64, '9') + "\""));
  EXPECT_THAT(bad.status().message(),
              ::testing::Not(HasSubstr(std::string(65, '9'))));
}

TEST(ConvertersTest, PagesDefaultTheirSizeAndStayUnderTheMessageLimit) {
  const Page page = PageFromProto(0, "token");
  EXPECT_EQ(page.page_size, Page().page_size);
  EXPECT_EQ(page.page_token, "token");
  EXPECT_EQ(page.max_bytes, 3 << 20);
  EXPECT_EQ(PageFromProto(-5, "").page_size, Page().page_size);
  EXPECT_EQ(PageFromProto(7, "").page_size, 7);
}

TEST(ConvertersTest, ACheckWithFindingsIsNotOk) {
  StoreCheckReport report;
  report.users_checked = 3;
  report.events_checked = 40;
  v1::CheckStoreResponse clean;
  CheckReportToProto(report, absl::Milliseconds(1500), &clean);
  EXPECT_TRUE(clean.ok());
  EXPECT_EQ(clean.users_checked(), 3);
  EXPECT_EQ(clean.events_checked(), 40);
  EXPECT_DOUBLE_EQ(clean.seconds(), 1.5);

  report.findings = {"event 5: checksum"};
  v1::CheckStoreResponse damaged;
  CheckReportToProto(report, absl::ZeroDuration(), &damaged);
  EXPECT_FALSE(damaged.ok());
  EXPECT_THAT(damaged.findings(), ElementsAre("event 5: checksum"));
}

TEST(ConvertersTest, ModelsAndPoolsCarryTheirFields) {
  ModelExport model;
  model.user.user_id = "ann";
  model.user.model_version = 5;
  model.user.config.action_names = {"fork"};
  ActionModelExport action;
  action.action = 0;
  action.action_name = "fork";
  action.count = 5;
  action.theta = {0.1, 0.2};
  action.phi = {0.3};
  action.mean_loss = 0.4;
  model.actions.push_back(action);
  v1::Model proto;
  ModelToProto(model, &proto);
  EXPECT_EQ(proto.user_id(), "ann");
  EXPECT_EQ(proto.model_version(), 5);
  EXPECT_THAT(proto.config().action_names(), ElementsAre("fork"));
  ASSERT_EQ(proto.actions_size(), 1);
  EXPECT_EQ(proto.actions(0).count(), 5);
  EXPECT_THAT(proto.actions(0).theta(), ElementsAre(0.1, 0.2));
  EXPECT_THAT(proto.actions(0).phi(), ElementsAre(0.3));
  EXPECT_EQ(proto.actions(0).mean_loss(), 0.4);

  PoolRecord pool;
  pool.pool_version = 2;
  pool.users = 11;
  pool.learner = Learner::kPoLinUcb;
  pool.context_dim = 8;
  pool.posthoc_dim = 3;
  pool.action_names = {"a", "b"};
  pool.prior.context_msn = 1.5;
  pool.prior.posthoc_msn = 2.5;
  pool.created_at = absl::FromUnixSeconds(100);
  v1::PopulationPool pool_proto;
  PoolToProto(pool, &pool_proto);
  EXPECT_EQ(pool_proto.pool_version(), 2);
  EXPECT_EQ(pool_proto.users(), 11);
  EXPECT_EQ(pool_proto.like().learner(), v1::LEARNER_POLINUCB);
  EXPECT_EQ(pool_proto.like().context_dim(), 8u);
  EXPECT_EQ(pool_proto.like().posthoc_dim(), 3u);
  EXPECT_THAT(pool_proto.like().action_names(), ElementsAre("a", "b"));
  EXPECT_EQ(pool_proto.context_msn(), 1.5);
  EXPECT_EQ(pool_proto.posthoc_msn(), 2.5);
  EXPECT_EQ(pool_proto.created_at().seconds(), 100);
}

}  // namespace
}  // namespace bitewise::bandit
