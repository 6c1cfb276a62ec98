#include "clients/meal/update_journal.h"

#include <signal.h>
#include <stdlib.h>
#include <sys/resource.h>
#include <unistd.h>

#include <cmath>
#include <fstream>
#include <iterator>
#include <limits>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "gtest/gtest.h"

namespace bitewise::meals {
namespace {

std::string TempPath() {
  std::string dir = ::testing::TempDir() + "/journal_XXXXXX";
  EXPECT_NE(mkdtemp(dir.data()), nullptr);
  return dir + "/updates.journal";
}

TEST(UpdateJournalTest, AbsentFileIsEmpty) {
  UpdateJournal journal(TempPath());
  absl::StatusOr<std::vector<JournaledUpdate>> all = journal.ReadAll();
  ASSERT_TRUE(all.ok());
  EXPECT_TRUE(all->empty());
}

// One process per journal: a second claim (another orchestrator, a
// console on the same file) is refused naming the holder; the claim goes
// with its holder.
TEST(JournalClaimTest, ASecondHolderIsRefusedNamingTheFirst) {
  const std::string path = TempPath();
  absl::StatusOr<std::unique_ptr<JournalClaim>> first =
      JournalClaim::Take(path);
  ASSERT_TRUE(first.ok()) << first.status();
  absl::StatusOr<std::unique_ptr<JournalClaim>> second =
      JournalClaim::Take(path);
  ASSERT_EQ(second.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_NE(second.status().message().find(absl::StrCat(
                "journal ", path, " is in use by another process (pid ",
                getpid(), ", holding ", path, ".lock)")),
            std::string::npos)
      << second.status();
  first->reset();
  EXPECT_TRUE(JournalClaim::Take(path).ok());
}

TEST(UpdateJournalTest, RoundTripsDoublesExactly) {
  UpdateJournal journal(TempPath());
  const std::vector<double> posthoc = {
      -0.1, std::log(0.3), -std::numeric_limits<double>::denorm_min(),
      -1234.5678901234567};
  ASSERT_TRUE(journal.Append({"17", 1.0, posthoc}).ok());
  ASSERT_TRUE(journal.Append({"18", 0.0, {}}).ok());
  absl::StatusOr<std::vector<JournaledUpdate>> all = journal.ReadAll();
  ASSERT_TRUE(all.ok()) << all.status();
  ASSERT_EQ(all->size(), 2u);
  EXPECT_EQ((*all)[0].event_id, "17");
  EXPECT_EQ((*all)[0].loss, 1.0);
  EXPECT_EQ((*all)[0].posthoc, posthoc);
  EXPECT_EQ((*all)[1].event_id, "18");
  EXPECT_TRUE((*all)[1].posthoc.empty());
}

TEST(UpdateJournalTest, DrainKeepsOnlyWhatFailed) {
  UpdateJournal journal(TempPath());
  for (const char* id : {"1", "2", "3", "4"}) {
    ASSERT_TRUE(journal.Append({id, 1.0, {-1.0, -2.0}}).ok());
  }
  std::vector<std::string> seen;
  absl::StatusOr<int> delivered =
      journal.Drain([&](const JournaledUpdate& update) {
        seen.push_back(update.event_id);
        return update.event_id == "2" || update.event_id == "4"
                   ? absl::UnavailableError("bandit down")
                   : absl::OkStatus();
      });
  ASSERT_TRUE(delivered.ok());
  EXPECT_EQ(*delivered, 2);
  EXPECT_EQ(seen, (std::vector<std::string>{"1", "2", "3", "4"}));
  absl::StatusOr<std::vector<JournaledUpdate>> left = journal.ReadAll();
  ASSERT_TRUE(left.ok());
  ASSERT_EQ(left->size(), 2u);
  EXPECT_EQ((*left)[0].event_id, "2");
  EXPECT_EQ((*left)[1].event_id, "4");
  // Delivering the rest empties (removes) the journal.
  delivered =
      journal.Drain([](const JournaledUpdate&) { return absl::OkStatus(); });
  ASSERT_TRUE(delivered.ok());
  EXPECT_EQ(*delivered, 2);
  EXPECT_FALSE(std::ifstream(journal.path()).good());
}

// An operator who changes an answer appends the event again: only the last
// answer is delivered, and once delivered none is left.
TEST(UpdateJournalTest, LaterLineForAnEventSupersedes) {
  UpdateJournal journal(TempPath());
  ASSERT_TRUE(journal.Append({"7", 0.0, {-0.1}}).ok());
  ASSERT_TRUE(journal.Append({"8", 1.0, {-0.2}}).ok());
  ASSERT_TRUE(journal.Append({"7", 1.0, {-0.1}}).ok());
  std::vector<JournaledUpdate> seen;
  absl::StatusOr<int> delivered =
      journal.Drain([&](const JournaledUpdate& update) {
        seen.push_back(update);
        return absl::OkStatus();
      });
  ASSERT_TRUE(delivered.ok());
  EXPECT_EQ(*delivered, 2);
  ASSERT_EQ(seen.size(), 2u);
  EXPECT_EQ(seen[0].event_id, "8");
  EXPECT_EQ(seen[1].event_id, "7");
  EXPECT_EQ(seen[1].loss, 1.0);
  EXPECT_FALSE(std::ifstream(journal.path()).good());
}

TEST(UpdateJournalTest, MalformedLineIsDataLossNamingTheLine) {
  const std::string path = TempPath();
  std::ofstream(path) << "5\t1\t-0.5\n6\tnot-a-number\n";
  UpdateJournal journal(path);
  absl::StatusOr<std::vector<JournaledUpdate>> all = journal.ReadAll();
  EXPECT_EQ(all.status().code(), absl::StatusCode::kDataLoss);
  EXPECT_NE(all.status().message().find("line 2"), std::string::npos)
      << all.status();
}

// A line cut short (a crash mid-write, never acknowledged) is not read,
// even when what is left parses (here the post hoc value -0.12 of what was
// -0.125), and the next Append cuts it off rather than running on from it.
TEST(UpdateJournalTest, ALineCutShortIsNotReadAndIsCutOffByTheNextAppend) {
  const std::string path = TempPath();
  std::ofstream(path) << "5\t1\t-0.5\n6\t0.25\t-0.12";
  UpdateJournal journal(path);
  absl::StatusOr<std::vector<JournaledUpdate>> all = journal.ReadAll();
  ASSERT_TRUE(all.ok()) << all.status();
  ASSERT_EQ(all->size(), 1u);
  EXPECT_EQ((*all)[0].event_id, "5");
  ASSERT_TRUE(journal.Append({"7", 0.0, {-2.5}}).ok());
  all = journal.ReadAll();
  ASSERT_TRUE(all.ok()) << all.status();
  ASSERT_EQ(all->size(), 2u);
  EXPECT_EQ((*all)[1].event_id, "7");
  EXPECT_EQ((*all)[1].posthoc, std::vector<double>{-2.5});
  std::ifstream in(path);
  EXPECT_EQ(std::string(std::istreambuf_iterator<char>(in), {}),
            "5\t1\t-0.5\n7\t0\t-2.5\n");
}

// A write that fails part way (here the file size limit, as a full disk
// does) is refused and leaves the file as it was.
TEST(UpdateJournalTest, AWriteThatFailsPartWayLeavesNothingBehind) {
  const std::string path = TempPath();
  UpdateJournal journal(path);
  ASSERT_TRUE(journal.Append({"5", 1.0, {-0.5}}).ok());
  std::ifstream before_in(path);
  const std::string before(std::istreambuf_iterator<char>(before_in), {});
  signal(SIGXFSZ, SIG_IGN);
  rlimit old_limit{};
  ASSERT_EQ(getrlimit(RLIMIT_FSIZE, &old_limit), 0);
  rlimit limit = old_limit;
  limit.rlim_cur = before.size() + 10;  // the next line is longer
  ASSERT_EQ(setrlimit(RLIMIT_FSIZE, &limit), 0);
  const absl::Status failed =
      journal.Append({"6", 0.0, {-0.123456789, 0.987654321}});
  ASSERT_EQ(setrlimit(RLIMIT_FSIZE, &old_limit), 0);
  signal(SIGXFSZ, SIG_DFL);
  EXPECT_FALSE(failed.ok());
  EXPECT_NE(failed.message().find("cannot write journal"), std::string::npos)
      << failed;
  std::ifstream after_in(path);
  EXPECT_EQ(std::string(std::istreambuf_iterator<char>(after_in), {}), before);
  ASSERT_TRUE(journal.Append({"7", 0.0, {}}).ok());
  absl::StatusOr<std::vector<JournaledUpdate>> all = journal.ReadAll();
  ASSERT_TRUE(all.ok()) << all.status();
  ASSERT_EQ(all->size(), 2u);
  EXPECT_EQ((*all)[1].event_id, "7");
}

// A journal that cannot be written is found at start, not when the
// BanditService is down and the update has nowhere else to go.
TEST(UpdateJournalTest, CheckWritableNamesAJournalThatCannotBeWritten) {
  const std::string path = TempPath();
  EXPECT_TRUE(UpdateJournal(path).CheckWritable().ok());
  EXPECT_FALSE(std::ifstream(path).good());  // the check left no file
  const std::string missing = path + ".d/none/updates.journal";
  const absl::Status refused = UpdateJournal(missing).CheckWritable();
  EXPECT_EQ(refused.code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_NE(refused.message().find("cannot open journal " + missing),
            std::string::npos)
      << refused;
}

}  // namespace
}  // namespace bitewise::meals
