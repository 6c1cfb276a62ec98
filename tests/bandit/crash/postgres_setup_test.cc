// The PostgreSQL setup that docs/operations.md gives a facility's engineer,
// tried on a real server whose pg_hba.conf is Debian's kind (no trust): a
// role with a password and the password in the service account's password
// file (PGPASSFILE, as a remote server needs), and a role named after the
// service's OS account with peer authentication on the server's socket (a
// server on the same machine). Each starts the real bitewise-bandit with
// --create and serves; without the password file the start fails naming
// the authentication.
#include <pwd.h>
#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "tests/bandit/crash/bandit_process.h"
#include "tests/common/postgres_server.h"

namespace bitewise {
namespace {

using ::testing::HasSubstr;

class PostgresSetupTest : public ::testing::Test {
 protected:
  void SetUp() override {
    absl::StatusOr<std::unique_ptr<testing::TestPostgres>> pg =
        testing::TestPostgres::Create();
    ASSERT_TRUE(pg.ok()) << pg.status();
    pg_ = *std::move(pg);
    // The test's own superuser keeps trust; the service's roles do not.
    const passwd* me = getpwuid(geteuid());
    ASSERT_NE(me, nullptr);
    me_ = me->pw_name;
    std::ofstream(pg_->dir() + "/data/pg_hba.conf")
        << "local all bitewise trust\n"
        << "local all app scram-sha-256\n"
        << "local all " << me_ << " peer\n";
    for (const std::string& sql :
         {std::string("CREATE ROLE app LOGIN PASSWORD 'a secret'"),
          std::string("CREATE DATABASE appdb OWNER app"),
          absl::StrCat("CREATE ROLE \"", me_, "\" LOGIN"),
          absl::StrCat("CREATE DATABASE peerdb OWNER \"", me_, "\""),
          std::string("SELECT pg_reload_conf()")}) {
      absl::StatusOr<std::string> done = pg_->Query("postgres", sql);
      ASSERT_TRUE(done.ok()) << sql << ": " << done.status();
    }
    std::string pattern =
        (std::filesystem::temp_directory_path() / "pg_setup_test.XXXXXX")
            .string();
    ASSERT_NE(mkdtemp(pattern.data()), nullptr);
    dir_ = pattern;
  }

  void TearDown() override {
    server_.Kill();
    std::error_code ignored;
    std::filesystem::remove_all(dir_, ignored);
  }

  // The socket directory and port of the test's server, as a URI's query.
  std::string Socket() const {
    return absl::StrCat("host=", pg_->dir(), "&port=5432");
  }

  // Creates a user through the service: the store takes writes.
  void ExpectServes() {
    v1::CreateUserRequest create;
    create.set_user_id("setup");
    create.mutable_config()->set_context_dim(4);
    absl::StatusOr<v1::User> user =
        Call(server_.stub(), &v1::BanditService::Stub::CreateUser, create);
    EXPECT_TRUE(user.ok()) << user.status();
  }

  std::unique_ptr<testing::TestPostgres> pg_;
  std::string me_;
  std::string dir_;
  ServerProcess server_;
};

TEST_F(PostgresSetupTest, APasswordRoleServesWithItsPasswordFile) {
  const std::string db = absl::StrCat("postgresql://app@/appdb?", Socket());
  const std::string log = dir_ + "/no-password.log";
  absl::Status refused = server_.Start(db, log);
  ASSERT_FALSE(refused.ok());
  const std::string said = testing::ReadFile(log);
  EXPECT_THAT(said, HasSubstr("cannot open the event store"));
  EXPECT_THAT(said, HasSubstr("password"));
  std::cout << said;
  // One line, without libpq's "FATAL:" prefix.
  EXPECT_THAT(said, ::testing::Not(HasSubstr("FATAL:")));

  // The documented fix: the password in a file only its owner can read.
  const std::string pgpass = dir_ + "/pgpass";
  std::ofstream(pgpass) << "*:*:appdb:app:a secret\n";
  ASSERT_EQ(chmod(pgpass.c_str(), 0600), 0);
  absl::Status started = server_.Start(db, dir_ + "/password.log",
                                       {absl::StrCat("PGPASSFILE=", pgpass)});
  ASSERT_TRUE(started.ok()) << started;
  ExpectServes();
}

TEST_F(PostgresSetupTest, APeerRoleServesOnTheSocketWithoutAPassword) {
  absl::Status started = server_.Start(
      absl::StrCat("postgresql:///peerdb?", Socket()), dir_ + "/peer.log");
  ASSERT_TRUE(started.ok()) << started;
  ExpectServes();
}

}  // namespace
}  // namespace bitewise
