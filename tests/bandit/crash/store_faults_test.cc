// Storage that refuses writes, under the real bitewise-bandit binary on
// SQLite: a full disk, an I/O error and a read-only file (injected beneath
// the store's own code by the write-fault injector, tests/common), a real
// file-size limit (setrlimit on the running process) and a real immutable
// file (chattr +i, where the file system and the test's privileges allow).
// For each: the failing Update answers RESOURCE_EXHAUSTED or UNAVAILABLE
// naming the cause and the file, never INTERNAL; health turns NOT_SERVING
// within 1 s and back to SERVING within 1 s of the storage taking writes
// again, with no restart; the refused update is then accepted; nothing
// acknowledged is lost across a SIGKILL; the store checks clean.
#include <fcntl.h>
#include <linux/fs.h>
#include <signal.h>
#include <sqlite3.h>
#include <stdlib.h>
#include <sys/ioctl.h>
#include <sys/resource.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "absl/time/time.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "tests/bandit/crash/bandit_process.h"
#include "tests/common/postgres_server.h"

namespace bitewise {
namespace {

using ::testing::HasSubstr;

// Health is polled at this pace (the service's own check runs every 0.5 s).
constexpr absl::Duration kPoll = absl::Milliseconds(20);
// The bound for both directions.
constexpr absl::Duration kHealthBound = absl::Seconds(1);
constexpr int kContextDim = 1024;  // 8 KB: kept in the contexts file
constexpr int kPosthocDim = 4;

// Random, so PostgreSQL cannot compress it into its row: it goes to new
// pages of the table's out-of-line storage.
std::vector<double> Context(int t) {
  std::mt19937_64 rng(static_cast<uint64_t>(t) + 1);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<double> x(kContextDim);
  for (double& v : x) v = 0.01 * u(rng);
  return x;
}
std::vector<double> Posthoc(int t) { return {0.1 * (t % 3), 0.2, 0.3, 0.4}; }

class StoreFaultsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string pattern =
        (std::filesystem::temp_directory_path() / "store_faults_test.XXXXXX")
            .string();
    ASSERT_NE(mkdtemp(pattern.data()), nullptr) << std::strerror(errno);
    dir_ = pattern;
    db_ = dir_ + "/bandit.db";
    control_ = dir_ + "/fault";
  }

  void TearDown() override {
    SetImmutable(false);
    if (HasFailure() && server_.running()) {
      absl::StatusOr<int> ended = server_.SignalAndWait(SIGKILL, kExitTimeout);
      if (ended.ok()) {
        std::cerr << "the server had ended: "
                  << testing::DescribeWaitStatus(*ended) << "\n";
      }
    }
    server_.Kill();
    if (HasFailure()) {
      for (int i = 0; i < starts_; ++i) {
        std::cerr << "---- server log " << i << "\n"
                  << testing::ReadFile(LogPath(i)) << "----\n";
      }
    }
    std::error_code ignored;
    std::filesystem::remove_all(dir_, ignored);
  }

  std::string LogPath(int start) const {
    return absl::StrCat(dir_, "/server-", start, ".log");
  }

  // With the write-fault injector loaded when `injector`; without
  // `wait_serving`, returns once it listens.
  absl::Status StartServer(bool injector, bool wait_serving = true) {
    std::vector<std::string> env;
    if (injector) {
      env = {absl::StrCat("LD_PRELOAD=", BITEWISE_WRITE_FAULT_INJECTOR),
             absl::StrCat("BITEWISE_WRITE_FAULT_FILE=", control_),
             absl::StrCat("BITEWISE_WRITE_FAULT_PREFIX=", db_),
             // A sanitizer build: its runtime need not come first.
             "ASAN_OPTIONS=verify_asan_link_order=0"};
    }
    return server_.Start(db_, LogPath(starts_++), env, wait_serving);
  }

  v1::BanditService::Stub& stub() { return server_.stub(); }

