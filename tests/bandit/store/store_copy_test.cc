// Copying users between real stores (services/bandit/store/store_copy.h)
// and the bitewise-admin binary: a round trip of 20 users, SQLite to SQLite
// and SQLite to PostgreSQL (a real server the test starts) and back, equals
// the original event for event and model for model; one user exported and
// imported alone; a damaged copy is found and named.
#include "services/bandit/store/store_copy.h"

#include <stdlib.h>
#include <sys/wait.h>

#include <filesystem>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/time/time.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "services/bandit/store/postgres_event_store.h"
#include "services/bandit/store/sqlite_event_store.h"
#include "tests/common/child_process.h"
#include "tests/common/postgres_server.h"

namespace bitewise::bandit {
namespace {

using ::testing::HasSubstr;
using ::testing::IsEmpty;

class StoreCopyTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string base = ::testing::TempDir();
    if (base.empty() || base.back() != '/') base += '/';
    std::string pattern = base + "store_copy_XXXXXX";
    ASSERT_NE(mkdtemp(pattern.data()), nullptr) << pattern;
    dir_ = pattern;
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  std::string Path(const std::string& name) const {
    return dir_ + "/" + name + ".db";
  }

  std::unique_ptr<SqliteEventStore> Open(const std::string& name) {
    SqliteStoreOptions options;
    options.path = Path(name);
    absl::StatusOr<std::unique_ptr<SqliteEventStore>> store =
        SqliteEventStore::Open(options);
    EXPECT_TRUE(store.ok()) << store.status();
    return store.ok() ? std::move(store).value() : nullptr;
  }

  // `users` users of varied configurations, each with completed events
  // (some completed out of their selection order) and pending ones.
  void Fill(EventStore& store, int users) {
    std::mt19937_64 rng(2026);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    for (int u = 0; u < users; ++u) {
      UserRecord user;
      user.user_id = absl::StrCat("user-", u);
      user.config.context_dim = 4 + u % 5;
      user.config.posthoc_dim = 2 + u % 3;
      user.config.learner =
          u % 4 == 3 ? Learner::kContextOnly : Learner::kPostHoc;
      user.config.lambda_c = 0.5 + u;
      user.config.alpha = 0.01 * (u + 1);
      user.config.seed = 1000 + u;
      user.config.importance_weighting = u % 2 == 1;
      user.created_at = absl::FromUnixMicros(1700000000000000 + u);
      ASSERT_TRUE(store.CreateUser(user).ok());
      std::vector<int64_t> ids;
      const int events = 5 + u % 7;
      for (int e = 0; e < events; ++e) {
        EventRecord event;
        event.user_id = user.user_id;
        event.meal_id = absl::StrCat("meal-", e / 3);
        event.item_label = e % 2 ? "carrot" : "grape";
        for (int i = 0; i < user.config.context_dim; ++i) {
          event.context.push_back(unit(rng) - 0.5);
        }
        event.action = e % 6;
        event.propensity = 0.2 + 0.1 * (e % 3);
        event.selected_at = absl::FromUnixMicros(1700000100000000 + 1000 * e);
        absl::StatusOr<int64_t> id = store.AppendPending(event);
        ASSERT_TRUE(id.ok()) << id.status();
        ids.push_back(*id);
      }
      // Complete all but the last two, the second before the first.
      for (int e = 0; e + 2 < events; ++e) {
        const int64_t id = ids[e == 0 ? 1 : (e == 1 ? 0 : e)];
        std::vector<double> posthoc;
        for (int i = 0; i < user.config.posthoc_dim; ++i) {
          posthoc.push_back(unit(rng));
        }
        ASSERT_TRUE(store
                        .CompleteEvent(
                            id, e % 3 == 0 ? 1.0 : 0.0, posthoc, 1.0 + e % 2,
                            absl::FromUnixMicros(1700000200000000 + 1000 * e))
                        .ok());
      }
    }
  }

