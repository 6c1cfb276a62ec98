// The population pools and audit roles of the store contract
// (population_pools.h, audit_log.h) and the full check, on every backend.
#include "tests/bandit/store/store_test_fixture.h"

namespace bitewise::bandit::store_test {
namespace {

class PoolsAuditContractTest : public StoreContractTest {};
INSTANTIATE_TEST_SUITE_P(Stores, PoolsAuditContractTest, kAllBackends,
                         BackendName);

TEST_P(PoolsAuditContractTest, PoolsAndUsersWithAPriorRoundTripExactly) {
  EXPECT_EQ(store_->LatestPool(SmallConfig()).status().code(),
            absl::StatusCode::kNotFound);
  EXPECT_THAT(store_->LatestPool(SmallConfig()).status().message(),
              HasSubstr("BuildPopulationPrior"));
  PoolRecord pool;
  pool.created_at = absl::FromUnixMicros(1700000000000001);
  pool.users = 20;
  pool.learner = Learner::kPostHoc;
  pool.context_dim = 3;
  pool.posthoc_dim = 2;
  pool.action_names = DefaultActionNames();
  pool.prior = SmallPrior(0, 0.0);
  auto first = store_->AddPool(pool);
  auto second = store_->AddPool(pool);
  ASSERT_TRUE(first.ok() && second.ok());
  EXPECT_GT(*second, *first);
  auto latest = store_->LatestPool(SmallConfig());
  ASSERT_TRUE(latest.ok()) << latest.status();
  EXPECT_EQ(latest->pool_version, *second);
  EXPECT_EQ(latest->prior.pool_version, *second);
  EXPECT_EQ(latest->users, 20);
  EXPECT_EQ(latest->prior.theta0, pool.prior.theta0);
  EXPECT_EQ(latest->prior.phi0, pool.prior.phi0);
  EXPECT_EQ(latest->prior.context_msn, 1.25);
  // Other dimensions have no pool.
  BanditConfig other = SmallConfig();
  other.context_dim = 4;
  EXPECT_EQ(store_->LatestPool(other).status().code(),
            absl::StatusCode::kNotFound);

  UserRecord user = MakeUser("primed");
  user.config.prior = SmallPrior(*second, 12.5);
  ASSERT_TRUE(store_->CreateUser(user).ok());
  auto read = store_->GetUser("primed");
  ASSERT_TRUE(read.ok()) << read.status();
  EXPECT_EQ(read->config.prior.pool_version, *second);
  EXPECT_EQ(read->config.prior.rounds, 12.5);
  EXPECT_EQ(read->config.prior.theta0, user.config.prior.theta0);
  EXPECT_EQ(read->config.prior.phi0, user.config.prior.phi0);
  // A user without one reads back without one.
  ASSERT_TRUE(store_->CreateUser(MakeUser("plain")).ok());
  EXPECT_FALSE(store_->GetUser("plain")->config.prior.enabled());
  // A tampered prior is data loss, not a silently different model.
  Raw().Exec(absl::StrCat("UPDATE users SET prior = ", BlobLiteral("0102"),
                          " WHERE user_id = 'primed'"));
  EXPECT_EQ(store_->GetUser("primed").status().code(),
            absl::StatusCode::kDataLoss);
}

TEST_P(PoolsAuditContractTest, AuditEntriesAreKeptAndPaged) {
  for (int i = 0; i < 3; ++i) {
    AuditEntry entry;
    entry.time = absl::FromUnixSeconds(1700000000 + i);
    entry.method = "BanditService/DeleteUser";
    entry.target = absl::StrCat("user", i);
    entry.identity = "admin.lab";
    entry.role = "admin";
    entry.peer = "ipv4:10.0.0.2:5000";
    entry.result = i == 2 ? "NOT_FOUND" : "OK";
    auto id = store_->AppendAudit(entry);
    ASSERT_TRUE(id.ok()) << id.status();
    EXPECT_EQ(*id, i + 1);
  }
  Page page;
  page.page_size = 2;
  auto first = store_->ListAudit(page);
  ASSERT_TRUE(first.ok()) << first.status();
  ASSERT_EQ(first->items.size(), 2u);
  EXPECT_EQ(first->items[0].target, "user0");
  EXPECT_EQ(first->items[1].time, absl::FromUnixSeconds(1700000001));
  page.page_token = first->next_page_token;
  auto second = store_->ListAudit(page);
  ASSERT_TRUE(second.ok()) << second.status();
  ASSERT_EQ(second->items.size(), 1u);
  EXPECT_EQ(second->items[0].result, "NOT_FOUND");
  EXPECT_TRUE(second->next_page_token.empty());
  page.page_token = "bm90IGEgdG9rZW4";
  EXPECT_EQ(store_->ListAudit(page).status().code(),
            absl::StatusCode::kInvalidArgument);
}

TEST_P(PoolsAuditContractTest, CheckStoreReadsEverythingAndNamesWhatIsWrong) {
  ASSERT_TRUE(store_->CreateUser(MakeUser("alice")).ok());
  ASSERT_TRUE(store_->CreateUser(MakeUser("bob")).ok());
  const int64_t a = MustAppend(MakeEvent("alice", "m"));
  MustAppend(MakeEvent("bob", "m"));
  auto clean = store_->CheckStore();
  ASSERT_TRUE(clean.ok()) << clean.status();
  EXPECT_TRUE(clean->findings.empty());
  EXPECT_EQ(clean->users_checked, 2);
  EXPECT_EQ(clean->events_checked, 2);

  RawSql& raw = Raw();
  raw.Exec(
      absl::StrCat("UPDATE events SET item_label = 'grape' WHERE "
                   "event_id = ",
                   a));
  raw.Exec("DELETE FROM user_actions WHERE user_id = 'bob' AND action = 0");
  auto damaged = store_->CheckStore();
  ASSERT_TRUE(damaged.ok()) << damaged.status();
  ASSERT_EQ(damaged->findings.size(), 2u);
  EXPECT_THAT(damaged->findings[0], HasSubstr("bob"));
  EXPECT_THAT(damaged->findings[1],
              HasSubstr(absl::StrCat("event ", a, " of user \"alice\"")));
}

// The child tables are the truth: a missing name is DATA_LOSS naming the
// user, not a shorter action list.
TEST_P(PoolsAuditContractTest, MissingActionNameIsDataLoss) {
  ASSERT_TRUE(store_->CreateUser(MakeUser("alice")).ok());
  Raw().Exec("DELETE FROM user_actions WHERE action = 2");
  auto user = store_->GetUser("alice");
  EXPECT_EQ(user.status().code(), absl::StatusCode::kDataLoss);
  EXPECT_THAT(user.status().message(), HasSubstr("alice"));
  EXPECT_THAT(user.status().message(), HasSubstr("action 2"));
}

}  // namespace
}  // namespace bitewise::bandit::store_test