  // The user, then `rounds` acknowledged rounds.
  void Feed(int rounds) {
    v1::CreateUserRequest create;
    create.set_user_id("u");
    v1::UserConfig* config = create.mutable_config();
    config->set_learner(v1::LEARNER_POSTHOC);
    config->set_strategy(v1::STRATEGY_LINUCB);
    config->set_context_dim(kContextDim);
    config->set_posthoc_dim(kPosthocDim);
    config->set_alpha(0.1);
    config->set_lambda_c(1.0);
    config->set_lambda_p(1.0);
    config->set_seed(7);
    ASSERT_TRUE(
        Call(stub(), &v1::BanditService::Stub::CreateUser, create).ok());
    for (int t = 0; t < rounds; ++t) {
      absl::StatusOr<v1::SelectResponse> chosen =
          Select(stub(), "u", Context(t));
      ASSERT_TRUE(chosen.ok()) << chosen.status();
      ASSERT_TRUE(Update(stub(), chosen->event_id(), t % 2, Posthoc(t)).ok());
    }
  }

  // Polls health until it reports `want`; the time it took.
  absl::StatusOr<absl::Duration> TimeUntil(ServingStatus want,
                                           absl::Time since) {
    while (absl::Now() - since < absl::Seconds(10)) {
      absl::StatusOr<ServingStatus> health =
          CheckHealth(server_.channel(), kServiceName, absl::Seconds(2));
      if (health.ok() && *health == want) return absl::Now() - since;
      absl::SleepFor(kPoll);
    }
    return absl::DeadlineExceededError(
        absl::StrCat("health never reported ", ServingStatusName(want)));
  }

  // The scenario every fault goes through: `inject` makes the storage
  // refuse writes and `lift` ends it.
  //
  // The first write after `inject` is the pending event's Update, or (with
  // `select_first`) a Select: on PostgreSQL only a write that needs a new
  // page of a table reaches the server's disk at once, and an Update may
  // not. `store_name` is how messages name the store.
  void RefusedThenRecovered(const std::function<void()>& inject,
                            const std::function<void()>& lift,
                            absl::StatusCode code, const std::string& cause,
                            bool select_first = false,
                            std::string store_name = "") {
    if (store_name.empty()) store_name = db_;
    constexpr int kRounds = 6;
    ASSERT_NO_FATAL_FAILURE(Feed(kRounds));
    absl::StatusOr<v1::SelectResponse> pending =
        Select(stub(), "u", Context(kRounds));
    ASSERT_TRUE(pending.ok()) << pending.status();

    ASSERT_NO_FATAL_FAILURE(inject());
    const absl::Time failed_at = absl::Now();
    absl::Status refused =
        select_first
            ? Select(stub(), "u", Context(kRounds + 1)).status()
            : Update(stub(), pending->event_id(), 1.0, Posthoc(kRounds))
                  .status();
    ASSERT_FALSE(refused.ok());
    EXPECT_EQ(refused.code(), code) << refused;
    EXPECT_THAT(refused.message(), HasSubstr(cause));
    EXPECT_THAT(refused.message(), HasSubstr(store_name));
    absl::StatusOr<absl::Duration> down =
        TimeUntil(ServingStatus::kNotServing, failed_at);
    ASSERT_TRUE(down.ok()) << down.status();
    EXPECT_LT(*down, kHealthBound);
    std::cout << "NOT_SERVING after " << absl::FormatDuration(*down) << "\n";

    // Writes are refused with the same cause; reads still answer, and the
    // model did not run ahead of the store.
    absl::Status write =
        select_first
            ? Update(stub(), pending->event_id(), 1.0, Posthoc(kRounds))
                  .status()
            : Select(stub(), "u", Context(kRounds + 1)).status();
    ASSERT_FALSE(write.ok());
    EXPECT_EQ(write.code(), code) << write;
    EXPECT_THAT(write.message(), HasSubstr(cause));
    absl::StatusOr<v1::User> user = GetUser(stub(), "u");
    ASSERT_TRUE(user.ok()) << user.status();
    EXPECT_EQ(user->model_version(), kRounds);
    // The probe keeps failing while the fault lasts.
    absl::SleepFor(absl::Milliseconds(1200));
    absl::StatusOr<ServingStatus> still =
        CheckHealth(server_.channel(), kServiceName, absl::Seconds(2));
    ASSERT_TRUE(still.ok()) << still.status();
    EXPECT_EQ(*still, ServingStatus::kNotServing);

    ASSERT_NO_FATAL_FAILURE(lift());
    const absl::Time lifted_at = absl::Now();
    absl::StatusOr<absl::Duration> up =
        TimeUntil(ServingStatus::kServing, lifted_at);
    ASSERT_TRUE(up.ok()) << up.status();
    EXPECT_LT(*up, kHealthBound);
    std::cout << "SERVING again after " << absl::FormatDuration(*up) << "\n";

    // The refused update is taken now, and the service goes on.
    absl::StatusOr<v1::UpdateResponse> retried =
        Update(stub(), pending->event_id(), 1.0, Posthoc(kRounds));
    ASSERT_TRUE(retried.ok()) << retried.status();
    EXPECT_EQ(retried->model_version(), kRounds + 1);
    absl::StatusOr<v1::SelectResponse> next =
        Select(stub(), "u", Context(kRounds + 2));
    ASSERT_TRUE(next.ok()) << next.status();
    ASSERT_TRUE(
        Update(stub(), next->event_id(), 0.0, Posthoc(kRounds + 2)).ok());

    // Nothing acknowledged is lost, nothing is half-written.
    ASSERT_TRUE(server_.SignalAndWait(SIGKILL, kExitTimeout).ok());
    ASSERT_TRUE(StartServer(/*injector=*/false).ok());
    user = GetUser(stub(), "u");
    ASSERT_TRUE(user.ok()) << user.status();
    EXPECT_EQ(user->model_version(), kRounds + 2);
    EXPECT_EQ(user->pending_events(), 0);
    absl::StatusOr<v1::CheckStoreResponse> check = Call(
        stub(), &v1::BanditService::Stub::CheckStore, v1::CheckStoreRequest());
    ASSERT_TRUE(check.ok()) << check.status();
    EXPECT_TRUE(check->ok()) << ::testing::PrintToString(check->findings());
  }

