// Store locations (open_store.h): each form opens the store it names, on a
// real SQLite file and a real PostgreSQL server, only creating one when
// asked; and what of a location may be logged.
#include "services/bandit/store/open_store.h"

#include <stdlib.h>

#include <filesystem>
#include <memory>
#include <string>

#include "absl/strings/str_cat.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "tests/bandit/store/store_test_fixture.h"
#include "tests/common/postgres_server.h"
#include "tests/common/status_matchers.h"

namespace bitewise::bandit {
namespace {

using ::bitewise::testing::IsOk;
using ::bitewise::testing::StatusIs;
using ::testing::HasSubstr;
using ::testing::Not;

class OpenEventStoreTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string base = ::testing::TempDir();
    if (base.empty() || base.back() != '/') base += '/';
    std::string pattern = base + "open_store_XXXXXX";
    ASSERT_NE(mkdtemp(pattern.data()), nullptr) << pattern;
    dir_ = pattern;
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  std::string dir_;
};

TEST_F(OpenEventStoreTest, AnEmptyLocationIsInvalidArgument) {
  OpenStoreOptions options;
  options.create_if_missing = true;
  EXPECT_THAT(OpenEventStore("", options),
              StatusIs(absl::StatusCode::kInvalidArgument,
                       HasSubstr("the store location is empty")));
}

TEST_F(OpenEventStoreTest, SqliteLocationsWithOrWithoutThePrefixAreOneFile) {
  const std::string path = dir_ + "/bandit.db";
  OpenStoreOptions options;
  // Not there, and not asked to create it: refused, and nothing made.
  EXPECT_THAT(OpenEventStore("sqlite:" + path, options),
              StatusIs(absl::StatusCode::kFailedPrecondition,
                       HasSubstr("pass --create")));
  EXPECT_FALSE(std::filesystem::exists(path));

  options.create_if_missing = true;
  {
    absl::StatusOr<std::unique_ptr<EventStore>> store =
        OpenEventStore("sqlite:" + path, options);
    ASSERT_THAT(store, IsOk());
    ASSERT_THAT((*store)->CreateUser(store_test::MakeUser("ann")), IsOk());
  }
  EXPECT_TRUE(std::filesystem::exists(path));
  options.create_if_missing = false;
  options.defer_full_check = true;
  absl::StatusOr<std::unique_ptr<EventStore>> again =
      OpenEventStore(path, options);
  ASSERT_THAT(again, IsOk());
  ASSERT_THAT((*again)->RunDeferredChecks(), IsOk());
  absl::StatusOr<UserRecord> ann = (*again)->GetUser("ann");
  ASSERT_THAT(ann, IsOk());
  EXPECT_EQ(ann->config.context_dim, store_test::SmallConfig().context_dim);
}

TEST_F(OpenEventStoreTest, APostgresUriOpensThePostgresStore) {
  ::bitewise::testing::TestPostgres* server =
      ::bitewise::testing::SharedTestPostgres();
  ASSERT_NE(server, nullptr);
  absl::StatusOr<std::string> conninfo =
      server->CreateDatabase("open_store_test");
  ASSERT_THAT(conninfo, IsOk());
  ASSERT_TRUE(IsPostgresSpec(*conninfo)) << *conninfo;
  OpenStoreOptions options;
  options.postgres_connections = 2;
  // An empty database becomes a store only when asked for.
  EXPECT_THAT(
      OpenEventStore(*conninfo, options),
      StatusIs(absl::StatusCode::kFailedPrecondition, HasSubstr("--create")));
  EXPECT_EQ(
      *server->Query("open_store_test", "SELECT to_regclass('users') IS NULL"),
      "t");
  options.create_if_missing = true;
  {
    absl::StatusOr<std::unique_ptr<EventStore>> store =
        OpenEventStore(*conninfo, options);
    ASSERT_THAT(store, IsOk());
    ASSERT_THAT((*store)->CreateUser(store_test::MakeUser("bo")), IsOk());
  }
  EXPECT_EQ(*server->Query("open_store_test",
                           "SELECT user_id FROM users WHERE user_id = 'bo'"),
            "bo");
  // The other spelling of the scheme is the same store.
  std::string postgres = *conninfo;
  postgres.replace(0, std::string("postgresql").size(), "postgres");
  ASSERT_TRUE(IsPostgresSpec(postgres)) << postgres;
  options.create_if_missing = false;
  absl::StatusOr<std::unique_ptr<EventStore>> again =
      OpenEventStore(postgres, options);
  ASSERT_THAT(again, IsOk());
  absl::StatusOr<UserRecord> bo = (*again)->GetUser("bo");
  ASSERT_THAT(bo, IsOk());
  EXPECT_EQ(bo->user_id, "bo");
  again->reset();
  server->Query("postgres", "DROP DATABASE open_store_test").IgnoreError();
}

// libpq's key=value form is not taken for a SQLite file: refused, not
// echoed (it may hold a password), and no file is made even with create.
TEST(OpenStoreLocationTest, LibpqKeyValueFormIsRefusedWithoutEchoingIt) {
  OpenStoreOptions options;
  options.create_if_missing = true;
  for (const std::string spec :
       {"host=db dbname=bitewise password=s3cret", "dbname=x",
        "port=5432 user=bw password=s3cret"}) {
    absl::StatusOr<std::unique_ptr<EventStore>> store =
        OpenEventStore(spec, options);
    EXPECT_EQ(store.status().code(), absl::StatusCode::kInvalidArgument)
        << spec;
    EXPECT_THAT(store.status().message(), HasSubstr("key=value form"));
    EXPECT_THAT(store.status().message(), Not(HasSubstr("s3cret")));
    EXPECT_FALSE(std::filesystem::exists(spec)) << spec;  // relative
    std::filesystem::remove(spec);
  }
}

TEST(DescribeStoreSpecTest, EveryPasswordIsHiddenAndNothingElse) {
  EXPECT_EQ(
      DescribeStoreSpec("postgresql://bw:s3cret@db:5432/bitewise?password=x&"
                        "sslmode=require&password=y"),
      "postgresql://bw:***@db:5432/bitewise?password=***&sslmode=require&"
      "password=***");
  EXPECT_EQ(DescribeStoreSpec("postgres://:pw@db"), "postgres://:***@db");
  // The client key's passphrase is one too; not a password: another key
  // ending in it, a colon after the host.
  EXPECT_EQ(DescribeStoreSpec("postgresql://db:5432/x?sslpassword=pp"),
            "postgresql://db:5432/x?sslpassword=***");
  EXPECT_EQ(DescribeStoreSpec("postgresql://db/x?oldpassword=keep"),
            "postgresql://db/x?oldpassword=keep");
  EXPECT_EQ(DescribeStoreSpec("postgresql://db/x?user=a@b"),
            "postgresql://db/x?user=a@b");
  EXPECT_EQ(DescribeStoreSpec("bandit.db"), "bandit.db");
  EXPECT_FALSE(IsPostgresSpec("sqlite:postgresql://x"));
  EXPECT_FALSE(IsPostgresSpec("mysql://db/x"));
  EXPECT_TRUE(IsPostgresSpec("postgresql://"));
}

}  // namespace
}  // namespace bitewise::bandit