  // Copies `original` (20 users) to `there` and on to `back`, and checks
  // that both copies equal it event for event and model for model.
  void ExpectRoundTrip(EventStore& original, EventStore& there,
                       EventStore& back) {
    absl::StatusOr<CopyReport> out = CopyUsers(original, there);
    ASSERT_TRUE(out.ok()) << out.status();
    EXPECT_EQ(out->users, 20);
    absl::StatusOr<CopyReport> in = CopyUsers(there, back);
    ASSERT_TRUE(in.ok()) << in.status();
    EXPECT_EQ(in->events, out->events);
    for (EventStore* copy : {&there, &back}) {
      absl::StatusOr<VerifyReport> verified = VerifyCopy(original, *copy);
      ASSERT_TRUE(verified.ok()) << verified.status();
      EXPECT_THAT(verified->differences, IsEmpty());
      EXPECT_EQ(verified->users, 20);
      EXPECT_EQ(verified->events, out->events);
      EXPECT_LE(verified->worst_model_difference, 1e-12);
    }
  }

  // A new database on the test's PostgreSQL server, and its URI.
  std::string NewPostgresDatabase(const std::string& name) {
    testing::TestPostgres* server = testing::SharedTestPostgres();
    if (server == nullptr) return "";
    absl::StatusOr<std::string> conninfo = server->CreateDatabase(name);
    EXPECT_TRUE(conninfo.ok()) << conninfo.status();
    return conninfo.ok() ? *conninfo : "";
  }

  // The admin binary's exit code, and its output in `log`.
  int RunAdmin(const std::vector<std::string>& args, std::string* log) {
    testing::ChildProcess child;
    std::vector<std::string> argv = {BITEWISE_ADMIN_BINARY};
    argv.insert(argv.end(), args.begin(), args.end());
    const std::string log_path = dir_ + "/admin.log";
    std::filesystem::remove(log_path);
    EXPECT_TRUE(child.Start(argv, log_path).ok());
    absl::StatusOr<int> status = child.Wait(absl::Seconds(60));
    *log = child.log();
    return status.ok() && WIFEXITED(*status) ? WEXITSTATUS(*status) : -1;
  }