  void SetControl(const std::string& error) {
    std::ofstream(control_) << error;
  }
  void ClearControl() { std::filesystem::remove(control_); }

  // chattr +i / -i on the store's durable files (the database, its log
  // and its contexts file); false when the file system or the test's
  // privileges do not allow it. Not on "-shm": SQLite maps that index into
  // memory, and a store to a mapped page of a file turned immutable or
  // read-only is not an error but SIGBUS (docs/operations.md).
  bool SetImmutable(bool on) {
    for (const std::string& path : {db_, db_ + "-wal", db_ + ".contexts"}) {
      const int fd = open(path.c_str(), O_RDONLY | O_CLOEXEC);
      if (fd < 0) continue;
      int flags = 0;
      bool ok = ioctl(fd, FS_IOC_GETFLAGS, &flags) == 0;
      if (ok) {
        flags = on ? (flags | FS_IMMUTABLE_FL) : (flags & ~FS_IMMUTABLE_FL);
        ok = ioctl(fd, FS_IOC_SETFLAGS, &flags) == 0;
      }
      close(fd);
      if (!ok) return false;
    }
    return true;
  }

  std::string dir_;
  std::string db_;
  std::string control_;
  int starts_ = 0;
  ServerProcess server_;
};

// The start does not read the whole file (its time does not grow with it):
// SQLite's integrity check runs once the service listens, and the first
// write waits for it. A damaged file is then reported by health, named in
// the log, and never written, however long the service runs.
TEST_F(StoreFaultsTest, ADamagedFileIsNotServingAndTakesNoWrite) {
  ASSERT_TRUE(StartServer(/*injector=*/false).ok());
  ASSERT_NO_FATAL_FAILURE(Feed(60));
  // A clean stop folds the log into the database file.
  ASSERT_TRUE(server_.SignalAndWait(SIGTERM, kExitTimeout).ok());
  ASSERT_FALSE(std::filesystem::exists(db_ + "-wal"));
  // Garbage over the cell pointers of the event table's indexes' root pages
  // (found with SQLite itself, read-only). (Damage that the open itself
  // reads, such as the table's last page, stops the start at once.)
  std::vector<int64_t> roots;
  int64_t page_size = 0;
  {
    sqlite3* raw = nullptr;
    ASSERT_EQ(sqlite3_open_v2(db_.c_str(), &raw, SQLITE_OPEN_READONLY, nullptr),
              SQLITE_OK);
    sqlite3_stmt* st = nullptr;
    ASSERT_EQ(sqlite3_prepare_v2(raw,
                                 "SELECT rootpage, (SELECT page_size FROM "
                                 "pragma_page_size) FROM sqlite_schema WHERE "
                                 "tbl_name = 'events' AND type = 'index'",
                                 -1, &st, nullptr),
              SQLITE_OK);
    while (sqlite3_step(st) == SQLITE_ROW) {
      roots.push_back(sqlite3_column_int64(st, 0));
      page_size = sqlite3_column_int64(st, 1);
    }
    sqlite3_finalize(st);
    sqlite3_close(raw);
  }
  ASSERT_GE(roots.size(), 2u);
  {
    std::fstream file(db_, std::ios::in | std::ios::out | std::ios::binary);
    for (const int64_t root : roots) {
      file.seekp((root - 1) * page_size + 8);
      const std::string garbage(64, '\x5a');
      file.write(garbage.data(), garbage.size());
    }
  }
  const absl::Time started = absl::Now();
  ASSERT_TRUE(StartServer(/*injector=*/false, /*wait_serving=*/false).ok());
  absl::StatusOr<absl::Duration> down =
      TimeUntil(ServingStatus::kNotServing, started);
  ASSERT_TRUE(down.ok()) << down.status();
  EXPECT_LT(*down, kHealthBound);
  ASSERT_TRUE(server_
                  .WaitForLog(absl::StrCat("health NOT_SERVING: ", db_,
                                           " failed SQLite's integrity check"),
                              absl::Seconds(5))
                  .ok());
  for (int attempt = 0; attempt < 2; ++attempt) {
    absl::Status select = Select(stub(), "u", Context(0)).status();
    EXPECT_EQ(select.code(), absl::StatusCode::kDataLoss) << select;
    EXPECT_THAT(select.message(),
                HasSubstr(db_ + " failed SQLite's integrity check"));
    v1::CreateUserRequest create;
    create.set_user_id("v");
    create.mutable_config()->set_context_dim(kContextDim);
    create.mutable_config()->set_posthoc_dim(kPosthocDim);
    absl::Status created =
        Call(stub(), &v1::BanditService::Stub::CreateUser, create).status();
    EXPECT_EQ(created.code(), absl::StatusCode::kDataLoss) << created;
    absl::SleepFor(absl::Milliseconds(600));  // probes cannot clear it
    absl::StatusOr<ServingStatus> still =
        CheckHealth(server_.channel(), kServiceName, absl::Seconds(2));
    ASSERT_TRUE(still.ok()) << still.status();
    EXPECT_EQ(*still, ServingStatus::kNotServing);
  }
}

