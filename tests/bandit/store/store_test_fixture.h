// The store contract tests' fixture (tests/bandit/store): a fresh store of
// each backend (a SQLite file in a temporary directory, the same with every
// context in the contexts file, a database on a real PostgreSQL server the
// test starts itself, tests/common/postgres_server.h), raw access to its
// tables for tampering and inspection, and helpers. The contract is split
// by the store's roles (event_log_contract_test.cc,
// checkpoint_contract_test.cc, pools_audit_contract_test.cc), each run on
// every backend; what one store has alone is in sqlite_store_test.cc and
// postgres_store_test.cc.
#ifndef BITEWISE_TESTS_BANDIT_STORE_STORE_TEST_FIXTURE_H_
#define BITEWISE_TESTS_BANDIT_STORE_STORE_TEST_FIXTURE_H_

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

namespace bitewise::bandit::store_test {

using ::testing::ElementsAre;
using ::testing::HasSubstr;
using ::testing::IsEmpty;

inline std::vector<uint64_t> Bits(const std::vector<double>& values) {
  std::vector<uint64_t> bits(values.size());
  std::memcpy(bits.data(), values.data(), values.size() * sizeof(double));
  return bits;
}

inline uint64_t Bits(double value) {
  return Bits(std::vector<double>{value})[0];
}

inline double FromBits(uint64_t bits) {
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

inline BanditConfig SmallConfig() {
  BanditConfig config;
  config.context_dim = 3;
  config.posthoc_dim = 2;
  return config;
}

inline UserRecord MakeUser(const std::string& user_id) {
  UserRecord user;
  user.user_id = user_id;
  user.config = SmallConfig();
  user.created_at = absl::FromUnixMicros(1700000000123456);
  return user;
}

inline EventRecord MakeEvent(const std::string& user_id,
                             const std::string& meal_id, double x = 0.5) {
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

inline std::string BackendName(const ::testing::TestParamInfo<Backend>& info) {
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

inline PopulationPrior SmallPrior(int64_t version, double rounds) {
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

// A context of 600 doubles (4,800 bytes): over the contexts file's
// threshold as shipped.
inline EventRecord LargeEvent(const std::string& user_id, double x) {
  EventRecord event = MakeEvent(user_id, "m", x);
  event.context.assign(600, x);
  event.context[1] = -0.0;
  return event;
}

inline std::string FileBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

// The contract on every backend.
class StoreContractTest : public StoreTestBase,
                          public ::testing::WithParamInterface<Backend> {
 protected:
  Backend backend() const override { return GetParam(); }
};

inline const auto kAllBackends = ::testing::Values(
    Backend::kSqlite, Backend::kSqliteContextFile, Backend::kPostgres);

// What only the SQLite store has: its file, its lock, its migrations.
class SqliteEventStoreTest : public StoreTestBase {
 protected:
  Backend backend() const override { return Backend::kSqlite; }
};

// What only the PostgreSQL store has: its schema checks against a shared
// server, and a server that goes away and comes back.
class PostgresEventStoreTest : public StoreTestBase {
 protected:
  Backend backend() const override { return Backend::kPostgres; }
};

}  // namespace bitewise::bandit::store_test

#endif  // BITEWISE_TESTS_BANDIT_STORE_STORE_TEST_FIXTURE_H_