  std::string dir_;
};

TEST_F(StoreCopyTest, RoundTripOfTwentyUsersEqualsTheOriginal) {
  std::unique_ptr<SqliteEventStore> original = Open("original");
  ASSERT_NE(original, nullptr);
  Fill(*original, 20);
  std::unique_ptr<SqliteEventStore> there = Open("there");
  std::unique_ptr<SqliteEventStore> back = Open("back");
  ExpectRoundTrip(*original, *there, *back);
  // Copying again into a store that has the users is refused, naming one.
  absl::StatusOr<CopyReport> again = CopyUsers(*original, *back);
  EXPECT_EQ(again.status().code(), absl::StatusCode::kAlreadyExists);
}

// The measure of moving between stores: SQLite -> PostgreSQL ->
// SQLite, 20 users, equal to the original.
TEST_F(StoreCopyTest, RoundTripThroughPostgresEqualsTheOriginal) {
  std::unique_ptr<SqliteEventStore> original = Open("original");
  ASSERT_NE(original, nullptr);
  Fill(*original, 20);
  PostgresStoreOptions options;
  options.conninfo = NewPostgresDatabase("copy_round_trip");
  auto there = PostgresEventStore::Open(options);
  ASSERT_TRUE(there.ok()) << there.status();
  std::unique_ptr<SqliteEventStore> back = Open("back");
  ExpectRoundTrip(*original, **there, *back);
}

TEST_F(StoreCopyTest, OneUserExportedAndImported) {
  std::unique_ptr<SqliteEventStore> original = Open("original");
  Fill(*original, 5);
  std::unique_ptr<SqliteEventStore> file = Open("user-3");
  ASSERT_TRUE(CopyUsers(*original, *file, "user-3").ok());
  std::unique_ptr<SqliteEventStore> other = Open("other");
  ASSERT_TRUE(CopyUsers(*file, *other, "user-3").ok());
  absl::StatusOr<VerifyReport> one = VerifyCopy(*original, *other, "user-3");
  ASSERT_TRUE(one.ok()) << one.status();
  EXPECT_THAT(one->differences, IsEmpty());
  // Compared as wholes, the other four users are missing from the copy.
  absl::StatusOr<VerifyReport> all = VerifyCopy(*original, *other);
  ASSERT_TRUE(all.ok());
  EXPECT_EQ(all->differences.size(), 4u);
  EXPECT_THAT(all->differences[0], HasSubstr("missing in the copy"));
  // Unknown user: an error, nothing written.
  EXPECT_EQ(CopyUsers(*original, *other, "nobody").status().code(),
            absl::StatusCode::kNotFound);
}

TEST_F(StoreCopyTest, DamagedCopyIsFoundAndNamed) {
  {
    std::unique_ptr<SqliteEventStore> original = Open("original");
    Fill(*original, 3);
    std::unique_ptr<SqliteEventStore> copy = Open("copy");
    ASSERT_TRUE(CopyUsers(*original, *copy).ok());
  }
  // The copy gains an event the original never had (a Select made on the
  // copy; a field changed behind the store's back would fail its checksum,
  // an error rather than a difference).
  {
    std::unique_ptr<SqliteEventStore> copy = Open("copy");
    EventRecord extra;
    extra.user_id = "user-1";
    extra.meal_id = "late";
    extra.item_label = "carrot";
    extra.context = std::vector<double>(5, 0.5);
    extra.selected_at = absl::FromUnixMicros(1800000000000000);
    ASSERT_TRUE(copy->AppendPending(extra).ok());
  }
  std::unique_ptr<SqliteEventStore> original = Open("original");
  std::unique_ptr<SqliteEventStore> copy = Open("copy");
  absl::StatusOr<VerifyReport> verified = VerifyCopy(*original, *copy);
  ASSERT_TRUE(verified.ok()) << verified.status();
  ASSERT_EQ(verified->differences.size(), 1u);
  EXPECT_THAT(verified->differences[0], HasSubstr("user \"user-1\""));
  EXPECT_THAT(verified->differences[0], HasSubstr("pending events"));
}

// A workstation replaced keeps its administrative history: the audit log
// goes with a copy of everyone (after the target's own entries), verify
// compares it, and a one-user export leaves it alone.
TEST_F(StoreCopyTest, TheAuditLogGoesWithEveryone) {
  std::unique_ptr<SqliteEventStore> original = Open("original");
  ASSERT_NE(original, nullptr);
  Fill(*original, 3);
  for (int i = 0; i < 5; ++i) {
    AuditEntry entry;
    entry.time = absl::FromUnixMicros(1700000300000000 + i);
    entry.method =
        i % 2 ? "BanditService/ResetUser" : "BanditService/SetLearner";
    entry.target = absl::StrCat("user-", i % 3);
    entry.identity = "ops";
    entry.role = "admin";
    entry.peer = "ipv4:10.0.0.9:5555";
    entry.result = i == 4 ? "NOT_FOUND" : "OK";
    ASSERT_TRUE(original->AppendAudit(entry).ok());
  }
  std::unique_ptr<SqliteEventStore> copy = Open("copy");
  AuditEntry own;
  own.time = absl::FromUnixMicros(1600000000000000);
  own.method = "BanditService/CheckStore";
  own.result = "OK";
  ASSERT_TRUE(copy->AppendAudit(own).ok());
  absl::StatusOr<CopyReport> copied = CopyUsers(*original, *copy);
  ASSERT_TRUE(copied.ok()) << copied.status();
  EXPECT_EQ(copied->audit_entries, 5);
  absl::StatusOr<VerifyReport> verified = VerifyCopy(*original, *copy);
  ASSERT_TRUE(verified.ok()) << verified.status();
  EXPECT_THAT(verified->differences, IsEmpty());
  EXPECT_EQ(verified->audit_entries, 5);

  // An export of one person carries no one's audit.
  std::unique_ptr<SqliteEventStore> one = Open("one");
  absl::StatusOr<CopyReport> exported = CopyUsers(*original, *one, "user-1");
  ASSERT_TRUE(exported.ok()) << exported.status();
  EXPECT_EQ(exported->audit_entries, 0);
  // Compared as a whole, the export lacks the audit log (and two users).
  absl::StatusOr<VerifyReport> partial = VerifyCopy(*original, *one);
  ASSERT_TRUE(partial.ok()) << partial.status();
  EXPECT_THAT(partial->differences,
              ::testing::Contains("audit log: 5 entries against 0"));
}

// Ctrl-C or a stop during a copy: the user being copied is taken out of
// the target again, those before it stay whole, and verify names only the
// users not copied.
TEST_F(StoreCopyTest, AnInterruptedCopyLeavesNoHalfCopiedUser) {
  std::unique_ptr<SqliteEventStore> original = Open("original");
  ASSERT_NE(original, nullptr);
  Fill(*original, 4);
  std::unique_ptr<SqliteEventStore> copy = Open("copy");
  // user-0 has 5 events, user-1 6 (Fill): stop within user-1.
  int asked = 0;
  absl::StatusOr<CopyReport> copied =
      CopyUsers(*original, *copy, "", [&] { return ++asked > 8; });
  EXPECT_EQ(copied.status().code(), absl::StatusCode::kCancelled);
  EXPECT_THAT(copied.status().message(), HasSubstr("copying user \"user-1\""));
  EXPECT_THAT(copied.status().message(),
              HasSubstr("interrupted; 1 users before it were copied whole; "
                        "the user was removed from the copy"));
  EXPECT_TRUE(copy->GetUser("user-0").ok());
  EXPECT_EQ(copy->GetUser("user-1").status().code(),
            absl::StatusCode::kNotFound);
  absl::StatusOr<VerifyReport> verified =
      VerifyCopy(*original, *copy, "user-0");
  ASSERT_TRUE(verified.ok()) << verified.status();
  EXPECT_THAT(verified->differences, IsEmpty());
}

// The binary, as an operator runs it: copy, verify (exit 0), then verify
// against a store that differs (exit 1), and a store that is not there
// (exit 2, naming it).
TEST_F(StoreCopyTest, AdminBinaryCopiesAndVerifies) {
  {
    std::unique_ptr<SqliteEventStore> original = Open("original");
    Fill(*original, 4);
  }
  auto run = [&](const std::vector<std::string>& args, std::string* log) {
    return RunAdmin(args, log);
  };
  std::string log;
  EXPECT_EQ(
      run({"copy", "--from=sqlite:" + Path("original"), "--to=" + Path("copy")},
          &log),
      0)
      << log;
  EXPECT_THAT(log, HasSubstr("copied 4 users"));
  EXPECT_EQ(
      run({"verify", "--from=" + Path("original"), "--to=" + Path("copy")},
          &log),
      0)
      << log;
  EXPECT_THAT(log, HasSubstr("equal: 4 users"));
  {
    std::unique_ptr<SqliteEventStore> copy = Open("copy");
    ASSERT_TRUE(copy->DeleteUser("user-2").ok());
  }
  EXPECT_EQ(
      run({"verify", "--from=" + Path("original"), "--to=" + Path("copy")},
          &log),
      1)
      << log;
  EXPECT_THAT(log, HasSubstr("user \"user-2\": missing in the copy"));
  EXPECT_EQ(run({"verify", "--from=" + Path("nothere"), "--to=" + Path("copy")},
                &log),
            2)
      << log;
  EXPECT_THAT(log,
              HasSubstr(absl::StrCat("--from: no store at \"", Path("nothere"),
                                     "\" (nothing to compare)")));
  // One file named twice (once through a sqlite: prefix): refused, not
  // "already open in another process".
  EXPECT_EQ(run({"copy", "--from=" + Path("copy"),
                 "--to=sqlite:" + dir_ + "/./copy.db"},
                &log),
            2)
      << log;
  EXPECT_THAT(log, HasSubstr("--from and --to are the same store"));
}

// The binary with a PostgreSQL URI on either side.
TEST_F(StoreCopyTest, AdminBinaryMovesUsersIntoPostgresAndBack) {
  {
    std::unique_ptr<SqliteEventStore> original = Open("original");
    Fill(*original, 4);
  }
  const std::string facility = NewPostgresDatabase("admin_facility");
  ASSERT_FALSE(facility.empty());
  std::string log;
  EXPECT_EQ(RunAdmin({"copy", "--from=" + Path("original"), "--to=" + facility},
                     &log),
            0)
      << log;
  EXPECT_THAT(log, HasSubstr("copied 4 users"));
  EXPECT_EQ(RunAdmin({"copy", "--from=" + facility, "--to=" + Path("back"),
                      "--user=user-1"},
                     &log),
            0)
      << log;
  EXPECT_EQ(
      RunAdmin({"verify", "--from=" + Path("original"), "--to=" + facility},
               &log),
      0)
      << log;
  EXPECT_THAT(log, HasSubstr("equal: 4 users"));
  EXPECT_EQ(RunAdmin({"verify", "--from=" + Path("original"),
                      "--to=" + Path("back"), "--user=user-1"},
                     &log),
            0)
      << log;
  // A database that is not there: exit 2, naming it.
  EXPECT_EQ(RunAdmin({"verify", "--from=" + Path("original"),
                      "--to=postgresql:///absent?host=" + dir_ + "&port=1"},
                     &log),
            2)
      << log;
  EXPECT_THAT(log, HasSubstr("database \"absent\""));
}

}  // namespace
}  // namespace bitewise::bandit
