// What only the PostgreSQL store has: its schema checks, replicas' writes
// at a position, a server that stops and returns; and store locations.
#include "services/bandit/store/pg_helpers.h"
#include "services/bandit/store/write_faults.h"
#include "services/common/status_macros.h"
#include "tests/bandit/store/store_test_fixture.h"

namespace bitewise::bandit::store_test {
namespace {

TEST_F(PostgresEventStoreTest, OtherTablesOrVersionsOrNoStoreAreRefused) {
  const std::string info = conninfo_;
  // A database of other tables of the same names is not ours to add to.
  ASSERT_TRUE(server_->CreateDatabase(database_ + "_other").ok());
  ASSERT_TRUE(server_
                  ->Query(database_ + "_other",
                          "CREATE TABLE users (name text); INSERT INTO users "
                          "VALUES ('someone')")
                  .ok());
  PostgresStoreOptions options;
  options.conninfo = server_->ConnInfo(database_ + "_other");
  auto foreign = PostgresEventStore::Open(options);
  EXPECT_EQ(foreign.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(foreign.status().message(),
              HasSubstr(absl::StrCat("database \"", database_, "_other\"")));
  EXPECT_EQ(*server_->Query(database_ + "_other",
                            "SELECT to_regclass('events') IS NULL"),
            "t");  // untouched
  // An empty database becomes a store only when asked for.
  ASSERT_TRUE(server_->CreateDatabase(database_ + "_empty").ok());
  options.conninfo = server_->ConnInfo(database_ + "_empty");
  options.create_if_missing = false;
  auto empty = PostgresEventStore::Open(options);
  EXPECT_EQ(empty.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(empty.status().message(), HasSubstr("--create"));
  // A newer schema is refused by version.
  Raw().Exec("UPDATE bitewise_store SET schema_version = 99");
  options.conninfo = info;
  auto newer = PostgresEventStore::Open(options);
  EXPECT_EQ(newer.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(newer.status().message(), HasSubstr("version 99"));
  // Nothing listens there: UNAVAILABLE naming where it looked.
  options.conninfo = absl::StrCat("postgresql:///nothing?host=", dir_,
                                  "&port=1&connect_timeout=2");
  auto absent = PostgresEventStore::Open(options);
  EXPECT_EQ(absent.status().code(), absl::StatusCode::kUnavailable);
  EXPECT_THAT(absent.status().message(), HasSubstr("database \"nothing\""));
  for (const char* suffix : {"_other", "_empty"}) {
    server_
        ->Query("postgres", absl::StrCat("DROP DATABASE ", database_, suffix))
        .IgnoreError();
  }
}

TEST_F(PostgresEventStoreTest, TwoStoresOnOneDatabaseOrderEachUsersWrites) {
  // Two processes' stores (their own connections) completing the same
  // users' events at once: every completion gets its own model_version.
  auto other = OpenStore();
  ASSERT_NE(other, nullptr);
  constexpr int kUsers = 3;
  constexpr int kRounds = 30;
  for (int u = 0; u < kUsers; ++u) {
    ASSERT_TRUE(store_->CreateUser(MakeUser(absl::StrCat("u", u))).ok());
  }
  std::atomic<int> failures{0};
  std::vector<std::thread> threads;
  for (EventStore* store : {store_.get(), other.get()}) {
    for (int u = 0; u < kUsers; ++u) {
      threads.emplace_back([&, store, u] {
        for (int i = 0; i < kRounds; ++i) {
          auto id =
              store->AppendPending(MakeEvent(absl::StrCat("u", u), "m", i));
          if (!id.ok() || !store
                               ->CompleteEvent(*id, 0.0, {1.0, 2.0}, 1.0,
                                               absl::FromUnixMicros(1))
                               .ok()) {
            ++failures;
          }
        }
      });
    }
  }
  for (std::thread& thread : threads) thread.join();
  EXPECT_EQ(failures.load(), 0);
  for (int u = 0; u < kUsers; ++u) {
    auto log = other->CompletedEvents(absl::StrCat("u", u));
    ASSERT_TRUE(log.ok()) << log.status();
    ASSERT_EQ(log->size(), size_t{2 * kRounds});
    for (size_t k = 0; k < log->size(); ++k) {
      EXPECT_EQ((*log)[k].model_version, static_cast<int64_t>(k) + 1);
    }
    EXPECT_EQ(MustGetUser(absl::StrCat("u", u)).model_version, 2 * kRounds);
  }
}

TEST_F(PostgresEventStoreTest, WritesAtAPositionAreRefusedOnceTheLogMoved) {
  // What replicas write with: each write only where the caller read the
  // log, else ABORTED naming the user, with nothing written.
  auto other = OpenStore();
  ASSERT_NE(other, nullptr);
  ASSERT_TRUE(store_->CreateUser(MakeUser("alice")).ok());
  auto at = store_->LogPosition("alice");
  ASSERT_TRUE(at.ok()) << at.status();
  EXPECT_EQ(at->model_version, 0);
  EXPECT_EQ(at->pending_events, 0);
  auto first = store_->AppendPendingAt(MakeEvent("alice", "m", 0), *at);
  ASSERT_TRUE(first.ok()) << first.status();
  // The other store appends and completes from the same, now stale, read.
  auto stale = other->AppendPendingAt(MakeEvent("alice", "m", 1), *at);
  EXPECT_EQ(stale.status().code(), absl::StatusCode::kAborted);
  EXPECT_THAT(stale.status().message(), HasSubstr("\"alice\""));
  EXPECT_EQ(other
                ->CompleteEventAt("alice", *first, 0.0, {1.0, 2.0}, 1.0,
                                  absl::FromUnixMicros(1),
                                  UserLogPosition{1, 0, at->incarnation})
                .status()
                .code(),
            absl::StatusCode::kAborted);
  EXPECT_EQ(MustGetUser("alice").pending_events, 1);
  EXPECT_EQ(MustGetUser("alice").model_version, 0);
  // From a fresh read both go through, and the position follows.
  at = other->LogPosition("alice");
  ASSERT_TRUE(at.ok()) << at.status();
  EXPECT_EQ(at->pending_events, 1);
  auto done = other->CompleteEventAt("alice", *first, 0.0, {1.0, 2.0}, 1.0,
                                     absl::FromUnixMicros(1), *at);
  ASSERT_TRUE(done.ok()) << done.status();
  EXPECT_EQ(done->model_version, 1);
  EXPECT_EQ(done->context, MakeEvent("alice", "m", 0).context);
  // Completed already, unknown, or another user's: as CompleteEvent says.
  at = store_->LogPosition("alice");
  auto complete_as_alice = [&](int64_t event_id) {
    return store_
        ->CompleteEventAt("alice", event_id, 0.0, {1.0, 2.0}, 1.0,
                          absl::FromUnixMicros(1), *at)
        .status()
        .code();
  };
  EXPECT_EQ(complete_as_alice(*first), absl::StatusCode::kFailedPrecondition);
  EXPECT_EQ(complete_as_alice(999999), absl::StatusCode::kNotFound);
  ASSERT_TRUE(store_->CreateUser(MakeUser("bob")).ok());
  auto bobs = store_->AppendPending(MakeEvent("bob", "m", 0));
  ASSERT_TRUE(bobs.ok());
  EXPECT_EQ(complete_as_alice(*bobs), absl::StatusCode::kAborted);
  EXPECT_FALSE(store_->GetEvent(*bobs)->completed);
  // A reset starts a new incarnation: an older read no longer writes.
  ASSERT_TRUE(store_->ResetUser("alice").ok());
  EXPECT_EQ(other
                ->AppendPendingAt(MakeEvent("alice", "m", 2),
                                  UserLogPosition{0, 0, at->incarnation})
                .status()
                .code(),
            absl::StatusCode::kAborted);
  auto reset = other->LogPosition("alice");
  ASSERT_TRUE(reset.ok());
  EXPECT_NE(reset->incarnation, at->incarnation);
  EXPECT_EQ(reset->model_version + reset->pending_events, 0);
  EXPECT_EQ(other->AppendPendingAt(MakeEvent("nobody", "m", 0), *reset)
                .status()
                .code(),
            absl::StatusCode::kNotFound);
  EXPECT_EQ(other->LogPosition("nobody").status().code(),
            absl::StatusCode::kNotFound);
}

TEST_F(PostgresEventStoreTest, SchemaOneIsUpgradedAndCountsAreChecked) {
  // A store of schema 1 (before the selections count and poLinUCB's radius
  // per user): opening it adds the count from each user's log, drops the
  // lock function and gives every user the radius it had, the default.
  ASSERT_TRUE(store_->CreateUser(MakeUser("alice")).ok());
  ASSERT_TRUE(store_->CreateUser(MakeUser("bob")).ok());
  for (int i = 0; i < 3; ++i) {
    auto id = store_->AppendPending(MakeEvent("alice", "m", i));
    ASSERT_TRUE(id.ok());
    if (i < 2) {
      ASSERT_TRUE(store_
                      ->CompleteEvent(*id, 0.0, {1.0, 2.0}, 1.0,
                                      absl::FromUnixMicros(1))
                      .ok());
    }
  }
  store_.reset();
  Raw().Exec(
      "ALTER TABLE users DROP COLUMN selections, DROP COLUMN phi_radius; "
      "CREATE FUNCTION "
      "bitewise_enter_user(lock_key bigint, id text) RETURNS void LANGUAGE "
      "sql AS 'SELECT 1'; UPDATE bitewise_store SET schema_version = 1");
  store_ = OpenStore();
  ASSERT_NE(store_, nullptr);
  EXPECT_EQ(*server_->Query(database_,
                            "SELECT string_agg(user_id || '=' || selections, "
                            "',' ORDER BY user_id) FROM users"),
            "alice=3,bob=0");
  EXPECT_EQ(*server_->Query(database_,
                            "SELECT schema_version || ' ' || "
                            "(to_regproc('bitewise_enter_user') IS NULL) FROM "
                            "bitewise_store"),
            "3 true");
  EXPECT_EQ(*server_->Query(database_,
                            "SELECT string_agg(user_id || '=' || phi_radius, "
                            "',' ORDER BY user_id) FROM users"),
            "alice=0.1,bob=0.1");
  EXPECT_EQ(MustGetUser("alice").config.phi_radius, 0.1);
  auto clean = store_->CheckStore();
  ASSERT_TRUE(clean.ok()) << clean.status();
  EXPECT_THAT(clean->findings, IsEmpty());
  // A count that disagrees with the log is a finding naming the user.
  Raw().Exec("UPDATE users SET selections = 7 WHERE user_id = 'bob'");
  auto damaged = store_->CheckStore();
  ASSERT_TRUE(damaged.ok()) << damaged.status();
  ASSERT_EQ(damaged->findings.size(), 1u);
  EXPECT_THAT(damaged->findings[0], HasSubstr("\"bob\" counts 7 selections"));
}

// A server of the test's own (to stop or restart) with a database
// "facility", the store options for it, and a store open on it.
struct OwnServer {
  std::unique_ptr<testing::TestPostgres> server;
  PostgresStoreOptions options;
  std::unique_ptr<PostgresEventStore> store;
};

absl::StatusOr<OwnServer> StartOwnServer(
    absl::Duration response_timeout = absl::Seconds(30)) {
  OwnServer own;
  ASSIGN_OR_RETURN(own.server, testing::TestPostgres::Create());
  ASSIGN_OR_RETURN(own.options.conninfo,
                   own.server->CreateDatabase("facility"));
  own.options.connections = 2;
  own.options.response_timeout = response_timeout;
  ASSIGN_OR_RETURN(own.store, PostgresEventStore::Open(own.options));
  return own;
}

TEST_F(PostgresEventStoreTest, AStoppedServerIsUnavailableAndTheStoreRecovers) {
  absl::StatusOr<OwnServer> own = StartOwnServer();
  ASSERT_TRUE(own.ok()) << own.status();
  testing::TestPostgres& server = *own->server;
  PostgresEventStore& store = *own->store;
  ASSERT_TRUE(store.CreateUser(MakeUser("alice")).ok());
  auto first = store.AppendPending(MakeEvent("alice", "m"));
  ASSERT_TRUE(first.ok());
  ASSERT_TRUE(
      store.CompleteEvent(*first, 0.5, {1.0, 2.0}, 1.0, absl::FromUnixMicros(1))
          .ok());
  EXPECT_TRUE(store.CheckHealth().ok());

  ASSERT_TRUE(server.Stop().ok());
  for (int attempt = 0; attempt < 3; ++attempt) {  // every pooled connection
    auto down = store.AppendPending(MakeEvent("alice", "m"));
    EXPECT_EQ(down.status().code(), absl::StatusCode::kUnavailable);
    EXPECT_THAT(down.status().message(), HasSubstr("database \"facility\""));
  }
  const absl::Status health = store.CheckHealth();
  EXPECT_EQ(health.code(), absl::StatusCode::kUnavailable);
  EXPECT_THAT(health.message(), HasSubstr("database \"facility\""));

  // Back, with the same store object: no restart of the service.
  ASSERT_TRUE(server.Start().ok());
  EXPECT_TRUE(store.CheckHealth().ok()) << store.CheckHealth();
  auto second = store.AppendPending(MakeEvent("alice", "m"));
  ASSERT_TRUE(second.ok()) << second.status();
  auto done = store.CompleteEvent(*second, 1.0, {1.0, 2.0}, 1.0,
                                  absl::FromUnixMicros(2));
  ASSERT_TRUE(done.ok()) << done.status();
  EXPECT_EQ(done->model_version, 2);  // the first one was kept
  auto user = store.GetUser("alice");
  ASSERT_TRUE(user.ok()) << user.status();
  EXPECT_EQ(user->model_version, 2);
}

// A server that stops answering (its process stopped: the kernel still
// takes the bytes) used to hang every call and keep health SERVING.
TEST_F(PostgresEventStoreTest, AFrozenServerFailsCallsAndHealthThenRecovers) {
  absl::StatusOr<OwnServer> own = StartOwnServer(absl::Seconds(1));
  ASSERT_TRUE(own.ok()) << own.status();
  PostgresEventStore& store = *own->store;
  ASSERT_TRUE(store.CreateUser(MakeUser("alice")).ok());
  ASSERT_TRUE(store.AppendPending(MakeEvent("alice", "m")).ok());
  EXPECT_TRUE(store.CheckHealth().ok());
  {
    auto frozen = own->server->Freeze();
    ASSERT_TRUE(frozen.ok()) << frozen.status();
    // A Select's one statement commits by itself: sent and not answered,
    // it may have been applied, and the error says so.
    const absl::Time start = absl::Now();
    auto hung = store.AppendPending(MakeEvent("alice", "m"));
    EXPECT_LT(absl::Now() - start, absl::Seconds(20));  // a bound, not speed
    EXPECT_EQ(hung.status().code(), absl::StatusCode::kUnavailable);
    EXPECT_TRUE(IsStorageFault(hung.status()));
    EXPECT_THAT(
        hung.status().message(),
        ::testing::AllOf(HasSubstr("database \"facility\""),
                         HasSubstr("did not answer within 1s (AppendPending)"),
                         HasSubstr("the outcome is unknown: it may have been "
                                   "applied. Retrying is safe: a Select")));
    const absl::Status health = store.CheckHealth();
    EXPECT_EQ(health.code(), absl::StatusCode::kUnavailable);
    EXPECT_THAT(
        health.message(),
        ::testing::AllOf(HasSubstr("database \"facility\""),
                         HasSubstr("did not answer within 1s (health check)")));
  }
  // Going on: the same store serves again, and the Select that was never
  // answered was applied after all (hence "unknown").
  absl::Status health = store.CheckHealth();
  if (absl::IsUnavailable(health)) health = store.CheckHealth();
  EXPECT_TRUE(health.ok()) << health;
  auto after = store.AppendPending(MakeEvent("alice", "m"));
  ASSERT_TRUE(after.ok()) << after.status();
  int64_t pending = 0;
  const absl::Time deadline = absl::Now() + absl::Seconds(20);
  while (absl::Now() < deadline) {
    auto user = store.GetUser("alice");
    ASSERT_TRUE(user.ok()) << user.status();
    pending = user->pending_events;
    if (pending == 3) break;
    absl::SleepFor(absl::Milliseconds(50));
  }
  EXPECT_EQ(pending, 3);
}

// A lock another connection holds (another replica's transaction, a
// person's psql) is waited for up to half the response timeout, then the
// call fails as contention: UNAVAILABLE, no storage fault, health still
// SERVING (before, the wait ran into the response timeout and was taken for
// a server that stopped answering).
TEST_F(PostgresEventStoreTest, ALockHeldElsewhereIsContentionNotAFault) {
  absl::StatusOr<OwnServer> own = StartOwnServer(absl::Seconds(2));
  ASSERT_TRUE(own.ok()) << own.status();
  PostgresEventStore& store = *own->store;
  ASSERT_TRUE(store.CreateUser(MakeUser("alice")).ok());
  auto holder = pg::Connection::Open(own->options.conninfo);
  ASSERT_TRUE(holder.ok()) << holder.status();
  ASSERT_TRUE((*holder)
                  ->ExecScript("BEGIN; SELECT 1 FROM users WHERE user_id = "
                               "'alice' FOR UPDATE",
                               "holding alice's row")
                  .ok());
  const absl::Time start = absl::Now();
  auto waited = store.AppendPending(MakeEvent("alice", "m"));
  EXPECT_LT(absl::Now() - start, absl::Seconds(20));  // a bound, not speed
  EXPECT_EQ(waited.status().code(), absl::StatusCode::kUnavailable)
      << waited.status();
  EXPECT_FALSE(IsStorageFault(waited.status())) << waited.status();
  EXPECT_THAT(waited.status().message(), HasSubstr("55P03"));
  EXPECT_TRUE(store.CheckHealth().ok()) << store.CheckHealth();
  ASSERT_TRUE((*holder)->ExecScript("ROLLBACK", "letting go").ok());
  EXPECT_TRUE(store.AppendPending(MakeEvent("alice", "m")).ok());
}

// fsync off is refused at open, and found by the health check when the
// server comes back with it under a running store (before, only the open
// looked: the store went on acknowledging updates a power loss would lose).
TEST_F(PostgresEventStoreTest, FsyncOffIsRefusedAtOpenAndDropsHealthLater) {
  absl::StatusOr<OwnServer> own = StartOwnServer();
  ASSERT_TRUE(own.ok()) << own.status();
  testing::TestPostgres& server = *own->server;
  const PostgresStoreOptions& options = own->options;
  PostgresEventStore& store = *own->store;
  EXPECT_TRUE(store.CheckHealth().ok());
  // The server restarted with fsync off under the running store (a
  // setting a reload can change too).
  ASSERT_TRUE(server.Stop().ok());
  ASSERT_TRUE(server.Start({"fsync=off"}).ok());
  // The first check may find its connection gone with the old server (as
  // the service's monitor, polling every 0.5 s, would); the next reconnects.
  absl::Status health = store.CheckHealth();
  if (absl::IsUnavailable(health)) health = store.CheckHealth();
  EXPECT_EQ(health.code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(health.message(), HasSubstr("runs with fsync off"));
  auto refused = PostgresEventStore::Open(options);
  EXPECT_EQ(refused.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(refused.status().message(), HasSubstr("runs with fsync off"));
  ASSERT_TRUE(server.Stop().ok());
  ASSERT_TRUE(server.Start().ok());
  health = store.CheckHealth();
  if (absl::IsUnavailable(health)) health = store.CheckHealth();
  EXPECT_TRUE(health.ok()) << health;
}

TEST(OpenStoreTest, LoggedLocationsHideThePassword) {
  EXPECT_EQ(DescribeStoreSpec("postgresql://bw:secret@db:5432/bitewise"),
            "postgresql://bw:***@db:5432/bitewise");
  EXPECT_EQ(DescribeStoreSpec("postgres://db/bitewise?password=secret&"
                              "sslmode=verify-full"),
            "postgres://db/bitewise?password=***&sslmode=verify-full");
  EXPECT_EQ(DescribeStoreSpec("postgresql://bw@db/bitewise"),
            "postgresql://bw@db/bitewise");
  EXPECT_EQ(DescribeStoreSpec("sqlite:/var/lib/bitewise/bandit.db"),
            "sqlite:/var/lib/bitewise/bandit.db");
  EXPECT_TRUE(IsPostgresSpec("postgres://db/x"));
  EXPECT_FALSE(IsPostgresSpec("bandit.db"));
}

}  // namespace
}  // namespace bitewise::bandit::store_test
