// Tests of the EventStore contract, run against both stores: real SQLite
// files in a temporary directory, and databases on a real PostgreSQL server
// the test starts itself (tests/common/postgres_server.h). Then what only
// one store has: SQLite's file, lock and migrations, PostgreSQL's schema
// checks and a server that stops and returns. Tampering (a corrupt vector,
// an injected failure) goes through a second, raw connection.
#include <signal.h>
#include <sqlite3.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <memory>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/time/time.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "services/bandit/store/open_store.h"
#include "services/bandit/store/postgres_event_store.h"
#include "services/bandit/store/sqlite_event_store.h"
#include "tests/common/postgres_server.h"

namespace bitewise::bandit {
namespace {

using ::testing::ElementsAre;
using ::testing::HasSubstr;
using ::testing::IsEmpty;

std::vector<uint64_t> Bits(const std::vector<double>& values) {
  std::vector<uint64_t> bits(values.size());
  std::memcpy(bits.data(), values.data(), values.size() * sizeof(double));
  return bits;
}

uint64_t Bits(double value) { return Bits(std::vector<double>{value})[0]; }

double FromBits(uint64_t bits) {
  double value;
  std::memcpy(&value, &bits, sizeof(value));
  return value;
}

// A second connection to the same file, as another process would have.
class RawDb {
 public:
  explicit RawDb(const std::string& path) {
    EXPECT_EQ(sqlite3_open(path.c_str(), &db_), SQLITE_OK);
  }
  ~RawDb() { sqlite3_close(db_); }

  void Exec(const std::string& sql) {
    char* error = nullptr;
    const int rc = sqlite3_exec(db_, sql.c_str(), nullptr, nullptr, &error);
    EXPECT_EQ(rc, SQLITE_OK) << sql << ": " << (error ? error : "");
    sqlite3_free(error);
  }

  std::string Text(const std::string& sql) {
    sqlite3_stmt* stmt = nullptr;
    EXPECT_EQ(sqlite3_prepare_v2(db_, sql.c_str(), -1, &stmt, nullptr),
              SQLITE_OK)
        << sqlite3_errmsg(db_);
    std::string result;
    if (sqlite3_step(stmt) == SQLITE_ROW) {
      const auto* text =
          reinterpret_cast<const char*>(sqlite3_column_text(stmt, 0));
      result = text ? text : "";
    }
    sqlite3_finalize(stmt);
    return result;
  }

 private:
  sqlite3* db_ = nullptr;
};

BanditConfig SmallConfig() {
  BanditConfig config;
  config.context_dim = 3;
  config.posthoc_dim = 2;
  return config;
}

UserRecord MakeUser(const std::string& user_id) {
  UserRecord user;
  user.user_id = user_id;
  user.config = SmallConfig();
  user.created_at = absl::FromUnixMicros(1700000000123456);
  return user;
}

EventRecord MakeEvent(const std::string& user_id, const std::string& meal_id,
                      double x = 0.5) {
  EventRecord event;
  event.user_id = user_id;
  event.meal_id = meal_id;
  event.item_label = "carrot";
  event.context = {x, 1.0, -2.0};
  event.action = 2;
  event.propensity = 0.25;
  event.selected_at = absl::FromUnixMicros(1700000001000001);
  return event;
}

// SQLite as shipped (contexts of 4 KB and more in the contexts file, the
// tests' small ones in the database), SQLite with every context in the
// contexts file, and PostgreSQL.
enum class Backend { kSqlite, kSqliteContextFile, kPostgres };

std::string BackendName(const ::testing::TestParamInfo<Backend>& info) {
  switch (info.param) {
    case Backend::kSqlite:
      return "Sqlite";
    case Backend::kSqliteContextFile:
      return "SqliteContextFile";
    case Backend::kPostgres:
      break;
  }
  return "Postgres";
}

// The store's tables as another process (or an administrator's shell)
// sees them: for tampering and inspection.
class RawSql {
 public:
  virtual ~RawSql() = default;
  virtual void Exec(const std::string& sql) = 0;
  // The first column of the first row ("" if none).
  virtual std::string Text(const std::string& sql) = 0;
};

class SqliteRaw final : public RawSql {
 public:
  explicit SqliteRaw(const std::string& path) : db_(path) {}
  void Exec(const std::string& sql) override { db_.Exec(sql); }
  std::string Text(const std::string& sql) override { return db_.Text(sql); }

 private:
  RawDb db_;
};

class PostgresRaw final : public RawSql {
 public:
  PostgresRaw(testing::TestPostgres* server, std::string database)
      : server_(server), database_(std::move(database)) {}
  void Exec(const std::string& sql) override {
    absl::StatusOr<std::string> done = server_->Query(database_, sql);
    EXPECT_TRUE(done.ok()) << done.status();
  }
  std::string Text(const std::string& sql) override {
    absl::StatusOr<std::string> value = server_->Query(database_, sql);
    EXPECT_TRUE(value.ok()) << value.status();
    return value.ok() ? *value : "";
  }

 private:
  testing::TestPostgres* const server_;
  const std::string database_;
};

// What every store test has: a fresh store of its backend (a SQLite file
// in a temporary directory, or a new database on the test's PostgreSQL
// server), raw access to its tables, and helpers.
class StoreTestBase : public ::testing::Test {
 protected:
  virtual Backend backend() const = 0;
  bool sqlite() const { return backend() != Backend::kPostgres; }

  void SetUp() override {
    std::string base = ::testing::TempDir();
    if (base.empty() || base.back() != '/') base += '/';
    std::string pattern = base + "bandit_store_XXXXXX";
    ASSERT_NE(mkdtemp(pattern.data()), nullptr) << pattern;
    dir_ = pattern;
    path_ = dir_ + "/bandit.db";
    if (backend() == Backend::kPostgres) {
      server_ = testing::SharedTestPostgres();
      ASSERT_NE(server_, nullptr);
      static int databases = 0;
      database_ = absl::StrCat("store_test_", ++databases);
      absl::StatusOr<std::string> conninfo = server_->CreateDatabase(database_);
      ASSERT_TRUE(conninfo.ok()) << conninfo.status();
      conninfo_ = *conninfo;
    }
    store_ = OpenStore();
    ASSERT_NE(store_, nullptr);
  }

  void TearDown() override {
    store_.reset();
    raw_.reset();
    std::filesystem::remove_all(dir_);
    if (server_ != nullptr) {
      server_->Query("postgres", absl::StrCat("DROP DATABASE ", database_))
          .IgnoreError();
    }
  }

  // A store on the test's file or database (synchronous_full: SQLite's).
  absl::StatusOr<std::unique_ptr<EventStore>> TryOpenStore(
      bool synchronous_full = true) {
    if (backend() == Backend::kPostgres) {
      PostgresStoreOptions options;
      options.conninfo = conninfo_;
      auto store = PostgresEventStore::Open(options);
      if (!store.ok()) return store.status();
      return std::unique_ptr<EventStore>(std::move(store).value());
    }
    SqliteStoreOptions options;
    options.path = path_;
    options.synchronous_full = synchronous_full;
    if (backend() == Backend::kSqliteContextFile) {
      options.context_file_min_bytes = 1;
    }
    auto store = SqliteEventStore::Open(options);
    if (!store.ok()) return store.status();
    return std::unique_ptr<EventStore>(std::move(store).value());
  }

  std::unique_ptr<EventStore> OpenStore(bool synchronous_full = true) {
    auto store = TryOpenStore(synchronous_full);
    EXPECT_TRUE(store.ok()) << store.status();
    return store.ok() ? std::move(store).value() : nullptr;
  }

  RawSql& Raw() {
    if (raw_ == nullptr) {
      if (backend() == Backend::kPostgres) {
        raw_ = std::make_unique<PostgresRaw>(server_, database_);
      } else {
        raw_ = std::make_unique<SqliteRaw>(path_);
      }
    }
    return *raw_;
  }

  // A literal of these bytes (hex) in the backend's SQL.
  std::string BlobLiteral(const std::string& hex) const {
    return backend() == Backend::kPostgres
               ? absl::StrCat("'\\x", hex, "'::bytea")
               : absl::StrCat("x'", hex, "'");
  }

  UserRecord MustGetUser(const std::string& user_id) {
    auto user = store_->GetUser(user_id);
    EXPECT_TRUE(user.ok()) << user.status();
    return user.ok() ? *user : UserRecord();
  }

  EventRecord MustGetEvent(int64_t event_id) {
    auto event = store_->GetEvent(event_id);
    EXPECT_TRUE(event.ok()) << event.status();
    return event.ok() ? *event : EventRecord();
  }

  int64_t MustAppend(const EventRecord& event) {
    auto id = store_->AppendPending(event);
    EXPECT_TRUE(id.ok()) << id.status();
    return id.ok() ? *id : 0;
  }

  EventRecord MustComplete(int64_t event_id, double loss = 1.0) {
    auto event = store_->CompleteEvent(event_id, loss, {0.1, 0.2}, 1.0,
                                       absl::FromUnixMicros(1700000002000000));
    EXPECT_TRUE(event.ok()) << event.status();
    return event.ok() ? *event : EventRecord();
  }