TEST_F(StoreFaultsTest, ADiskFullIsResourceExhaustedAndRecovers) {
  ASSERT_TRUE(StartServer(/*injector=*/true).ok());
  RefusedThenRecovered([&] { SetControl("ENOSPC"); }, [&] { ClearControl(); },
                       absl::StatusCode::kResourceExhausted,
                       "the disk is full");
}

TEST_F(StoreFaultsTest, AnIoErrorIsUnavailableAndRecovers) {
  ASSERT_TRUE(StartServer(/*injector=*/true).ok());
  RefusedThenRecovered([&] { SetControl("EIO"); }, [&] { ClearControl(); },
                       absl::StatusCode::kUnavailable, "an I/O error");
}

TEST_F(StoreFaultsTest, AReadOnlyFileSystemIsUnavailableAndRecovers) {
  ASSERT_TRUE(StartServer(/*injector=*/true).ok());
  RefusedThenRecovered([&] { SetControl("EROFS"); }, [&] { ClearControl(); },
                       absl::StatusCode::kUnavailable, "read-only");
}

// A real limit, set on the running process as `prlimit --fsize` would:
// every write past 64 KB into any file fails with EFBIG (the service's log
// stays below it).
TEST_F(StoreFaultsTest, AFileSizeLimitIsResourceExhaustedAndRecovers) {
  ASSERT_TRUE(StartServer(/*injector=*/false).ok());
  const pid_t pid = server_.pid();
  RefusedThenRecovered(
      [&] {
        ASSERT_LT(std::filesystem::file_size(LogPath(0)), 32 * 1024);
        const struct rlimit limit = {64 * 1024, RLIM_INFINITY};
        ASSERT_EQ(prlimit(pid, RLIMIT_FSIZE, &limit, nullptr), 0)
            << std::strerror(errno);
      },
      [&] {
        const struct rlimit none = {RLIM_INFINITY, RLIM_INFINITY};
        ASSERT_EQ(prlimit(pid, RLIMIT_FSIZE, &none, nullptr), 0)
            << std::strerror(errno);
      },
      absl::StatusCode::kResourceExhausted, "the file size limit is reached");
}

