#include "experiments/replay.h"

#include <cstdio>
#include <fstream>
#include <string>

#include "absl/time/clock.h"
#include "experiments/event_log.h"
#include "gtest/gtest.h"
#include "services/bandit/store/sqlite_event_store.h"

namespace bitewise::experiments {
namespace {

constexpr char kLog[] =
    "# comment\n"
    "item_label,action,propensity,loss,context,posthoc\n"
    "apple,0,0.5,1,1 0,1\n"
    "apple,0,0.5,0,1 0,1\n"
    "apple,1,0.25,0,1 0,1\n"
    "kiwi,0,0.5,1,0 1,2\n";

TEST(EventLogTest, ParsesAndRoundTripsTheCsvExport) {
  auto log = ParseEventLogCsv(kLog, 2);
  ASSERT_TRUE(log.ok()) << log.status();
  ASSERT_EQ(log->events.size(), 4u);
  EXPECT_FALSE(log->labelled);
  EXPECT_EQ(log->events[2].action, 1);
  EXPECT_DOUBLE_EQ(log->events[2].propensity, 0.25);
  EXPECT_EQ(log->events[3].item_label, "kiwi");
  EXPECT_EQ(log->events[3].context, (std::vector<double>{0, 1}));
  auto again = ParseEventLogCsv(FormatEventLogCsv(*log), 2);
  ASSERT_TRUE(again.ok()) << again.status();
  EXPECT_EQ(FormatEventLogCsv(*again), FormatEventLogCsv(*log));
}

TEST(EventLogTest, ErrorsNameLineAndColumn) {
  const std::string header =
      "item_label,action,propensity,loss,context,posthoc\n";
  auto bad_action = ParseEventLogCsv(header + "x,2,1,0,1,1\n", 2);
  EXPECT_NE(bad_action.status().message().find("line 2, column action"),
            std::string::npos)
      << bad_action.status();
  auto bad_loss = ParseEventLogCsv(header + "x,0,1,1.5,1,1\n", 2);
  EXPECT_NE(bad_loss.status().message().find("column loss"), std::string::npos);
  auto ragged = ParseEventLogCsv(header + "x,0,1,0,1 2,1\nx,0,1,0,1,1\n", 2);
  EXPECT_NE(ragged.status().message().find("line 3, column context"),
            std::string::npos);
  EXPECT_FALSE(ParseEventLogCsv("a,b\n", 2).ok());
}

TEST(ImputeTest, PerFoodMeansWithFallbackAndDoublyRobustCorrection) {
  auto log = ParseEventLogCsv(kLog, 2);
  ASSERT_TRUE(log.ok());
  auto k = ImputeLosses(*log, DrWeight::kNumActions);
  ASSERT_TRUE(k.ok()) << k.status();
  // apple: action 0 mean 0.5, action 1 mean 0. kiwi: action 0 mean 1;
  // action 1 never tried on kiwi, so its mean over all foods (0).
  EXPECT_DOUBLE_EQ(k->direct(0, 0), 0.5);
  EXPECT_DOUBLE_EQ(k->direct(0, 1), 0.0);
  EXPECT_DOUBLE_EQ(k->direct(3, 0), 1.0);
  EXPECT_DOUBLE_EQ(k->direct(3, 1), 0.0);
  // DR: the logged action gets K (l - l_hat); the others keep l_hat.
  EXPECT_DOUBLE_EQ(k->doubly_robust(0, 0), 0.5 + 2 * (1 - 0.5));
  EXPECT_DOUBLE_EQ(k->doubly_robust(1, 0), 0.5 + 2 * (0 - 0.5));
  EXPECT_DOUBLE_EQ(k->doubly_robust(0, 1), 0.0);
  EXPECT_DOUBLE_EQ(k->doubly_robust(3, 0), 1.0);
  auto ips = ImputeLosses(*log, DrWeight::kInversePropensity);
  ASSERT_TRUE(ips.ok());
  EXPECT_DOUBLE_EQ(ips->doubly_robust(0, 0), 0.5 + 2 * (1 - 0.5));
  EXPECT_DOUBLE_EQ(ips->doubly_robust(2, 1), 0.0 + 4 * (0 - 0.0));
  // Averaged over the log, DR recovers the logged mean loss of each action
  // under uniform-with-weight-K logging of the rows where it was taken.
  EXPECT_DOUBLE_EQ(k->doubly_robust.col(0).sum(),
                   k->direct.col(0).sum() + 2 * (1 + 0 + 1 - 0.5 - 0.5 - 1));
}

// A labelled dataset where the right action depends on the context: a good
// setting must find it, so its cumulative loss is far below a random
// policy's, and the interval brackets the mean.
TEST(ReplayTest, LabelledDatasetRanksAGoodSettingLow) {
  std::string csv = "item_label,losses,context,posthoc\n";
  for (int i = 0; i < 60; ++i) {
    csv += i % 2 == 0 ? "a,0 1 1,1 0,1 0\n" : "b,1 1 0,0 1,0 1\n";
  }
  auto log = ParseEventLogCsv(csv, 0);
  ASSERT_TRUE(log.ok()) << log.status();
  EXPECT_EQ(log->num_actions, 3);
  auto imputed = ImputeLosses(*log, DrWeight::kNumActions);
  ASSERT_TRUE(imputed.ok());
  for (auto learner :
       {bandit::Learner::kPostHoc, bandit::Learner::kContextOnly}) {
    ReplaySetting setting;
    setting.learner = learner;
    setting.alpha = 0.1;
    setting.lambda_c = 1.0;
    auto est = ReplaySettingOnLog(*log, *imputed, setting, 10, 3);
    ASSERT_TRUE(est.ok()) << est.status();
    EXPECT_LT(est->doubly_robust.mean, 10.0);  // random play: 40 of 60
    EXPECT_LE(est->doubly_robust.lower, est->doubly_robust.mean);
    EXPECT_GE(est->doubly_robust.upper, est->doubly_robust.mean);
    EXPECT_DOUBLE_EQ(est->direct.mean, est->doubly_robust.mean);
  }
}

TEST(EventLogTest, ReadsCompletedEventsFromTheBanditServiceStore) {
  const std::string path = ::testing::TempDir() + "/replay_store.db";
  std::remove(path.c_str());
  {
    bandit::SqliteStoreOptions options;
    options.path = path;
    options.synchronous_full = false;
    auto store = bandit::SqliteEventStore::Open(options);
    ASSERT_TRUE(store.ok()) << store.status();
    bandit::UserRecord user;
    user.user_id = "u";
    user.config.context_dim = 2;
    user.config.posthoc_dim = 1;
    user.created_at = absl::Now();
    ASSERT_TRUE((*store)->CreateUser(user).ok());
    for (int i = 0; i < 3; ++i) {
      bandit::EventRecord e;
      e.user_id = "u";
      e.item_label = i == 0 ? "grape" : "carrot";
      e.context = {0.5, double(i)};
      e.action = i;
      e.propensity = 1.0 / 6;
      e.selected_at = absl::Now();
      auto id = (*store)->AppendPending(e);
      ASSERT_TRUE(id.ok());
      if (i < 2) {  // the last one stays pending and must not be replayed
        ASSERT_TRUE(
            (*store)->CompleteEvent(*id, i, {0.25}, 1.0, absl::Now()).ok());
      }
    }
  }
  auto log = ReadEventLogSqlite(path, "u");
  ASSERT_TRUE(log.ok()) << log.status();
  EXPECT_EQ(log->num_actions, 6);
  ASSERT_EQ(log->events.size(), 2u);
  EXPECT_EQ(log->events[0].item_label, "grape");
  EXPECT_EQ(log->events[1].action, 1);
  EXPECT_DOUBLE_EQ(log->events[1].loss, 1.0);
  EXPECT_EQ(log->events[1].posthoc, (std::vector<double>{0.25}));
  EXPECT_EQ(ReadEventLogSqlite(path, "nobody").status().code(),
            absl::StatusCode::kNotFound);
  const std::string missing = ::testing::TempDir() + "/no_such.db";
  EXPECT_EQ(ReadEventLogSqlite(missing, "u").status().code(),
            absl::StatusCode::kNotFound);
  EXPECT_FALSE(std::ifstream(missing).good());
}

}  // namespace
}  // namespace bitewise::experiments