  std::string dir_;
  std::string path_;                         // SQLite
  testing::TestPostgres* server_ = nullptr;  // PostgreSQL
  std::string database_;
  std::string conninfo_;
  std::unique_ptr<EventStore> store_;
  std::unique_ptr<RawSql> raw_;
};

// The EventStore contract, on both stores.
class EventStoreTest : public StoreTestBase,
                       public ::testing::WithParamInterface<Backend> {
 protected:
  Backend backend() const override { return GetParam(); }
};

INSTANTIATE_TEST_SUITE_P(Stores, EventStoreTest,
                         ::testing::Values(Backend::kSqlite,
                                           Backend::kSqliteContextFile,
                                           Backend::kPostgres),
                         BackendName);

// What only the SQLite store has: its file, its lock, its migrations.
class SqliteEventStoreTest : public StoreTestBase {
 protected:
  Backend backend() const override { return Backend::kSqlite; }
};

TEST_P(EventStoreTest, CreateAndGetUserRoundTripsConfig) {
  UserRecord user = MakeUser("alice");
  BanditConfig& c = user.config;
  c.learner = Learner::kContextOnly;
  c.strategy = Strategy::kThompson;
  c.alpha = 0.1 + 0.2;
  c.lambda_c = std::numeric_limits<double>::denorm_min();
  c.lambda_p = 1e300;
  c.epsilon = -0.0;
  c.importance_weighting = true;
  c.context_dim = 7;
  c.posthoc_dim = 0;
  // Every character a naive separator or quoting scheme would trip over.
  c.action_names = {
      "a,b",      "quote\"d",          "back\\slash", "tab\tnew\nline",
      "\x01\x1f", "\xc3\xbcn\xc3\xaf", "[\"]",        "x\x7f;|"};
  c.seed = std::numeric_limits<uint64_t>::max();
  user.model_version = 42;  // ignored: a new user has no events
  ASSERT_TRUE(store_->CreateUser(user).ok());

  const UserRecord got = MustGetUser("alice");
  EXPECT_EQ(got.user_id, "alice");
  EXPECT_EQ(got.config.learner, Learner::kContextOnly);
  EXPECT_EQ(got.config.strategy, Strategy::kThompson);
  EXPECT_EQ(Bits(got.config.alpha), Bits(c.alpha));
  EXPECT_EQ(Bits(got.config.lambda_c), Bits(c.lambda_c));
  EXPECT_EQ(Bits(got.config.lambda_p), Bits(c.lambda_p));
  EXPECT_EQ(Bits(got.config.epsilon), Bits(-0.0));
  EXPECT_TRUE(got.config.importance_weighting);
  EXPECT_EQ(got.config.context_dim, 7);
  EXPECT_EQ(got.config.posthoc_dim, 0);
  EXPECT_EQ(got.config.action_names, c.action_names);
  EXPECT_EQ(got.config.seed, std::numeric_limits<uint64_t>::max());
  EXPECT_EQ(got.created_at, user.created_at);
  EXPECT_EQ(got.model_version, 0);
  EXPECT_EQ(got.pending_events, 0);
}

TEST_P(EventStoreTest, DuplicateUserIsAlreadyExistsAndKeepsOriginal) {
  ASSERT_TRUE(store_->CreateUser(MakeUser("alice")).ok());
  UserRecord again = MakeUser("alice");
  again.config.alpha = 5.0;
  const absl::Status status = store_->CreateUser(again);
  EXPECT_EQ(status.code(), absl::StatusCode::kAlreadyExists) << status;
  EXPECT_THAT(status.message(), HasSubstr("alice"));
  EXPECT_EQ(MustGetUser("alice").config.alpha, SmallConfig().alpha);
}

TEST_P(EventStoreTest, CreateUserRejectsInvalidInput) {
  EXPECT_EQ(store_->CreateUser(MakeUser("")).code(),
            absl::StatusCode::kInvalidArgument);
  UserRecord bad = MakeUser("bob");
  bad.config.context_dim = 0;
  EXPECT_EQ(store_->CreateUser(bad).code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(store_->GetUser("bob").status().code(),
            absl::StatusCode::kNotFound);
}

TEST_P(EventStoreTest, UnknownUserIsNotFoundEverywhere) {
  EXPECT_EQ(store_->GetUser("nobody").status().code(),
            absl::StatusCode::kNotFound);
  EXPECT_EQ(store_->DeleteUser("nobody").code(), absl::StatusCode::kNotFound);
  EXPECT_EQ(store_->ResetUser("nobody").code(), absl::StatusCode::kNotFound);
  const auto appended = store_->AppendPending(MakeEvent("nobody", "m"));
  EXPECT_EQ(appended.status().code(), absl::StatusCode::kNotFound);
  EXPECT_THAT(appended.status().message(), HasSubstr("nobody"));
  EXPECT_EQ(store_->ListEvents("nobody", "", Page()).status().code(),
            absl::StatusCode::kNotFound);
  EXPECT_EQ(store_->CompletedEvents("nobody").status().code(),
            absl::StatusCode::kNotFound);
}

TEST_P(EventStoreTest, ListUsersPagesInUserIdOrder) {
  for (const char* id : {"u3", "u0", "u6", "u1", "u5", "u2", "u4"}) {
    ASSERT_TRUE(store_->CreateUser(MakeUser(id)).ok());
  }
  std::vector<std::string> seen;
  std::vector<size_t> page_sizes;
  Page page;
  page.page_size = 3;
  while (true) {
    auto result = store_->ListUsers(page);
    ASSERT_TRUE(result.ok()) << result.status();
    page_sizes.push_back(result->items.size());
    for (const UserRecord& user : result->items) seen.push_back(user.user_id);
    if (result->next_page_token.empty()) break;
    page.page_token = result->next_page_token;
  }
  EXPECT_THAT(page_sizes, ElementsAre(3, 3, 1));
  EXPECT_THAT(seen, ElementsAre("u0", "u1", "u2", "u3", "u4", "u5", "u6"));

  for (int size : {0, -5}) {
    Page defaults;
    defaults.page_size = size;
    auto all = store_->ListUsers(defaults);
    ASSERT_TRUE(all.ok()) << all.status();
    EXPECT_EQ(all->items.size(), 7u);
    EXPECT_THAT(all->next_page_token, IsEmpty());
  }
}

TEST_P(EventStoreTest, ListUsersExactPageHasNoNextToken) {
  for (const char* id : {"a", "b"}) {
    ASSERT_TRUE(store_->CreateUser(MakeUser(id)).ok());
  }
  Page page;
  page.page_size = 2;
  auto result = store_->ListUsers(page);
  ASSERT_TRUE(result.ok()) << result.status();
  EXPECT_EQ(result->items.size(), 2u);
  EXPECT_THAT(result->next_page_token, IsEmpty());
}

TEST_P(EventStoreTest, ListUsersClampsPageSizeTo1000) {
  // Many commits: skip the per-commit fsync, which this test is not about.
  store_.reset();
  store_ = OpenStore(/*synchronous_full=*/false);
  for (int i = 0; i < 1001; ++i) {
    ASSERT_TRUE(store_->CreateUser(MakeUser(absl::StrCat("user", i))).ok());
  }
  Page page;
  page.page_size = 5000;
  auto first = store_->ListUsers(page);
  ASSERT_TRUE(first.ok()) << first.status();
  EXPECT_EQ(first->items.size(), 1000u);
  ASSERT_FALSE(first->next_page_token.empty());
  page.page_token = first->next_page_token;
  auto second = store_->ListUsers(page);
  ASSERT_TRUE(second.ok()) << second.status();
  EXPECT_EQ(second->items.size(), 1u);
  EXPECT_THAT(second->next_page_token, IsEmpty());
}

TEST_P(EventStoreTest, InvalidPageTokensAreInvalidArgument) {
  ASSERT_TRUE(store_->CreateUser(MakeUser("alice")).ok());
  ASSERT_TRUE(store_->CreateUser(MakeUser("bob")).ok());
  for (int i = 0; i < 3; ++i) MustAppend(MakeEvent("alice", "m"));

  Page one;
  one.page_size = 1;
  auto users = store_->ListUsers(one);
  ASSERT_TRUE(users.ok());
  const std::string user_token = users->next_page_token;
  auto events = store_->ListEvents("alice", "", one);
  ASSERT_TRUE(events.ok());
  const std::string event_token = events->next_page_token;
  ASSERT_FALSE(user_token.empty());
  ASSERT_FALSE(event_token.empty());

  for (const std::string& token :
       {std::string("not a token!"), std::string("AAAA"), event_token}) {
    Page page;
    page.page_token = token;
    EXPECT_EQ(store_->ListUsers(page).status().code(),
              absl::StatusCode::kInvalidArgument)
        << token;
  }
  for (const std::string& token :
       {std::string("not a token!"), std::string("AAAA"), user_token}) {
    Page page;
    page.page_token = token;
    EXPECT_EQ(store_->ListEvents("alice", "", page).status().code(),
              absl::StatusCode::kInvalidArgument)
        << token;
  }
}

TEST_P(EventStoreTest, AppendAndCompleteEvent) {
  ASSERT_TRUE(store_->CreateUser(MakeUser("alice")).ok());
  const EventRecord event = MakeEvent("alice", "meal1");
  const int64_t id = MustAppend(event);
  const int64_t id2 = MustAppend(MakeEvent("alice", "meal1"));
  EXPECT_GT(id, 0);
  EXPECT_GT(id2, id);

  const EventRecord pending = MustGetEvent(id);
  EXPECT_EQ(pending.event_id, id);
  EXPECT_EQ(pending.user_id, "alice");
  EXPECT_EQ(pending.meal_id, "meal1");
  EXPECT_EQ(pending.item_label, "carrot");
  EXPECT_EQ(pending.context, event.context);
  EXPECT_EQ(pending.action, 2);
  EXPECT_EQ(pending.propensity, 0.25);
  EXPECT_EQ(pending.selected_at, event.selected_at);
  EXPECT_FALSE(pending.completed);
  EXPECT_EQ(pending.model_version, 0);
  EXPECT_THAT(pending.posthoc, IsEmpty());
  EXPECT_EQ(MustGetUser("alice").pending_events, 2);

  const absl::Time updated_at = absl::FromUnixMicros(1700000009000007);
  auto completed =
      store_->CompleteEvent(id, 0.75, {3.0, -4.0}, 2.5, updated_at);
  ASSERT_TRUE(completed.ok()) << completed.status();
  EXPECT_EQ(completed->event_id, id);
  EXPECT_TRUE(completed->completed);
  EXPECT_EQ(completed->loss, 0.75);
  EXPECT_THAT(completed->posthoc, ElementsAre(3.0, -4.0));
  EXPECT_EQ(completed->weight, 2.5);
  EXPECT_EQ(completed->model_version, 1);
  EXPECT_EQ(completed->updated_at, updated_at);
  EXPECT_EQ(completed->context, event.context);

  const EventRecord stored = MustGetEvent(id);
  EXPECT_TRUE(stored.completed);
  EXPECT_EQ(stored.loss, 0.75);
  EXPECT_THAT(stored.posthoc, ElementsAre(3.0, -4.0));
  EXPECT_EQ(stored.weight, 2.5);
  EXPECT_EQ(stored.model_version, 1);
  EXPECT_EQ(stored.updated_at, updated_at);

  const UserRecord user = MustGetUser("alice");
  EXPECT_EQ(user.model_version, 1);
  EXPECT_EQ(user.pending_events, 1);
}

TEST_P(EventStoreTest, DoubleCompletionIsRejectedAndChangesNothing) {
  ASSERT_TRUE(store_->CreateUser(MakeUser("alice")).ok());
  const int64_t id = MustAppend(MakeEvent("alice", "m"));
  MustComplete(id, /*loss=*/1.0);

  auto again = store_->CompleteEvent(id, 9.0, {9.0, 9.0}, 9.0,
                                     absl::FromUnixMicros(1800000000000000));
  EXPECT_EQ(again.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_EQ(again.status().message(),
            absl::StrCat("event ", id, " is already completed"));

  EXPECT_EQ(MustGetUser("alice").model_version, 1);
  const EventRecord stored = MustGetEvent(id);
  EXPECT_EQ(stored.loss, 1.0);
  EXPECT_THAT(stored.posthoc, ElementsAre(0.1, 0.2));
  EXPECT_EQ(stored.model_version, 1);
}

// Concurrent writes are committed in groups: every acknowledged write is
// there once the store is reopened, writes that fail (an unknown user, an
// event completed twice, by two threads at once) fail alone and leave no
// trace, and each user's model_version counts exactly its completions.
TEST_P(EventStoreTest, ConcurrentWritesCommitInGroupsAndFailAlone) {
  constexpr int kThreads = 8;
  constexpr int kRounds = 40;
  for (int u = 0; u < kThreads; ++u) {
    ASSERT_TRUE(store_->CreateUser(MakeUser(absl::StrCat("user", u))).ok());
  }
  // Events that two threads complete at the same time: one wins.
  std::vector<int64_t> contested;
  for (int i = 0; i < kRounds; ++i) {
    contested.push_back(MustAppend(MakeEvent("user0", "contested")));
  }
  std::vector<std::vector<int64_t>> acknowledged(kThreads);
  std::atomic<int> contested_wins{0}, contested_refusals{0}, wrong{0};
  std::vector<std::thread> threads;
  for (int u = 0; u < kThreads; ++u) {
    threads.emplace_back([&, u] {
      const std::string user = absl::StrCat("user", u);
      for (int i = 0; i < kRounds; ++i) {
        absl::StatusOr<int64_t> id =
            store_->AppendPending(MakeEvent(user, "m", i));
        if (!id.ok()) {
          ++wrong;
          continue;
        }
        if (store_->AppendPending(MakeEvent("nobody", "m")).status().code() !=
            absl::StatusCode::kNotFound) {
          ++wrong;
        }
        absl::StatusOr<EventRecord> done = store_->CompleteEvent(
            *id, 0.5, {1.0, 2.0}, 1.0, absl::FromUnixMicros(1700000002000000));
        if (!done.ok() || done->context[0] != i) {
          ++wrong;
          continue;
        }
        acknowledged[u].push_back(*id);
        if (u < 2) {  // two threads race for the same event
          absl::StatusOr<EventRecord> race =
              store_->CompleteEvent(contested[i], 1.0, {0.0, 0.0}, 1.0,
                                    absl::FromUnixMicros(1700000003000000));
          if (race.ok()) {
            ++contested_wins;
          } else if (race.status().code() ==
                     absl::StatusCode::kFailedPrecondition) {
            ++contested_refusals;
          } else {
            ++wrong;
          }
        }
      }
    });
  }
  for (std::thread& t : threads) t.join();
  EXPECT_EQ(wrong.load(), 0);
  EXPECT_EQ(contested_wins.load(), kRounds);
  EXPECT_EQ(contested_refusals.load(), kRounds);
  const StoreWriteStats stats = store_->write_stats();
  if (sqlite()) {
    // Every hot-path write went through a group commit (how many shared
    // one depends on timing: not asserted beyond at most one commit each).
    EXPECT_EQ(stats.committed_writes,
              stats.appends + stats.completions +
                  kThreads * kRounds /* the refused appends */ +
                  kRounds /* the refused completions */);
  } else {
    // Each acknowledged write is its own commit; refused ones commit
    // nothing.
    EXPECT_EQ(stats.committed_writes, stats.appends + stats.completions);
  }
  EXPECT_LE(stats.commits, stats.committed_writes);

  store_.reset();
  store_ = OpenStore();
  ASSERT_NE(store_, nullptr);
  for (int u = 0; u < kThreads; ++u) {
    const std::string user = absl::StrCat("user", u);
    const int64_t expected = kRounds + (u == 0 ? kRounds : 0);
    EXPECT_EQ(MustGetUser(user).model_version, expected) << user;
    for (int64_t id : acknowledged[u]) {
      EXPECT_TRUE(MustGetEvent(id).completed) << id;
    }
    absl::StatusOr<std::vector<EventRecord>> log =
        store_->CompletedEvents(user);
    ASSERT_TRUE(log.ok());
    ASSERT_EQ(static_cast<int64_t>(log->size()), expected);
    for (size_t k = 0; k < log->size(); ++k) {
      EXPECT_EQ((*log)[k].model_version, static_cast<int64_t>(k) + 1);
    }
  }
  auto nobody = store_->ListEvents("nobody", "", Page());
  EXPECT_EQ(nobody.status().code(), absl::StatusCode::kNotFound);
}

TEST_P(EventStoreTest, UnknownEventIsNotFound) {
  ASSERT_TRUE(store_->CreateUser(MakeUser("alice")).ok());
  auto completed =
      store_->CompleteEvent(123, 1.0, {}, 1.0, absl::FromUnixMicros(0));
  EXPECT_EQ(completed.status().code(), absl::StatusCode::kNotFound);
  EXPECT_EQ(completed.status().message(), "event 123 not found");
  EXPECT_EQ(store_->GetEvent(123).status().code(), absl::StatusCode::kNotFound);
  EXPECT_EQ(MustGetUser("alice").model_version, 0);
}

TEST_P(EventStoreTest, DoublesRoundTripExactly) {
  ASSERT_TRUE(store_->CreateUser(MakeUser("alice")).ok());
  using limits = std::numeric_limits<double>;
  const std::vector<double> context = {
      -0.0,
      0.0,
      limits::denorm_min(),
      -limits::denorm_min(),
      limits::min(),
      limits::max(),
      limits::lowest(),
      limits::infinity(),
      -limits::infinity(),
      0.1,
      1.0 / 3.0,
      9007199254740993.0,  // 2^53 + 1 rounds; whatever it became must stay
      FromBits(0x7ff8000000000123),  // quiet NaN with a payload
      FromBits(0xfff0000000000001),  // signalling NaN, sign bit set
  };
  const std::vector<double> posthoc = {-0.0, limits::denorm_min(), 1e308};
  EventRecord event = MakeEvent("alice", "m");
  event.context = context;
  event.propensity = limits::denorm_min();
  const int64_t id = MustAppend(event);
  auto completed =
      store_->CompleteEvent(id, /*loss=*/-0.0, posthoc,
                            /*weight=*/limits::max(), absl::FromUnixMicros(1));
  ASSERT_TRUE(completed.ok()) << completed.status();

  auto check = [&](const EventRecord& got) {
    EXPECT_EQ(Bits(got.context), Bits(context));
    EXPECT_EQ(Bits(got.posthoc), Bits(posthoc));
    EXPECT_EQ(Bits(got.propensity), Bits(limits::denorm_min()));
    EXPECT_EQ(Bits(got.loss), Bits(-0.0));
    EXPECT_EQ(Bits(got.weight), Bits(limits::max()));
  };
  check(MustGetEvent(id));
  // And through the file, not just the connection's cache.
  store_.reset();
  store_ = OpenStore();
  ASSERT_NE(store_, nullptr);
  check(MustGetEvent(id));
  auto log = store_->CompletedEvents("alice");
  ASSERT_TRUE(log.ok()) << log.status();
  ASSERT_EQ(log->size(), 1u);
  check((*log)[0]);
}

TEST_P(EventStoreTest, EmptyVectorsRoundTrip) {
  ASSERT_TRUE(store_->CreateUser(MakeUser("alice")).ok());
  EventRecord event = MakeEvent("alice", "m");
  event.context.clear();
  const int64_t id = MustAppend(event);
  auto completed =
      store_->CompleteEvent(id, 1.0, {}, 1.0, absl::FromUnixMicros(1));
  ASSERT_TRUE(completed.ok()) << completed.status();
  const EventRecord got = MustGetEvent(id);
  EXPECT_THAT(got.context, IsEmpty());
  EXPECT_THAT(got.posthoc, IsEmpty());
  EXPECT_TRUE(got.completed);
}

TEST_P(EventStoreTest, NanScalarsAreRejected) {
  ASSERT_TRUE(store_->CreateUser(MakeUser("alice")).ok());
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EventRecord event = MakeEvent("alice", "m");
  event.propensity = nan;
  EXPECT_EQ(store_->AppendPending(event).status().code(),
            absl::StatusCode::kInvalidArgument);
  const int64_t id = MustAppend(MakeEvent("alice", "m"));
  EXPECT_EQ(store_->CompleteEvent(id, nan, {}, 1.0, absl::FromUnixMicros(1))
                .status()
                .code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(store_->CompleteEvent(id, 1.0, {}, nan, absl::FromUnixMicros(1))
                .status()
                .code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_FALSE(MustGetEvent(id).completed);
  EXPECT_EQ(MustGetUser("alice").model_version, 0);
}

TEST_P(EventStoreTest, ListEventsFiltersByMealWithPaging) {
  ASSERT_TRUE(store_->CreateUser(MakeUser("alice")).ok());
  ASSERT_TRUE(store_->CreateUser(MakeUser("bob")).ok());
  std::vector<int64_t> alice_m1;
  std::vector<int64_t> alice_all;
  for (int i = 0; i < 10; ++i) {
    const std::string meal = i % 2 == 0 ? "m1" : "m2";
    const int64_t id = MustAppend(MakeEvent("alice", meal, i));
    alice_all.push_back(id);
    if (meal == "m1") alice_m1.push_back(id);
    MustAppend(MakeEvent("bob", "m1", i));  // interleaved, never listed
  }
  MustComplete(alice_m1[1]);  // completed events are listed too

  auto list_all_pages = [&](const std::string& meal, int page_size,
                            std::vector<size_t>* sizes) {
    std::vector<int64_t> ids;
    Page page;
    page.page_size = page_size;
    while (true) {
      auto result = store_->ListEvents("alice", meal, page);
      EXPECT_TRUE(result.ok()) << result.status();
      if (!result.ok()) break;
      sizes->push_back(result->items.size());
      for (const EventRecord& event : result->items) {
        EXPECT_EQ(event.user_id, "alice");
        if (!meal.empty()) {
          EXPECT_EQ(event.meal_id, meal);
        }
        ids.push_back(event.event_id);
      }
      if (result->next_page_token.empty()) break;
      page.page_token = result->next_page_token;
    }
    return ids;
  };

  std::vector<size_t> sizes;
  EXPECT_EQ(list_all_pages("m1", 2, &sizes), alice_m1);
  EXPECT_THAT(sizes, ElementsAre(2, 2, 1));
  sizes.clear();
  EXPECT_EQ(list_all_pages("", 4, &sizes), alice_all);
  EXPECT_THAT(sizes, ElementsAre(4, 4, 2));
  sizes.clear();
  EXPECT_THAT(list_all_pages("no such meal", 4, &sizes), IsEmpty());
  EXPECT_THAT(sizes, ElementsAre(0));
}

TEST_P(EventStoreTest, CompletedEventsAreInModelVersionOrder) {
  ASSERT_TRUE(store_->CreateUser(MakeUser("alice")).ok());
  const int64_t e1 = MustAppend(MakeEvent("alice", "m", 1));
  const int64_t e2 = MustAppend(MakeEvent("alice", "m", 2));
  const int64_t e3 = MustAppend(MakeEvent("alice", "m", 3));
  MustAppend(MakeEvent("alice", "m", 4));  // stays pending
  EXPECT_EQ(MustComplete(e3).model_version, 1);
  EXPECT_EQ(MustComplete(e1).model_version, 2);
  EXPECT_EQ(MustComplete(e2).model_version, 3);

  auto log = store_->CompletedEvents("alice");
  ASSERT_TRUE(log.ok()) << log.status();
  std::vector<int64_t> ids;
  std::vector<int64_t> versions;
  for (const EventRecord& event : *log) {
    ids.push_back(event.event_id);
    versions.push_back(event.model_version);
    EXPECT_TRUE(event.completed);
  }
  EXPECT_THAT(ids, ElementsAre(e3, e1, e2));
  EXPECT_THAT(versions, ElementsAre(1, 2, 3));
}

TEST_P(EventStoreTest, ResetUserDeletesEventsAndKeepsConfig) {
  UserRecord user = MakeUser("alice");
  user.config.alpha = 0.5;
  ASSERT_TRUE(store_->CreateUser(user).ok());
  ASSERT_TRUE(store_->CreateUser(MakeUser("bob")).ok());
  const int64_t done = MustAppend(MakeEvent("alice", "m"));
  MustComplete(done);
  const int64_t pending = MustAppend(MakeEvent("alice", "m"));
  const int64_t bobs = MustAppend(MakeEvent("bob", "m"));

  ASSERT_TRUE(store_->ResetUser("alice").ok());
  const UserRecord reset = MustGetUser("alice");
  EXPECT_EQ(reset.model_version, 0);
  EXPECT_EQ(reset.pending_events, 0);
  EXPECT_EQ(reset.config.alpha, 0.5);
  EXPECT_EQ(reset.created_at, user.created_at);
  EXPECT_EQ(store_->GetEvent(done).status().code(),
            absl::StatusCode::kNotFound);
  EXPECT_EQ(store_->GetEvent(pending).status().code(),
            absl::StatusCode::kNotFound);
  EXPECT_TRUE(MustGetEvent(bobs).user_id == "bob");
  auto log = store_->CompletedEvents("alice");
  ASSERT_TRUE(log.ok());
  EXPECT_THAT(*log, IsEmpty());

  // Ids are not reused, and versions count again from 1.
  const int64_t fresh = MustAppend(MakeEvent("alice", "m"));
  EXPECT_GT(fresh, bobs);
  EXPECT_EQ(MustComplete(fresh).model_version, 1);
}

TEST_P(EventStoreTest, DeleteUserCascadesToEvents) {
  ASSERT_TRUE(store_->CreateUser(MakeUser("alice")).ok());
  ASSERT_TRUE(store_->CreateUser(MakeUser("bob")).ok());
  const int64_t a1 = MustAppend(MakeEvent("alice", "m"));
  MustComplete(a1);
  const int64_t a2 = MustAppend(MakeEvent("alice", "m"));
  const int64_t b1 = MustAppend(MakeEvent("bob", "m"));

  ASSERT_TRUE(store_->DeleteUser("alice").ok());
  EXPECT_EQ(store_->GetUser("alice").status().code(),
            absl::StatusCode::kNotFound);
  EXPECT_EQ(store_->GetEvent(a1).status().code(), absl::StatusCode::kNotFound);
  EXPECT_EQ(store_->GetEvent(a2).status().code(), absl::StatusCode::kNotFound);
  EXPECT_EQ(MustGetEvent(b1).user_id, "bob");
  EXPECT_EQ(store_->DeleteUser("alice").code(), absl::StatusCode::kNotFound);

  RawSql& raw = Raw();
  EXPECT_EQ(raw.Text("SELECT COUNT(*) FROM events WHERE user_id = 'alice'"),
            "0");
  EXPECT_EQ(raw.Text("SELECT COUNT(*) FROM events"), "1");

  // A new user under the old id starts empty.
  ASSERT_TRUE(store_->CreateUser(MakeUser("alice")).ok());
  auto events = store_->ListEvents("alice", "", Page());
  ASSERT_TRUE(events.ok());
  EXPECT_THAT(events->items, IsEmpty());
  EXPECT_EQ(MustGetUser("alice").model_version, 0);
}

TEST_P(EventStoreTest, DataSurvivesReopening) {
  ASSERT_TRUE(store_->CreateUser(MakeUser("alice")).ok());
  const int64_t done = MustAppend(MakeEvent("alice", "m"));
  MustComplete(done, /*loss=*/0.125);
  const int64_t pending = MustAppend(MakeEvent("alice", "m"));

  store_.reset();
  store_ = OpenStore();
  ASSERT_NE(store_, nullptr);
  const UserRecord user = MustGetUser("alice");
  EXPECT_EQ(user.model_version, 1);
  EXPECT_EQ(user.pending_events, 1);
  EXPECT_EQ(user.created_at, MakeUser("alice").created_at);
  EXPECT_EQ(MustGetEvent(done).loss, 0.125);
  EXPECT_FALSE(MustGetEvent(pending).completed);
  EXPECT_GT(MustAppend(MakeEvent("alice", "m")), pending);
  EXPECT_EQ(MustComplete(pending).model_version, 2);
}

TEST_P(EventStoreTest, AcknowledgedUpdateSurvivesKill9) {
  // No connection may be open across fork(): SQLite's per-process lock
  // bookkeeping (or a libpq socket) would be shared with the child.
  store_.reset();
  raw_.reset();
  int64_t ids[2] = {0, 0};
  int pipe_fds[2];
  ASSERT_EQ(pipe(pipe_fds), 0);
  const pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    // The child never returns into gtest: it reports the ids once both
    // writes are acknowledged, then dies without closing anything.
    close(pipe_fds[0]);
    auto store = TryOpenStore();
    if (!store.ok() || !(*store)->CreateUser(MakeUser("alice")).ok()) _exit(1);
    auto done = (*store)->AppendPending(MakeEvent("alice", "m"));
    auto pending = (*store)->AppendPending(MakeEvent("alice", "m"));
    if (!done.ok() || !pending.ok()) _exit(1);
    if (!(*store)
             ->CompleteEvent(*done, 0.5, {1.0, 2.0}, 1.0,
                             absl::FromUnixMicros(1))
             .ok()) {
      _exit(1);
    }
    const int64_t written[2] = {*done, *pending};
    if (write(pipe_fds[1], written, sizeof(written)) != sizeof(written)) {
      _exit(1);
    }
    raise(SIGKILL);
    _exit(1);
  }
  close(pipe_fds[1]);
  const ssize_t got = read(pipe_fds[0], ids, sizeof(ids));
  close(pipe_fds[0]);
  int wstatus = 0;
  ASSERT_EQ(waitpid(pid, &wstatus, 0), pid);
  ASSERT_TRUE(WIFSIGNALED(wstatus) && WTERMSIG(wstatus) == SIGKILL)
      << "child status " << wstatus;
  ASSERT_EQ(got, static_cast<ssize_t>(sizeof(ids)));

  auto store = TryOpenStore();
  ASSERT_TRUE(store.ok()) << store.status();
  auto user = (*store)->GetUser("alice");
  ASSERT_TRUE(user.ok()) << user.status();
  EXPECT_EQ(user->model_version, 1);
  EXPECT_EQ(user->pending_events, 1);
  auto done = (*store)->GetEvent(ids[0]);
  ASSERT_TRUE(done.ok()) << done.status();
  EXPECT_TRUE(done->completed);
  EXPECT_EQ(done->loss, 0.5);
  EXPECT_THAT(done->posthoc, ElementsAre(1.0, 2.0));
  auto pending = (*store)->GetEvent(ids[1]);
  ASSERT_TRUE(pending.ok()) << pending.status();
  EXPECT_FALSE(pending->completed);
}

TEST_F(SqliteEventStoreTest, FileIsWalWithSchemaVersion) {
  RawDb raw(path_);
  EXPECT_EQ(raw.Text("PRAGMA journal_mode"), "wal");
  EXPECT_EQ(raw.Text("PRAGMA user_version"), "6");
  EXPECT_NE(raw.Text("PRAGMA application_id"), "0");
}

TEST_F(SqliteEventStoreTest, MissingOrEmptyFileIsANewStoreOnlyWhenAskedFor) {
  SqliteStoreOptions options;
  options.path = dir_ + "/typo.db";
  options.create_if_missing = false;
  auto missing = SqliteEventStore::Open(options);
  EXPECT_EQ(missing.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(missing.status().message(),
              HasSubstr(options.path + "\" does not exist; pass --create"));
  EXPECT_FALSE(std::filesystem::exists(options.path));  // nothing made
  std::ofstream(options.path).close();                  // a 0-byte file
  auto empty = SqliteEventStore::Open(options);
  EXPECT_THAT(empty.status().message(), HasSubstr("is an empty file"));
  // Asked for: created, readable by its owner only.
  options.create_if_missing = true;
  std::filesystem::remove(options.path);
  auto created = SqliteEventStore::Open(options);
  ASSERT_TRUE(created.ok()) << created.status();
  struct stat st {};
  ASSERT_EQ(stat(options.path.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0600u);
  created->reset();
  // An existing store opens without it.
  options.create_if_missing = false;
  EXPECT_TRUE(SqliteEventStore::Open(options).ok());
}

TEST_F(SqliteEventStoreTest, NotADatabaseIsFailedPrecondition) {
  const std::string path = dir_ + "/notes.txt";
  const std::string content(4096, 'x');
  {
    std::ofstream out(path, std::ios::binary);
    out << content;
  }
  SqliteStoreOptions options;
  options.path = path;
  auto store = SqliteEventStore::Open(options);
  EXPECT_EQ(store.status().code(), absl::StatusCode::kFailedPrecondition)
      << store.status();
  EXPECT_THAT(store.status().message(), HasSubstr(path));
  std::ifstream in(path, std::ios::binary);
  EXPECT_EQ(std::string(std::istreambuf_iterator<char>(in), {}), content);
}

TEST_F(SqliteEventStoreTest, NewerSchemaVersionIsFailedPrecondition) {
  store_.reset();
  RawDb(path_).Exec("PRAGMA user_version = 7");
  SqliteStoreOptions options;
  options.path = path_;
  auto store = SqliteEventStore::Open(options);
  EXPECT_EQ(store.status().code(), absl::StatusCode::kFailedPrecondition)
      << store.status();
  EXPECT_THAT(store.status().message(), HasSubstr(path_));
  EXPECT_THAT(store.status().message(), HasSubstr("version 7"));
}

PopulationPrior SmallPrior(int64_t version, double rounds) {
  PopulationPrior prior;
  prior.pool_version = version;
  prior.rounds = rounds;
  prior.context_msn = 1.25;
  prior.posthoc_msn = 0.5;
  for (int a = 0; a < 6; ++a) {
    prior.theta0.push_back({0.1 * a, -0.2, 1.0 / 3.0});
    prior.phi0.push_back({0.01 * a, 7.0});
  }
  return prior;
}

TEST_P(EventStoreTest, PoolsAndUsersWithAPriorRoundTripExactly) {
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

// A second process on the same file would serve models that miss the first
// one's updates: it is refused, naming the holder; the file is free again
// once the first store closes (or its process dies: the lock is the
// kernel's).
TEST_F(SqliteEventStoreTest, ASecondStoreOnTheSameFileIsRefused) {
  SqliteStoreOptions options;
  options.path = path_;
  auto second = SqliteEventStore::Open(options);
  EXPECT_EQ(second.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(second.status().message(),
              HasSubstr("already open in another process (pid " +
                        std::to_string(getpid())));
  EXPECT_THAT(second.status().message(), HasSubstr(path_));
  store_.reset();
  auto third = SqliteEventStore::Open(options);
  EXPECT_TRUE(third.ok()) << third.status();
}

// A database file removed (or replaced) under a running service: writes
// would be acknowledged and lost at the next start, so none is accepted.
TEST_F(SqliteEventStoreTest, WritesAreRefusedOnceTheFileIsRemoved) {
  ASSERT_TRUE(store_->CreateUser(MakeUser("ann")).ok());
  EXPECT_TRUE(store_->CheckHealth().ok());
  std::filesystem::remove(path_);
  const absl::Status health = store_->CheckHealth();
  EXPECT_EQ(health.code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(health.message(), HasSubstr(path_ + " was removed or replaced"));
  auto appended = store_->AppendPending(MakeEvent("ann", "m1"));
  EXPECT_EQ(appended.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_EQ(store_->CreateUser(MakeUser("bob")).code(),
            absl::StatusCode::kFailedPrecondition);
}

// A file whose pages were damaged is not served as if it were whole.
TEST_F(SqliteEventStoreTest, ADamagedFileIsDataLossNotAnEmptyStore) {
  ASSERT_TRUE(store_->CreateUser(MakeUser("ann")).ok());
  for (int i = 0; i < 200; ++i) {
    ASSERT_TRUE(store_->AppendPending(MakeEvent("ann", "m1", i)).ok());
  }
  store_.reset();
  {
    RawDb raw(path_);
    raw.Exec("PRAGMA wal_checkpoint(TRUNCATE)");
  }
  // Overwrite the middle of the event table's pages with garbage.
  const auto size = std::filesystem::file_size(path_);
  ASSERT_GT(size, 16384u);
  {
    std::fstream file(path_, std::ios::in | std::ios::out | std::ios::binary);
    for (std::streamoff at = 8192; at < 8192 + 3 * 4096; at += 4096) {
      file.seekp(at + 8);
      const std::string garbage(64, '\x5a');
      file.write(garbage.data(), garbage.size());
    }
  }
  SqliteStoreOptions options;
  options.path = path_;
  auto store = SqliteEventStore::Open(options);
  EXPECT_EQ(store.status().code(), absl::StatusCode::kDataLoss)
      << store.status();
  EXPECT_THAT(store.status().message(), HasSubstr(path_));
}

// Turns the current store at `path` back into what a version 5 build wrote:
// no contexts file (every context, all small here, in event_contexts).
void RewriteAsVersion5(const std::string& path) {
  RawDb raw(path);
  EXPECT_EQ(raw.Text("SELECT COUNT(*) FROM events WHERE context_offset IS "
                     "NOT NULL"),
            "0");
  raw.Exec("ALTER TABLE events DROP COLUMN context_offset");
  raw.Exec("ALTER TABLE events DROP COLUMN context_bytes");
  raw.Exec("PRAGMA user_version = 5");
}

// Turns the current store at `path` back into what a version 4 build wrote:
// each event's context in its own row.
void RewriteAsVersion4(const std::string& path) {
  RewriteAsVersion5(path);
  RawDb raw(path);
  raw.Exec("ALTER TABLE events ADD COLUMN context BLOB");
  raw.Exec(
      "UPDATE events SET context = (SELECT context FROM event_contexts c "
      "WHERE c.event_id = events.event_id)");
  raw.Exec("DROP TABLE event_contexts");
  raw.Exec("PRAGMA user_version = 4");
}

// Turns the current store at `path` back into what a version 2 build wrote:
// action names as a JSON column of users and pools, no child tables.
void RewriteAsVersion2(const std::string& path,
                       const std::string& user_names_json,
                       const std::string& pool_names_json) {
  RewriteAsVersion4(path);
  RawDb raw(path);
  raw.Exec(
      "ALTER TABLE users ADD COLUMN action_names TEXT NOT NULL DEFAULT ''");
  raw.Exec("UPDATE users SET action_names = '" + user_names_json + "'");
  raw.Exec(
      "ALTER TABLE population_pools ADD COLUMN action_names TEXT NOT NULL "
      "DEFAULT ''");
  raw.Exec("UPDATE population_pools SET action_names = '" + pool_names_json +
           "'");
  raw.Exec("DROP TABLE user_actions");
  raw.Exec("DROP TABLE pool_actions");
  raw.Exec("ALTER TABLE events DROP COLUMN selection_checksum");
  raw.Exec("ALTER TABLE events DROP COLUMN outcome_checksum");
  raw.Exec("DROP TABLE audit");
  raw.Exec("DROP TABLE model_checkpoint_chunks");
  raw.Exec("DROP TABLE model_checkpoints");
  raw.Exec("PRAGMA user_version = 2");
}

// Version 4 kept each context in its event's row; version 5 moves them to
// event_contexts, and every event reads back as it was, checksums included.
TEST_F(SqliteEventStoreTest, VersionFourContextsMoveToTheirOwnTable) {
  ASSERT_TRUE(store_->CreateUser(MakeUser("four")).ok());
  const int64_t done = MustAppend(MakeEvent("four", "m1", 0.25));
  MustComplete(done, 0.0);
  const int64_t pending = MustAppend(MakeEvent("four", "m2", -1.5));
  const EventRecord before_done = MustGetEvent(done);
  const EventRecord before_pending = MustGetEvent(pending);
  store_.reset();
  RewriteAsVersion4(path_);
  EXPECT_EQ(RawDb(path_).Text("SELECT COUNT(*) FROM events WHERE context IS "
                              "NOT NULL"),
            "2");
  store_ = OpenStore();
  ASSERT_NE(store_, nullptr);
  EXPECT_EQ(RawDb(path_).Text("PRAGMA user_version"), "6");
  EXPECT_EQ(RawDb(path_).Text("SELECT COUNT(*) FROM event_contexts"), "2");
  const EventRecord after_done = MustGetEvent(done);
  const EventRecord after_pending = MustGetEvent(pending);
  EXPECT_EQ(after_done.context, before_done.context);
  EXPECT_EQ(after_done.loss, before_done.loss);
  EXPECT_EQ(after_done.model_version, 1);
  EXPECT_EQ(after_pending.context, before_pending.context);
  EXPECT_FALSE(after_pending.completed);
  absl::StatusOr<StoreCheckReport> check = store_->CheckStore();
  ASSERT_TRUE(check.ok()) << check.status();
  EXPECT_TRUE(check->findings.empty());
  // A lost context row is damage, found by the checksum, not an event
  // that silently drops out of the log.
  RawDb(path_).Exec(
      absl::StrCat("DELETE FROM event_contexts WHERE event_id = ", pending));
  EXPECT_EQ(store_->GetEvent(pending).status().code(),
            absl::StatusCode::kDataLoss);
  check = store_->CheckStore();
  ASSERT_TRUE(check.ok()) << check.status();
  EXPECT_FALSE(check->findings.empty());
  // Deleting the user takes the contexts along.
  ASSERT_TRUE(store_->DeleteUser("four").ok());
  EXPECT_EQ(RawDb(path_).Text("SELECT COUNT(*) FROM event_contexts"), "0");
}

TEST_F(SqliteEventStoreTest, VersionOneFilesAreMigratedKeepingEverything) {
  ASSERT_TRUE(store_->CreateUser(MakeUser("old")).ok());
  auto id = store_->AppendPending(MakeEvent("old", "m1"));
  ASSERT_TRUE(id.ok());
  store_.reset();
  RewriteAsVersion2(path_, R"(["VS0","VS90","TV0","TV90","TA0","TA90"])", "[]");
  {
    RawDb raw(path_);  // and back to what a version 1 build wrote
    raw.Exec("DROP TABLE population_pools");
    raw.Exec("ALTER TABLE users DROP COLUMN prior");
    raw.Exec("PRAGMA user_version = 1");
  }
  SqliteStoreOptions options;
  options.path = path_;
  auto store = SqliteEventStore::Open(options);
  ASSERT_TRUE(store.ok()) << store.status();
  EXPECT_EQ(RawDb(path_).Text("PRAGMA user_version"), "6");
  auto user = (*store)->GetUser("old");
  ASSERT_TRUE(user.ok()) << user.status();
  EXPECT_EQ(user->pending_events, 1);
  EXPECT_EQ(user->config.action_names, SmallConfig().action_names);
  // The migration gave the event its checksum: it reads back, and completes.
  ASSERT_TRUE((*store)->GetEvent(*id).ok());
  ASSERT_TRUE((*store)
                  ->CompleteEvent(*id, 1.0, {0.5, -0.5}, 1.0,
                                  absl::FromUnixSeconds(1700000100))
                  .ok());
  EXPECT_TRUE((*store)->CompletedEvents("old").ok());
  EXPECT_FALSE(user->config.prior.enabled());
  EXPECT_EQ((*store)->LatestPool(SmallConfig()).status().code(),
            absl::StatusCode::kNotFound);
}

// Version 2 kept action names as JSON; version 3 moves them, byte for byte
// (quotes, backslashes, control characters, NUL, non-ASCII), into
// user_actions and pool_actions and drops the columns.
TEST_F(SqliteEventStoreTest, VersionTwoActionNamesMoveIntoChildTables) {
  BanditConfig config = SmallConfig();
  config.action_names = {"a\"b",     "c\\d",      std::string("\0x", 2),
                         "\xc3\xa9", "tab\there", "/"};
  UserRecord user = MakeUser("v2");
  user.config = config;
  ASSERT_TRUE(store_->CreateUser(user).ok());
  PoolRecord pool;
  pool.users = 4;
  pool.learner = config.learner;
  pool.context_dim = config.context_dim;
  pool.posthoc_dim = config.posthoc_dim;
  pool.action_names = config.action_names;
  pool.prior = SmallPrior(0, 0.0);
  ASSERT_TRUE(store_->AddPool(pool).ok());
  store_.reset();
  const std::string json =
      R"(["a\"b","c\\d","\u0000x","\u00e9","tab\there","\/"])";
  RewriteAsVersion2(path_, json, json);

  SqliteStoreOptions options;
  options.path = path_;
  auto store = SqliteEventStore::Open(options);
  ASSERT_TRUE(store.ok()) << store.status();
  auto migrated = (*store)->GetUser("v2");
  ASSERT_TRUE(migrated.ok()) << migrated.status();
  EXPECT_EQ(migrated->config.action_names, config.action_names);
  auto found = (*store)->LatestPool(config);
  ASSERT_TRUE(found.ok()) << found.status();
  EXPECT_EQ(found->action_names, config.action_names);
  RawDb raw(path_);
  EXPECT_EQ(raw.Text("SELECT COUNT(*) FROM pragma_table_info('users') "
                     "WHERE name = 'action_names'"),
            "0");
  EXPECT_EQ(raw.Text("SELECT COUNT(*) FROM user_actions"), "6");
  EXPECT_EQ(raw.Text("SELECT COUNT(*) FROM pool_actions"), "6");
}

TEST_F(SqliteEventStoreTest, MalformedVersionTwoNamesAreDataLossAndUntouched) {
  ASSERT_TRUE(store_->CreateUser(MakeUser("broken")).ok());
  store_.reset();
  RewriteAsVersion2(path_, R"(["VS0","VS90)", "[]");
  SqliteStoreOptions options;
  options.path = path_;
  auto store = SqliteEventStore::Open(options);
  EXPECT_EQ(store.status().code(), absl::StatusCode::kDataLoss)
      << store.status();
  EXPECT_THAT(store.status().message(), HasSubstr("broken"));
  EXPECT_EQ(RawDb(path_).Text("PRAGMA user_version"), "2");  // rolled back
}

// An event altered on disk is DATA_LOSS naming it, for its selection and
// for its outcome, wherever it is read, so it is never learned from.
// A checkpoint larger than a chunk round-trips through several chunk
// transactions; the events after it are read from its version on; a damaged
// chunk is DATA_LOSS naming the user; a reset or a deleted user takes the
// checkpoint with it, and a checkpoint of a log that moved on is not kept.
TEST_P(EventStoreTest, CheckpointsRoundTripInChunksAndGoWithTheLog) {
  ASSERT_TRUE(store_->CreateUser(MakeUser("ann")).ok());
  std::vector<int64_t> ids;
  for (int i = 0; i < 5; ++i) {
    ids.push_back(MustAppend(MakeEvent("ann", "m", i)));
    MustComplete(ids.back());
  }
  EXPECT_EQ(store_->GetCheckpoint("ann").status().code(),
            absl::StatusCode::kNotFound);
  ModelCheckpoint checkpoint;
  checkpoint.model_version = 3;
  checkpoint.last_event_id = ids[2];
  checkpoint.created_at = absl::FromUnixMicros(1700000003000000);
  std::mt19937_64 rng(8);
  checkpoint.state.resize(2 * SqliteEventStore::kCheckpointChunkBytes + 12345);
  for (char& c : checkpoint.state) c = static_cast<char>(rng());
  ASSERT_TRUE(store_->PutCheckpoint("ann", checkpoint).ok());
  EXPECT_EQ(Raw().Text("SELECT COUNT(*) FROM model_checkpoint_chunks"), "3");
  auto read = store_->GetCheckpoint("ann");
  ASSERT_TRUE(read.ok()) << read.status();
  EXPECT_EQ(read->model_version, 3);
  EXPECT_EQ(read->last_event_id, ids[2]);
  EXPECT_EQ(read->created_at, checkpoint.created_at);
  EXPECT_TRUE(read->state == checkpoint.state);
  auto after = store_->CompletedEventsFrom("ann", 3);
  ASSERT_TRUE(after.ok());
  ASSERT_EQ(after->size(), 3u);
  EXPECT_EQ((*after)[0].event_id, ids[2]);
  EXPECT_EQ((*after)[2].model_version, 5);
  // A newer one replaces it, and its chunks the old ones.
  checkpoint.model_version = 5;
  checkpoint.last_event_id = ids[4];
  checkpoint.state = "small";
  ASSERT_TRUE(store_->PutCheckpoint("ann", checkpoint).ok());
  EXPECT_EQ(Raw().Text("SELECT COUNT(*) FROM model_checkpoint_chunks"), "1");
  EXPECT_EQ(store_->GetCheckpoint("ann")->state, "small");
  // Damaged bytes.
  Raw().Exec(absl::StrCat("UPDATE model_checkpoint_chunks SET data = ",
                          BlobLiteral("736D616C6C21")));
  auto damaged = store_->GetCheckpoint("ann");
  EXPECT_EQ(damaged.status().code(), absl::StatusCode::kDataLoss);
  EXPECT_THAT(damaged.status().message(), HasSubstr("user ann"));
  // The full check finds it too, as a finding (the store is still usable).
  {
    absl::StatusOr<StoreCheckReport> check = store_->CheckStore();
    ASSERT_TRUE(check.ok()) << check.status();
    ASSERT_EQ(check->findings.size(), 1u);
    EXPECT_THAT(check->findings[0], HasSubstr("model checkpoint of user ann"));
  }
  // A checkpoint whose event is not at its version is not kept (nor its
  // chunks); the one in place stays until deleted.
  checkpoint.model_version = 4;
  checkpoint.last_event_id = ids[2];
  EXPECT_EQ(store_->PutCheckpoint("ann", checkpoint).code(),
            absl::StatusCode::kFailedPrecondition);
  EXPECT_EQ(Raw().Text("SELECT COUNT(*) FROM model_checkpoint_chunks"), "1");
  EXPECT_EQ(store_->GetCheckpoint("ann").status().code(),
            absl::StatusCode::kDataLoss);  // the damaged version 5, still
  ASSERT_TRUE(store_->DeleteCheckpoint("ann").ok());
  EXPECT_EQ(store_->GetCheckpoint("ann").status().code(),
            absl::StatusCode::kNotFound);
  checkpoint.model_version = 5;
  // Reset and delete take it along.
  checkpoint.last_event_id = ids[4];
  ASSERT_TRUE(store_->PutCheckpoint("ann", checkpoint).ok());
  ASSERT_TRUE(store_->ResetUser("ann").ok());
  EXPECT_EQ(store_->GetCheckpoint("ann").status().code(),
            absl::StatusCode::kNotFound);
  EXPECT_EQ(Raw().Text("SELECT COUNT(*) FROM model_checkpoint_chunks"), "0");
  ASSERT_TRUE(store_->CreateUser(MakeUser("bob")).ok());
  const int64_t bob_event = MustAppend(MakeEvent("bob", "m"));
  MustComplete(bob_event);
  checkpoint.model_version = 1;
  checkpoint.last_event_id = bob_event;
  ASSERT_TRUE(store_->PutCheckpoint("bob", checkpoint).ok());
  ASSERT_TRUE(store_->DeleteUser("bob").ok());
  EXPECT_EQ(Raw().Text("SELECT COUNT(*) FROM model_checkpoints"), "0");
  EXPECT_EQ(store_->PutCheckpoint("nobody", checkpoint).code(),
            absl::StatusCode::kNotFound);
}

TEST_P(EventStoreTest, AlteredEventIsDataLossNamingIt) {
  ASSERT_TRUE(store_->CreateUser(MakeUser("alice")).ok());
  const int64_t id = MustAppend(MakeEvent("alice", "m"));
  ASSERT_TRUE(store_
                  ->CompleteEvent(id, 1.0, {0.25, 0.75}, 1.0,
                                  absl::FromUnixSeconds(1700000100))
                  .ok());
  ASSERT_TRUE(store_->GetEvent(id).ok());
  Raw().Exec(absl::StrCat("UPDATE events SET loss = 0.0 WHERE event_id = ",
                          id));  // "success"
  auto event = store_->GetEvent(id);
  EXPECT_EQ(event.status().code(), absl::StatusCode::kDataLoss);
  EXPECT_THAT(event.status().message(),
              HasSubstr(absl::StrCat("event ", id, " of user \"alice\"")));
  EXPECT_THAT(event.status().message(), HasSubstr("outcome"));
  EXPECT_EQ(store_->CompletedEvents("alice").status().code(),
            absl::StatusCode::kDataLoss);

  const int64_t other = MustAppend(MakeEvent("alice", "m"));
  Raw().Exec(
      absl::StrCat("UPDATE events SET action = 5 WHERE event_id = ", other));
  auto pending = store_->GetEvent(other);
  EXPECT_EQ(pending.status().code(), absl::StatusCode::kDataLoss);
  EXPECT_THAT(pending.status().message(), HasSubstr("selection"));
  EXPECT_EQ(store_
                ->CompleteEvent(other, 0.0, {0.5, 0.5}, 1.0,
                                absl::FromUnixSeconds(1700000200))
                .status()
                .code(),
            absl::StatusCode::kDataLoss);
}

// Pages end by size as well as by count, never empty, and still cover
// everything.
TEST_P(EventStoreTest, PagesEndByBytesToo) {
  ASSERT_TRUE(store_->CreateUser(MakeUser("alice")).ok());
  for (int i = 0; i < 10; ++i) MustAppend(MakeEvent("alice", "m"));
  Page page;
  page.max_bytes = 500;  // an event here is about 160 bytes
  int pages = 0, seen = 0;
  do {
    auto result = store_->ListEvents("alice", "", page);
    ASSERT_TRUE(result.ok()) << result.status();
    EXPECT_GE(result->items.size(), 1u);
    EXPECT_LE(result->items.size(), 4u);
    seen += static_cast<int>(result->items.size());
    page.page_token = result->next_page_token;
    ++pages;
  } while (!page.page_token.empty());
  EXPECT_EQ(seen, 10);
  EXPECT_GE(pages, 3);
  page.page_token.clear();
  page.max_bytes = 1;  // smaller than any event: one per page
  auto one = store_->ListEvents("alice", "", page);
  ASSERT_TRUE(one.ok());
  EXPECT_EQ(one->items.size(), 1u);
  EXPECT_FALSE(one->next_page_token.empty());

  ASSERT_TRUE(store_->CreateUser(MakeUser("bob")).ok());
  Page users;
  users.max_bytes = 1;
  auto first = store_->ListUsers(users);
  ASSERT_TRUE(first.ok());
  EXPECT_EQ(first->items.size(), 1u);
  EXPECT_FALSE(first->next_page_token.empty());
}

TEST_P(EventStoreTest, WriteStatsCountTheHotPath) {
  // The commit observer (the service's histograms) sees every commit the
  // counters count.
  std::atomic<int64_t> observed_commits{0}, observed_writes{0};
  store_->SetCommitObserver([&](double seconds, int64_t writes) {
    EXPECT_GE(seconds, 0.0);
    ++observed_commits;
    observed_writes += writes;
  });
  ASSERT_TRUE(store_->CreateUser(MakeUser("alice")).ok());
  const int64_t id = MustAppend(MakeEvent("alice", "m"));
  MustAppend(MakeEvent("alice", "m"));
  ASSERT_TRUE(store_
                  ->CompleteEvent(id, 1.0, {0.5, 0.5}, 1.0,
                                  absl::FromUnixSeconds(1700000100))
                  .ok());
  // A refused completion is not a write.
  EXPECT_FALSE(store_
                   ->CompleteEvent(id, 1.0, {0.5, 0.5}, 1.0,
                                   absl::FromUnixSeconds(1700000100))
                   .ok());
  const StoreWriteStats stats = store_->write_stats();
  EXPECT_EQ(stats.appends, 2);
  EXPECT_EQ(stats.completions, 1);
  EXPECT_GT(stats.append_seconds, 0.0);
  EXPECT_GT(stats.completion_seconds, 0.0);
  EXPECT_GE(stats.commits, 1);
  EXPECT_EQ(observed_commits.load(), stats.commits);
  EXPECT_EQ(observed_writes.load(), stats.committed_writes);
}

TEST_P(EventStoreTest, AuditEntriesAreKeptAndPaged) {
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

TEST_P(EventStoreTest, CheckStoreReadsEverythingAndNamesWhatIsWrong) {
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
TEST_P(EventStoreTest, MissingActionNameIsDataLoss) {
  ASSERT_TRUE(store_->CreateUser(MakeUser("alice")).ok());
  Raw().Exec("DELETE FROM user_actions WHERE action = 2");
  auto user = store_->GetUser("alice");
  EXPECT_EQ(user.status().code(), absl::StatusCode::kDataLoss);
  EXPECT_THAT(user.status().message(), HasSubstr("alice"));
  EXPECT_THAT(user.status().message(), HasSubstr("action 2"));
}

TEST_F(SqliteEventStoreTest, ForeignDatabaseIsFailedPreconditionAndUntouched) {
  const std::string path = dir_ + "/other.db";
  RawDb(path).Exec("CREATE TABLE notes (text TEXT)");
  SqliteStoreOptions options;
  options.path = path;
  auto store = SqliteEventStore::Open(options);
  EXPECT_EQ(store.status().code(), absl::StatusCode::kFailedPrecondition)
      << store.status();
  EXPECT_THAT(store.status().message(), HasSubstr(path));
  RawDb raw(path);
  EXPECT_EQ(raw.Text("PRAGMA journal_mode"), "delete");
  EXPECT_EQ(raw.Text("SELECT COUNT(*) FROM sqlite_schema"), "1");
}

TEST_F(SqliteEventStoreTest, OpenRejectsEmptyPathAndAcceptsMemory) {
  EXPECT_EQ(SqliteEventStore::Open(SqliteStoreOptions()).status().code(),
            absl::StatusCode::kInvalidArgument);
  SqliteStoreOptions memory;
  memory.path = ":memory:";
  auto store = SqliteEventStore::Open(memory);
  ASSERT_TRUE(store.ok()) << store.status();
  EXPECT_TRUE((*store)->CreateUser(MakeUser("alice")).ok());
}

TEST_P(EventStoreTest, CorruptVectorIsDataLoss) {
  ASSERT_TRUE(store_->CreateUser(MakeUser("alice")).ok());
  const int64_t id = MustAppend(MakeEvent("alice", "m"));
  if (backend() == Backend::kSqliteContextFile) {
    // Seven bytes of the context in the contexts file.
    Raw().Exec(absl::StrCat(
        "UPDATE events SET context_bytes = 7 WHERE event_id = ", id));
  } else {
    Raw().Exec(absl::StrCat(
        "UPDATE event_contexts SET context = ", BlobLiteral("00010203040506"),
        " WHERE event_id = ", id));
  }
  auto event = store_->GetEvent(id);
  EXPECT_EQ(event.status().code(), absl::StatusCode::kDataLoss)
      << event.status();
  EXPECT_THAT(event.status().message(), HasSubstr("7 bytes"));
}

TEST_P(EventStoreTest, FailedCompletionRollsBackEverything) {
  ASSERT_TRUE(store_->CreateUser(MakeUser("alice")).ok());
  const int64_t id = MustAppend(MakeEvent("alice", "m"));
  // Fails the last write of the transaction, after model_version was bumped.
  RawSql& raw = Raw();
  if (sqlite()) {
    raw.Exec(
        "CREATE TRIGGER fail_completion BEFORE UPDATE OF completed ON events "
        "BEGIN SELECT RAISE(ABORT, 'injected failure'); END");
  } else {
    raw.Exec(
        "CREATE FUNCTION fail() RETURNS trigger LANGUAGE plpgsql AS $$ "
        "BEGIN RAISE EXCEPTION 'injected failure'; END $$; "
        "CREATE TRIGGER fail_completion BEFORE UPDATE OF completed ON events "
        "FOR EACH ROW EXECUTE FUNCTION fail()");
  }

  auto completed =
      store_->CompleteEvent(id, 1.0, {0.5, 0.5}, 1.0, absl::FromUnixMicros(1));
  ASSERT_FALSE(completed.ok());
  EXPECT_THAT(completed.status().message(), HasSubstr("CompleteEvent"));
  EXPECT_THAT(completed.status().message(), HasSubstr("injected failure"));
  EXPECT_EQ(MustGetUser("alice").model_version, 0);
  EXPECT_FALSE(MustGetEvent(id).completed);

  raw.Exec(sqlite() ? "DROP TRIGGER fail_completion"
                    : "DROP TRIGGER fail_completion ON events");
  EXPECT_EQ(MustComplete(id).model_version, 1);
}

// A context of 600 doubles (4,800 bytes): over the contexts file's
// threshold as shipped.
EventRecord LargeEvent(const std::string& user_id, double x) {
  EventRecord event = MakeEvent(user_id, "m", x);
  event.context.assign(600, x);
  event.context[1] = -0.0;
  return event;
}

std::string FileBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

TEST_F(SqliteEventStoreTest, LargeContextsLiveInTheContextsFile) {
  // New files have 1 KB pages; large contexts go to "<db>.contexts", each
  // at a 4 KB boundary, and read back bit for bit, also after a restart.
  EXPECT_EQ(RawDb(path_).Text("PRAGMA page_size"), "1024");
  const std::string file = path_ + ".contexts";
  ASSERT_TRUE(store_->CreateUser(MakeUser("ann")).ok());
  const int64_t small = MustAppend(MakeEvent("ann", "m"));
  const int64_t first = MustAppend(LargeEvent("ann", 0.5));
  const int64_t second = MustAppend(LargeEvent("ann", 1.5));
  MustComplete(first);
  {
    RawDb raw(path_);
    EXPECT_EQ(raw.Text("SELECT COUNT(*) FROM event_contexts"), "1");
    EXPECT_EQ(raw.Text(absl::StrCat(
                  "SELECT context_offset IS NULL FROM events WHERE event_id = ",
                  small)),
              "1");
    EXPECT_EQ(raw.Text(absl::StrCat("SELECT (context_offset % 4096) || ' ' || "
                                    "context_bytes FROM events WHERE "
                                    "event_id = ",
                                    second)),
              "0 4800");
  }
  EXPECT_EQ(FileBytes(file).substr(0, 16), "bitewise ctx v1\n");
  EXPECT_EQ(
      std::filesystem::status(file).permissions() & std::filesystem::perms::all,
      std::filesystem::perms::owner_read | std::filesystem::perms::owner_write);
  store_ = nullptr;
  store_ = OpenStore();
  ASSERT_NE(store_, nullptr);
  const EventRecord read = MustGetEvent(second);
  ASSERT_EQ(read.context.size(), 600u);
  EXPECT_EQ(read.context[0], 1.5);
  EXPECT_TRUE(std::signbit(read.context[1]));
  EXPECT_EQ(MustGetEvent(first).context, LargeEvent("ann", 0.5).context);
  auto log = store_->CompletedEvents("ann");
  ASSERT_TRUE(log.ok());
  ASSERT_EQ(log->size(), 1u);
  EXPECT_EQ((*log)[0].context, LargeEvent("ann", 0.5).context);
  // A new context goes after everything before the restart.
  const int64_t third = MustAppend(LargeEvent("ann", 2.5));
  EXPECT_EQ(MustGetEvent(second).context, LargeEvent("ann", 1.5).context);
  EXPECT_EQ(MustGetEvent(third).context, LargeEvent("ann", 2.5).context);
  auto check = store_->CheckStore();
  ASSERT_TRUE(check.ok()) << check.status();
  EXPECT_THAT(check->findings, IsEmpty());
}

TEST_F(SqliteEventStoreTest, AMissingOrForeignContextsFileIsRefused) {
  const std::string file = path_ + ".contexts";
  ASSERT_TRUE(store_->CreateUser(MakeUser("ann")).ok());
  MustAppend(LargeEvent("ann", 0.5));
  store_ = nullptr;
  const std::string kept = FileBytes(file);
  // Missing while the database points into it: refused, naming it.
  std::filesystem::remove(file);
  auto missing = TryOpenStore();
  EXPECT_EQ(missing.status().code(), absl::StatusCode::kDataLoss);
  EXPECT_THAT(missing.status().message(), HasSubstr(file));
  EXPECT_THAT(missing.status().message(), HasSubstr("missing"));
  EXPECT_FALSE(std::filesystem::exists(file));  // not made up anew
  // Not ours: refused, untouched.
  std::ofstream(file, std::ios::binary) << "some other file's bytes";
  auto foreign = TryOpenStore();
  EXPECT_EQ(foreign.status().code(), absl::StatusCode::kDataLoss);
  EXPECT_THAT(foreign.status().message(),
              HasSubstr("is not a bitewise contexts file"));
  EXPECT_EQ(FileBytes(file), "some other file's bytes");
  // Put back: served again.
  std::ofstream(file, std::ios::binary | std::ios::trunc) << kept;
  store_ = OpenStore();
  ASSERT_NE(store_, nullptr);
  EXPECT_EQ(MustGetUser("ann").pending_events, 1);
  // A new store's file is made under a temporary name: one left by a crash
  // during that is replaced, and never taken for the file.
  store_ = nullptr;
  const std::string fresh = dir_ + "/fresh.db";
  std::ofstream(fresh + ".contexts.new", std::ios::binary) << "half";
  SqliteStoreOptions options;
  options.path = fresh;
  auto made = SqliteEventStore::Open(options);
  ASSERT_TRUE(made.ok()) << made.status();
  EXPECT_EQ(FileBytes(fresh + ".contexts"), "bitewise ctx v1\n");
  EXPECT_FALSE(std::filesystem::exists(fresh + ".contexts.new"));
}

TEST_F(SqliteEventStoreTest, ADamagedContextIsDataLossNamingTheEvent) {
  const std::string file = path_ + ".contexts";
  ASSERT_TRUE(store_->CreateUser(MakeUser("ann")).ok());
  const int64_t kept = MustAppend(LargeEvent("ann", 0.5));
  const int64_t cut = MustAppend(LargeEvent("ann", 1.5));
  // The file loses its end (a torn copy): the last context reads short.
  std::filesystem::resize_file(file, std::filesystem::file_size(file) - 100);
  auto event = store_->GetEvent(cut);
  EXPECT_EQ(event.status().code(), absl::StatusCode::kDataLoss);
  EXPECT_THAT(event.status().message(), HasSubstr(absl::StrCat("event ", cut)));
  EXPECT_EQ(MustGetEvent(kept).context, LargeEvent("ann", 0.5).context);
  auto check = store_->CheckStore();
  ASSERT_TRUE(check.ok()) << check.status();
  ASSERT_EQ(check->findings.size(), 1u);
  EXPECT_THAT(check->findings[0], HasSubstr(absl::StrCat("event ", cut)));
  // New contexts never land where the lost one was.
  const int64_t next = MustAppend(LargeEvent("ann", 2.5));
  EXPECT_EQ(MustGetEvent(next).context, LargeEvent("ann", 2.5).context);
  EXPECT_EQ(store_->GetEvent(cut).status().code(), absl::StatusCode::kDataLoss);
  // A row claiming a petabyte reads what the file holds, and is DATA_LOSS.
  RawDb(path_).Exec(absl::StrCat(
      "UPDATE events SET context_bytes = 1000000000000000 WHERE event_id = ",
      kept));
  EXPECT_EQ(store_->GetEvent(kept).status().code(),
            absl::StatusCode::kDataLoss);
}

// The first bytes of `event`'s context as the contexts file holds them.
std::string ContextPrefix(const EventRecord& event) {
  std::string bytes(64, '\0');
  std::memcpy(bytes.data(), event.context.data(), bytes.size());
  return bytes;
}

TEST_F(SqliteEventStoreTest, UnreferencedContextsAreErasedAtOpen) {
  // A write that did not commit (here: for a user that does not exist)
  // leaves its context in the file, unreferenced, until the next open.
  const std::string file = path_ + ".contexts";
  ASSERT_TRUE(store_->CreateUser(MakeUser("ann")).ok());
  const int64_t kept = MustAppend(LargeEvent("ann", 0.5));
  EXPECT_EQ(store_->AppendPending(LargeEvent("ghost", 3.75)).status().code(),
            absl::StatusCode::kNotFound);
  const int64_t after = MustAppend(LargeEvent("ann", 1.25));
  EXPECT_NE(FileBytes(file).find(ContextPrefix(LargeEvent("ghost", 3.75))),
            std::string::npos);
  store_ = nullptr;
  store_ = OpenStore();
  ASSERT_NE(store_, nullptr);
  EXPECT_EQ(FileBytes(file).find(ContextPrefix(LargeEvent("ghost", 3.75))),
            std::string::npos);
  EXPECT_EQ(MustGetEvent(kept).context, LargeEvent("ann", 0.5).context);
  EXPECT_EQ(MustGetEvent(after).context, LargeEvent("ann", 1.25).context);
  const int64_t next = MustAppend(LargeEvent("ann", 2.0));
  EXPECT_EQ(MustGetEvent(next).context, LargeEvent("ann", 2.0).context);
}

TEST_F(SqliteEventStoreTest, DeletedUsersContextsAreErasedFromTheFile) {
  const std::string file = path_ + ".contexts";
  ASSERT_TRUE(store_->CreateUser(MakeUser("ann")).ok());
  ASSERT_TRUE(store_->CreateUser(MakeUser("bob")).ok());
  const int64_t anns = MustAppend(LargeEvent("ann", 0.5));
  const int64_t bobs = MustAppend(LargeEvent("bob", 7.25));
  const int64_t anns_second = MustAppend(LargeEvent("ann", 0.75));
  auto where = [&](int64_t id) {
    const int64_t offset = std::stoll(RawDb(path_).Text(absl::StrCat(
        "SELECT context_offset FROM events WHERE event_id = ", id)));
    return FileBytes(file).substr(static_cast<size_t>(offset), 4800);
  };
  const std::string anns_bytes = where(anns);
  const std::string anns_second_bytes = where(anns_second);
  ASSERT_NE(anns_bytes, std::string(4800, '\0'));
  const std::string bobs_bytes = where(bobs);
  // The file's bytes, to find ann's afterwards.
  ASSERT_TRUE(store_->ResetUser("ann").ok());
  const std::string after_reset = FileBytes(file);
  EXPECT_EQ(after_reset.find(anns_bytes), std::string::npos);
  EXPECT_EQ(after_reset.find(anns_second_bytes), std::string::npos);
  EXPECT_NE(after_reset.find(bobs_bytes), std::string::npos);
  EXPECT_EQ(MustGetEvent(bobs).context, LargeEvent("bob", 7.25).context);
  ASSERT_TRUE(store_->DeleteUser("bob").ok());
  EXPECT_EQ(FileBytes(file).find(bobs_bytes), std::string::npos);
}

TEST_F(SqliteEventStoreTest, AReplacedContextsFileFailsHealth) {
  const std::string file = path_ + ".contexts";
  ASSERT_TRUE(store_->CreateUser(MakeUser("ann")).ok());
  MustAppend(LargeEvent("ann", 0.5));
  EXPECT_TRUE(store_->CheckHealth().ok());
  const std::string kept = FileBytes(file);
  std::filesystem::remove(file);
  std::ofstream(file, std::ios::binary) << kept;
  const absl::Status health = store_->CheckHealth();
  EXPECT_EQ(health.code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(health.message(), HasSubstr(file));
  // Writes are refused rather than acknowledged into the old file.
  EXPECT_EQ(store_->AppendPending(LargeEvent("ann", 1.0)).status().code(),
            absl::StatusCode::kFailedPrecondition);
}

TEST_F(SqliteEventStoreTest, LockHeldElsewhereIsUnavailable) {
  ASSERT_TRUE(store_->CreateUser(MakeUser("alice")).ok());
  const int64_t id = MustAppend(MakeEvent("alice", "m"));
  store_.reset();
  SqliteStoreOptions options;
  options.path = path_;
  options.busy_timeout = absl::Milliseconds(50);
  auto store = SqliteEventStore::Open(options);
  ASSERT_TRUE(store.ok()) << store.status();
  store_ = std::move(store).value();

  RawDb raw(path_);
  raw.Exec("BEGIN IMMEDIATE");
  auto completed =
      store_->CompleteEvent(id, 1.0, {}, 1.0, absl::FromUnixMicros(1));
  EXPECT_EQ(completed.status().code(), absl::StatusCode::kUnavailable)
      << completed.status();
  // Readers are not blocked by a writer in WAL mode.
  EXPECT_FALSE(MustGetEvent(id).completed);
  raw.Exec("ROLLBACK");
  EXPECT_EQ(MustComplete(id).model_version, 1);
}

TEST_P(EventStoreTest, ConcurrentWritersKeepCountsRight) {
  constexpr int kThreads = 4;
  constexpr int kRounds = 20;
  ASSERT_TRUE(store_->CreateUser(MakeUser("shared")).ok());
  for (int t = 0; t < kThreads; ++t) {
    ASSERT_TRUE(store_->CreateUser(MakeUser(absl::StrCat("user", t))).ok());
  }
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t) {
    threads.emplace_back([this, t] {
      const std::string own = absl::StrCat("user", t);
      for (int i = 0; i < kRounds; ++i) {
        // Per round on its own user: two selections, one update.
        const int64_t id = MustAppend(MakeEvent(own, "m", i));
        MustAppend(MakeEvent(own, "m", i));
        MustComplete(id);
        // And on the user every thread shares.
        MustComplete(MustAppend(MakeEvent("shared", "m", i)));
      }
    });
  }
  for (std::thread& thread : threads) thread.join();

  for (int t = 0; t < kThreads; ++t) {
    const UserRecord user = MustGetUser(absl::StrCat("user", t));
    EXPECT_EQ(user.model_version, kRounds);
    EXPECT_EQ(user.pending_events, kRounds);
  }
  const UserRecord shared = MustGetUser("shared");
  EXPECT_EQ(shared.model_version, kThreads * kRounds);
  EXPECT_EQ(shared.pending_events, 0);
  auto log = store_->CompletedEvents("shared");
  ASSERT_TRUE(log.ok()) << log.status();
  ASSERT_EQ(log->size(), static_cast<size_t>(kThreads * kRounds));
  for (size_t i = 0; i < log->size(); ++i) {
    EXPECT_EQ((*log)[i].model_version, static_cast<int64_t>(i + 1));
  }
}

// What only the PostgreSQL store has: its schema checks against a shared
// server, and a server that goes away and comes back.
class PostgresEventStoreTest : public StoreTestBase {
 protected:
  Backend backend() const override { return Backend::kPostgres; }
};

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
  // A store of schema 1 (before the selections count): opening it adds the
  // count from each user's log and drops the lock function.
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
      "ALTER TABLE users DROP COLUMN selections; CREATE FUNCTION "
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
            "2 true");
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

TEST_F(PostgresEventStoreTest, AStoppedServerIsUnavailableAndTheStoreRecovers) {
  // A server of its own, to stop.
  auto own = testing::TestPostgres::Create();
  ASSERT_TRUE(own.ok()) << own.status();
  testing::TestPostgres& server = **own;
  auto conninfo = server.CreateDatabase("facility");
  ASSERT_TRUE(conninfo.ok()) << conninfo.status();
  PostgresStoreOptions options;
  options.conninfo = *conninfo;
  options.connections = 2;
  auto opened = PostgresEventStore::Open(options);
  ASSERT_TRUE(opened.ok()) << opened.status();
  PostgresEventStore& store = **opened;
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

}  // namespace
}  // namespace bitewise::bandit

namespace bitewise::bandit {
namespace {

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
}  // namespace bitewise::bandit