// chattr +i on the open files: what the review tried from outside.
TEST_F(StoreFaultsTest, AnImmutableFileIsUnavailableAndRecovers) {
  ASSERT_TRUE(StartServer(/*injector=*/false).ok());
  if (!SetImmutable(false)) {
    GTEST_SKIP() << "this file system or account cannot set the immutable "
                    "flag (chattr +i needs root on ext4, xfs or btrfs)";
  }
  RefusedThenRecovered([&] { ASSERT_TRUE(SetImmutable(true)); },
                       [&] { ASSERT_TRUE(SetImmutable(false)); },
                       absl::StatusCode::kUnavailable, "read-only");
}

// PostgreSQL's disk fills: its own server, with the injector failing the
// writes of its table files (not its write-ahead log: a server that cannot
// write that stops, which is the "server gone" case).
TEST_F(StoreFaultsTest,
       APostgresServerOutOfSpaceIsResourceExhaustedAndRecovers) {
  absl::StatusOr<std::unique_ptr<testing::TestPostgres>> pg =
      testing::TestPostgres::Create();
  ASSERT_TRUE(pg.ok()) << pg.status();
  testing::TestPostgres& server = **pg;
  // In the server's own directory: its account must read the control file.
  const std::string control = server.dir() + "/fault";
  ASSERT_TRUE(server.Stop().ok());
  server.set_server_env(
      {absl::StrCat("LD_PRELOAD=", BITEWISE_WRITE_FAULT_INJECTOR),
       absl::StrCat("BITEWISE_WRITE_FAULT_FILE=", control),
       absl::StrCat("BITEWISE_WRITE_FAULT_PREFIX=", server.dir(),
                    "/data/base/"),
       "ASAN_OPTIONS=verify_asan_link_order=0"});
  ASSERT_TRUE(server.Start().ok());
  absl::StatusOr<std::string> conninfo = server.CreateDatabase("faults");
  ASSERT_TRUE(conninfo.ok()) << conninfo.status();
  db_ = *conninfo;
  ASSERT_TRUE(StartServer(/*injector=*/false).ok());
  RefusedThenRecovered([&] { std::ofstream(control) << "ENOSPC"; },
                       [&] { std::filesystem::remove(control); },
                       absl::StatusCode::kResourceExhausted, "out of space",
                       /*select_first=*/true, "database \"faults\"");
  if (HasFailure()) std::cerr << "---- PostgreSQL log\n" << server.log();
}

}  // namespace
}  // namespace bitewise
