#include "services/bandit/engine.h"

#include <stdlib.h>

#include <atomic>
#include <cmath>
#include <functional>
#include <memory>
#include <random>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "services/bandit/store/sqlite_event_store.h"
#include "services/bandit/store/write_faults.h"
#include "sqlite3.h"
#include "tests/bandit/dense_reference.h"
#include "tests/common/near.h"
#include "tests/common/status_matchers.h"

namespace bitewise::bandit {
namespace {

std::vector<double> RandomVector(int n, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<double> v(n);
  for (double& x : v) x = u(rng);
  return v;
}

BanditConfig SmallConfig() {
  BanditConfig config;
  config.context_dim = 8;
  config.posthoc_dim = 4;
  config.alpha = 0.3;
  config.lambda_c = 2.0;
  config.seed = 99;
  return config;
}

class EngineTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string dir = ::testing::TempDir() + "/engine_XXXXXX";
    ASSERT_NE(mkdtemp(dir.data()), nullptr);
    path_ = dir + "/bandit.db";
    Reopen();
  }

  void Reopen(EngineOptions options = EngineOptions()) {
    engine_.reset();
    store_.reset();
    SqliteStoreOptions store_options;
    store_options.path = path_;
    store_options.synchronous_full = false;  // tests need not fsync
    auto store = SqliteEventStore::Open(store_options);
    ASSERT_TRUE(store.ok()) << store.status();
    store_ = std::move(store).value();
    engine_ = std::make_unique<BanditEngine>(store_.get(), options);
  }

  // One Select + Update; returns the Select's result.
  SelectResult Bite(const std::string& user, std::mt19937_64& rng,
                    const std::string& meal = "m") {
    SelectInput select{user, RandomVector(8, rng), meal, "item"};
    absl::StatusOr<SelectResult> chosen = engine_->Select(select);
    EXPECT_TRUE(chosen.ok()) << chosen.status();
    UpdateInput update{chosen->event_id, chosen->action % 2 ? 1.0 : 0.0,
                       RandomVector(4, rng)};
    absl::StatusOr<UpdateResult> updated = engine_->Update(update);
    EXPECT_TRUE(updated.ok()) << updated.status();
    return *chosen;
  }

  std::string path_;
  std::unique_ptr<SqliteEventStore> store_;
  std::unique_ptr<BanditEngine> engine_;
};

TEST_F(EngineTest, SelectThenUpdateIsRecordedAndIdempotent) {
  ASSERT_TRUE(engine_->CreateUser("alice", SmallConfig()).ok());
  std::mt19937_64 rng(1);
  SelectInput select{"alice", RandomVector(8, rng), "breakfast", "grape"};
  absl::StatusOr<SelectResult> chosen = engine_->Select(select);
  ASSERT_TRUE(chosen.ok()) << chosen.status();
  EXPECT_EQ(chosen->estimates.size(), 6u);
  EXPECT_EQ(chosen->model_version, 0);
  EXPECT_EQ(chosen->action_names[chosen->action], chosen->action_name);

  UpdateInput update{chosen->event_id, 1.0, {0.1, 0.2, 0.3, 0.4}};
  absl::StatusOr<UpdateResult> first = engine_->Update(update);
  ASSERT_TRUE(first.ok()) << first.status();
  EXPECT_EQ(first->model_version, 1);
  EXPECT_FALSE(first->already_applied);
  EXPECT_EQ(first->user_id, "alice");

  // A repeat with the same outcome returns the recorded result.
  absl::StatusOr<UpdateResult> again = engine_->Update(update);
  ASSERT_TRUE(again.ok());
  EXPECT_TRUE(again->already_applied);
  EXPECT_EQ(again->model_version, 1);
  // Another outcome is a conflict, named, and changes nothing.
  update.loss = 0.0;
  absl::StatusOr<UpdateResult> conflict = engine_->Update(update);
  EXPECT_EQ(conflict.status().code(), absl::StatusCode::kAlreadyExists);
  EXPECT_THAT(conflict.status().message(),
              ::testing::HasSubstr("was completed with loss 1"));
  update.loss = 1.0;
  update.posthoc[0] = 0.5;
  EXPECT_THAT(engine_->Update(update).status().message(),
              ::testing::HasSubstr("another posthoc vector"));
  update.posthoc[0] = 0.1;
  absl::StatusOr<EventRecord> stored = store_->GetEvent(chosen->event_id);
  ASSERT_TRUE(stored.ok());
  EXPECT_EQ(stored->loss, 1.0);
  EXPECT_EQ(stored->meal_id, "breakfast");
  EXPECT_EQ(stored->item_label, "grape");
  EXPECT_EQ(engine_->GetUser("alice")->model_version, 1);
  // A retry with invalid input is still an error, and changes nothing.
  update.loss = 1.5;
  EXPECT_EQ(engine_->Update(update).status().code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(store_->GetEvent(chosen->event_id)->loss, 1.0);
}

// The cache budget counts what a user holds: the model, and between a
// Select and its Update the Select's products kept for that Update.
TEST_F(EngineTest, CacheCountsTheSelectsProductsUntilTheUpdate) {
  ASSERT_TRUE(engine_->CreateUser("alice", SmallConfig()).ok());
  std::mt19937_64 rng(3);
  for (int i = 0; i < 5; ++i) Bite("alice", rng);
  const size_t after_update = engine_->CachedBytes();
  EXPECT_GT(after_update, 0u);
  SelectInput select{"alice", RandomVector(8, rng), "m", "item"};
  absl::StatusOr<SelectResult> chosen = engine_->Select(select);
  ASSERT_TRUE(chosen.ok()) << chosen.status();
  // The context (8 doubles) and each dual action's product with it, one
  // double per round (5 rounds), and the event's context as written (8
  // more, so the Update need not read it): exactly 21 doubles more.
  EXPECT_EQ(engine_->CachedBytes(), after_update + 21 * sizeof(double));
  UpdateInput update{chosen->event_id, 0.0, RandomVector(4, rng)};
  ASSERT_TRUE(engine_->Update(update).ok());
  // Released at the Update: the next Select adds its own 8 + 6 + 8
  // doubles to the model alone.
  const size_t model_only = engine_->CachedBytes();
  SelectInput again{"alice", RandomVector(8, rng), "m", "item"};
  ASSERT_TRUE(engine_->Select(again).ok());
  EXPECT_EQ(engine_->CachedBytes(), model_only + 22 * sizeof(double));
}

TEST_F(EngineTest, BadInputGetsPreciseStatusAndWritesNothing) {
  ASSERT_TRUE(engine_->CreateUser("bob", SmallConfig()).ok());
  std::mt19937_64 rng(2);

  absl::StatusOr<SelectResult> bad =
      engine_->Select({"bob", RandomVector(7, rng), "", ""});
  EXPECT_EQ(bad.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(bad.status().message().find("context: expected 8 values, got 7"),
            std::string::npos)
      << bad.status();
  std::vector<double> nan_context = RandomVector(8, rng);
  nan_context[3] = std::nan("");
  bad = engine_->Select({"bob", nan_context, "", ""});
  EXPECT_EQ(bad.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(bad.status().message().find("context[3]"), std::string::npos);
  EXPECT_EQ(
      engine_->Select({"nobody", RandomVector(8, rng), "", ""}).status().code(),
      absl::StatusCode::kNotFound);
  EXPECT_EQ(engine_->Select({"bad id!", RandomVector(8, rng), "", ""})
                .status()
                .code(),
            absl::StatusCode::kInvalidArgument);
  for (const char* id : {".", "..", "-x", "_"}) {
    EXPECT_THAT(engine_->GetUser(id).status().message(),
                ::testing::HasSubstr("must start with a letter or digit"))
        << id;
  }
  EXPECT_THAT(
      engine_->Select({"bob", RandomVector(8, rng), std::string(257, 'm'), ""})
          .status()
          .message(),
      ::testing::HasSubstr("meal_id: at most 256 bytes, got 257"));
  // SQLite would store it; PostgreSQL's text cannot: refused on both.
  EXPECT_THAT(engine_
                  ->Select({"bob", RandomVector(8, rng), "lunch",
                            std::string("gra\0pe", 6)})
                  .status()
                  .message(),
              ::testing::HasSubstr(
                  "item_label: must not contain a NUL byte (at byte 3)"));
  BanditConfig long_names = SmallConfig();
  long_names.action_names[0] = std::string(1 << 20, 'a');  // 1 MB
  EXPECT_THAT(engine_->CreateUser("long", long_names).status().message(),
              ::testing::HasSubstr("action_names[0]: must be 1-64 bytes"));
  EXPECT_TRUE(store_->ListEvents("bob", "", Page())->items.empty());

  absl::StatusOr<SelectResult> chosen =
      engine_->Select({"bob", RandomVector(8, rng), "", ""});
  ASSERT_TRUE(chosen.ok());
  const std::vector<UpdateInput> bad_updates = {
      {chosen->event_id, 1.5, {0, 0, 0, 1}},
      {chosen->event_id, -0.1, {0, 0, 0, 1}},
      {chosen->event_id, std::nan(""), {0, 0, 0, 1}},
      {chosen->event_id, 1.0, {0, 0, 1}},
      {chosen->event_id, 1.0, {0, 0, INFINITY, 1}},
      {chosen->event_id, 1.0, {}},
  };
  const char* const fields[] = {"loss",    "loss",       "loss",
                                "posthoc", "posthoc[2]", "posthoc"};
  for (size_t i = 0; i < bad_updates.size(); ++i) {
    absl::StatusOr<UpdateResult> result = engine_->Update(bad_updates[i]);
    EXPECT_EQ(result.status().code(), absl::StatusCode::kInvalidArgument) << i;
    EXPECT_NE(result.status().message().find(fields[i]), std::string::npos)
        << result.status();
  }
  EXPECT_EQ(engine_->Update({chosen->event_id + 1000, 1.0, {0, 0, 0, 1}})
                .status()
                .code(),
            absl::StatusCode::kNotFound);
  EXPECT_EQ(engine_->Update({0, 1.0, {0, 0, 0, 1}}).status().code(),
            absl::StatusCode::kInvalidArgument);
  // Nothing was applied: the event is still pending and the model empty.
  EXPECT_FALSE(store_->GetEvent(chosen->event_id)->completed);
  EXPECT_EQ(engine_->GetUser("bob")->model_version, 0);
  EXPECT_EQ(engine_->GetModel("bob")->actions[0].count, 0);
  EXPECT_TRUE(engine_->Update({chosen->event_id, 0.0, {0, 0, 0, 1}}).ok());
}

TEST_F(EngineTest, ConfigsWhoseModelCouldOutgrowTheLimitAreRefused) {
  // The largest the validator allows: terabytes in primal form.
  BanditConfig huge = SmallConfig();
  huge.context_dim = 1 << 16;
  huge.posthoc_dim = 1024;
  huge.action_names.clear();
  for (int a = 0; a < 256; ++a)
    huge.action_names.push_back(absl::StrCat("a", a));
  absl::StatusOr<UserRecord> refused = engine_->CreateUser("huge", huge);
  EXPECT_EQ(refused.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(refused.status().message(),
              ::testing::HasSubstr("context_dim 65536, posthoc_dim 1024 and "
                                   "256 actions can grow to"));
  EXPECT_EQ(store_->GetUser("huge").status().code(),
            absl::StatusCode::kNotFound);
  // The paper's size fits the default limit, with room: d = 4096 too.
  BanditConfig spanet = SmallConfig();
  spanet.context_dim = 4096;
  EXPECT_LT(MaxModelBytes(spanet), EngineOptions().max_model_bytes);
  EXPECT_TRUE(engine_->CreateUser("spanet", spanet).ok());
  // A tighter limit refuses it, naming the limit.
  EngineOptions tight;
  tight.max_model_bytes = size_t{100} << 20;
  Reopen(tight);
  absl::StatusOr<UserRecord> over = engine_->CreateUser("spanet2", spanet);
  EXPECT_EQ(over.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(over.status().message(), ::testing::HasSubstr("limit of 0.1 GB"));
  // So does a cache budget it could not fit in, naming the budget.
  EngineOptions small_cache;
  small_cache.cache_budget_bytes = size_t{100} << 20;
  Reopen(small_cache);
  over = engine_->CreateUser("spanet3", spanet);
  EXPECT_EQ(over.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(
      over.status().message(),
      ::testing::HasSubstr("model cache of 0.1 GB (--cache_budget_mb)"));
  EXPECT_EQ(store_->GetUser("spanet3").status().code(),
            absl::StatusCode::kNotFound);
}

// Every model a user can have must be readable with GetModel under the
// 4 MiB message limit. Under the default memory limit every model is (the
// widest, 256 actions at d = 700, replies in under 3 MB); with a raised
// --max_model_mb, many actions with wide contexts are refused up front,
// naming the reply's size.
TEST_F(EngineTest, ConfigsWhoseModelCannotBeExportedAreRefused) {
  BanditConfig widest = SmallConfig();
  widest.context_dim = 700;
  widest.action_names.clear();
  for (int a = 0; a < 256; ++a) {
    widest.action_names.push_back(absl::StrCat("action", a));
  }
  EXPECT_LT(MaxModelBytes(widest), EngineOptions().max_model_bytes);
  EXPECT_LT(ModelReplyBytes(widest), EngineOptions().max_reply_bytes);
  EngineOptions roomy;
  roomy.max_model_bytes = size_t{1} << 40;
  Reopen(roomy);
  BanditConfig wide = widest;
  wide.context_dim = 2048;
  EXPECT_GT(ModelReplyBytes(wide), EngineOptions().max_reply_bytes);
  absl::StatusOr<UserRecord> refused = engine_->CreateUser("wide", wide);
  EXPECT_EQ(refused.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(refused.status().message(),
              ::testing::HasSubstr("GetModel's reply for context_dim 2048"));
  // The paper's SPANet size with six actions exports in well under 1 MB.
  BanditConfig spanet = SmallConfig();
  spanet.context_dim = 2048;
  EXPECT_LT(ModelReplyBytes(spanet), size_t{1} << 20);
  EXPECT_TRUE(engine_->CreateUser("spanet", spanet).ok());
}

TEST_F(EngineTest, ModelSurvivesReopenWithin1e12) {
  BanditConfig config = SmallConfig();
  config.lambda_c = 1000.0;  // the default
  ASSERT_TRUE(engine_->CreateUser("carol", config).ok());
  std::mt19937_64 rng(3);
  for (int t = 0; t < 120; ++t) Bite("carol", rng);
  // A pending event selected before the restart can be completed after it.
  absl::StatusOr<SelectResult> pending =
      engine_->Select({"carol", RandomVector(8, rng), "", ""});
  ASSERT_TRUE(pending.ok());
  const std::vector<double> probe = RandomVector(8, rng);
  absl::StatusOr<ModelExport> before = engine_->GetModel("carol");
  absl::StatusOr<SelectResult> select_before =
      engine_->Select({"carol", probe, "", ""});
  ASSERT_TRUE(before.ok() && select_before.ok());

  Reopen();
  absl::StatusOr<ModelExport> after = engine_->GetModel("carol");
  ASSERT_TRUE(after.ok());
  EXPECT_EQ(after->user.model_version, 120);
  for (int a = 0; a < 6; ++a) {
    EXPECT_EQ(after->actions[a].count, before->actions[a].count);
    for (int i = 0; i < 8; ++i) {
      EXPECT_TRUE(bitewise::testing::RelNear(
          after->actions[a].theta[i], before->actions[a].theta[i], 1e-12));
    }
  }
  absl::StatusOr<SelectResult> select_after =
      engine_->Select({"carol", probe, "", ""});
  ASSERT_TRUE(select_after.ok());
  EXPECT_EQ(select_after->action, select_before->action);
  for (int a = 0; a < 6; ++a) {
    const ActionEstimate& x = select_before->estimates[a];
    const ActionEstimate& y = select_after->estimates[a];
    EXPECT_TRUE(bitewise::testing::RelNear(y.lcb, x.lcb, 1e-12));
    EXPECT_TRUE(bitewise::testing::RelNear(y.width, x.width, 1e-12));
  }
  EXPECT_TRUE(engine_->Update({pending->event_id, 1.0, {0, 1, 0, 0}}).ok());
  EXPECT_EQ(engine_->GetUser("carol")->model_version, 121);
}

TEST_F(EngineTest, AnUpdateOfAnEventGoneWithItsUserIsNotFound) {
  // The engine remembers the events it selected (so their Updates need not
  // read them back); an event deleted since, with a reset or with its user,
  // is still unknown, and a new user of the same id learns nothing.
  ASSERT_TRUE(engine_->CreateUser("gus", SmallConfig()).ok());
  std::mt19937_64 rng(8);
  for (int gone = 0; gone < 3; ++gone) {
    auto selected = engine_->Select({"gus", RandomVector(8, rng), "m", "i"});
    ASSERT_TRUE(selected.ok()) << selected.status();
    if (gone == 0) {
      ASSERT_TRUE(engine_->ResetUser("gus").ok());
    } else {
      ASSERT_TRUE(engine_->DeleteUser("gus").ok());
      if (gone == 2) {
        ASSERT_TRUE(engine_->CreateUser("gus", SmallConfig()).ok());
      }
    }
    const absl::Status updated =
        engine_->Update({selected->event_id, 0.5, RandomVector(4, rng)})
            .status();
    EXPECT_EQ(updated.code(), absl::StatusCode::kNotFound) << updated;
    EXPECT_THAT(
        std::string(updated.message()),
        ::testing::HasSubstr(absl::StrCat("event ", selected->event_id)));
    if (gone == 1) {
      ASSERT_TRUE(engine_->CreateUser("gus", SmallConfig()).ok());
    }
    EXPECT_EQ(engine_->GetUser("gus")->model_version, 0);
  }
  // A retried Update (after it was applied) is answered from the store.
  auto selected = engine_->Select({"gus", RandomVector(8, rng), "m", "i"});
  ASSERT_TRUE(selected.ok());
  const UpdateInput update{selected->event_id, 0.25, RandomVector(4, rng)};
  ASSERT_TRUE(engine_->Update(update).ok());
  auto again = engine_->Update(update);
  ASSERT_TRUE(again.ok()) << again.status();
  EXPECT_TRUE(again->already_applied);
  EXPECT_EQ(again->model_version, 1);
}

TEST_F(EngineTest, SeededStrategiesAreReproducibleAcrossResetAndRestart) {
  BanditConfig config = SmallConfig();
  config.strategy = Strategy::kEpsilonGreedy;
  config.epsilon = 0.5;
  ASSERT_TRUE(engine_->CreateUser("dan", config).ok());
  auto run = [&](int bites) {
    std::mt19937_64 rng(4);
    std::vector<int> actions;
    for (int t = 0; t < bites; ++t) actions.push_back(Bite("dan", rng).action);
    return actions;
  };
  const std::vector<int> first = run(30);
  ASSERT_TRUE(engine_->ResetUser("dan").ok());
  EXPECT_EQ(engine_->GetUser("dan")->model_version, 0);
  EXPECT_EQ(run(30), first);
  // A restart mid-way continues the same random stream.
  ASSERT_TRUE(engine_->ResetUser("dan").ok());
  std::mt19937_64 rng(4);
  std::vector<int> split;
  for (int t = 0; t < 15; ++t) split.push_back(Bite("dan", rng).action);
  Reopen();
  for (int t = 15; t < 30; ++t) split.push_back(Bite("dan", rng).action);
  EXPECT_EQ(split, first);
  // Exploration happened: not every bite took the same action.
  EXPECT_GT(std::set<int>(first.begin(), first.end()).size(), 2u);
}

// Thetas of every action, as GetModel reports them.
std::vector<std::vector<double>> Thetas(BanditEngine& engine,
                                        const std::string& user) {
  absl::StatusOr<ModelExport> model = engine.GetModel(user);
  EXPECT_TRUE(model.ok()) << model.status();
  std::vector<std::vector<double>> out;
  if (model.ok()) {
    for (const ActionModelExport& a : model->actions) out.push_back(a.theta);
  }
  return out;
}

void ExpectNear(const std::vector<std::vector<double>>& a,
                const std::vector<std::vector<double>>& b) {
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    ASSERT_EQ(a[i].size(), b[i].size());
    for (size_t k = 0; k < a[i].size(); ++k) {
      EXPECT_NEAR(a[i][k], b[i][k], 1e-10 * std::max(1.0, std::abs(b[i][k])))
          << i << "," << k;
    }
  }
}

// A cold load starts from the user's checkpoint and replays only the events
// after it, and gives the model a full rebuild gives (1e-10), in both forms;
// a damaged checkpoint is detected and ignored, a deleted one loses nothing,
// and a reset takes it along.
TEST_F(EngineTest, ColdLoadsStartFromTheCheckpoint) {
  EngineOptions options;
  options.primal_threshold = 20;      // some actions primal, some dual
  options.checkpoint_min_events = 0;  // only when asked (CheckpointUser)
  Reopen(options);
  ASSERT_TRUE(engine_->CreateUser("kim", SmallConfig()).ok());
  std::mt19937_64 rng(12);
  for (int t = 0; t < 150; ++t) Bite("kim", rng);
  ASSERT_TRUE(engine_->CheckpointUser("kim").ok());
  EXPECT_EQ(engine_->Counters().checkpoints_written, 1);
  EXPECT_EQ(store_->GetCheckpoint("kim")->model_version, 150);
  for (int t = 0; t < 17; ++t) Bite("kim", rng);
  const auto live = Thetas(*engine_, "kim");

  Reopen(options);
  const auto from_checkpoint = Thetas(*engine_, "kim");
  EXPECT_EQ(engine_->Counters().checkpoint_loads, 1);
  EXPECT_EQ(engine_->Counters().checkpoints_ignored, 0);
  ExpectNear(from_checkpoint, live);
  // It keeps learning and selecting as the live one would have.
  Bite("kim", rng);

  // Damaged: ignored (counted, logged), the log rebuilds the same model.
  const auto before = Thetas(*engine_, "kim");
  ASSERT_TRUE(engine_->CheckpointUser("kim").ok());
  Reopen(options);
  {
    sqlite3* raw = nullptr;
    ASSERT_EQ(sqlite3_open(path_.c_str(), &raw), SQLITE_OK);
    ASSERT_EQ(sqlite3_exec(raw,
                           "UPDATE model_checkpoint_chunks SET data = "
                           "zeroblob(length(data)) WHERE seq = 0",
                           nullptr, nullptr, nullptr),
              SQLITE_OK);
    sqlite3_close(raw);
  }
  ExpectNear(Thetas(*engine_, "kim"), before);
  EXPECT_EQ(engine_->Counters().checkpoint_loads, 0);
  EXPECT_EQ(engine_->Counters().checkpoints_ignored, 1);

  // Deleted: nothing lost.
  ASSERT_TRUE(store_->DeleteCheckpoint("kim").ok());
  Reopen(options);
  ExpectNear(Thetas(*engine_, "kim"), before);
  EXPECT_EQ(engine_->Counters().checkpoint_loads, 0);
  EXPECT_EQ(engine_->Counters().checkpoints_ignored, 0);

  // A model rebuilt from the whole log can be saved again at once; a reset
  // takes the checkpoint along.
  ASSERT_TRUE(engine_->CheckpointUser("kim").ok());
  ASSERT_TRUE(store_->GetCheckpoint("kim").ok());
  EXPECT_EQ(store_->GetCheckpoint("kim")->model_version, 168);
  ASSERT_TRUE(engine_->ResetUser("kim").ok());
  EXPECT_EQ(store_->GetCheckpoint("kim").status().code(),
            absl::StatusCode::kNotFound);
}

// The background thread saves a model once enough events have come in and
// its user is idle, without anyone asking. Idle means 300 ms without a call,
// far longer than between two bites of the loop, so the one checkpoint
// comes after the last bite.
TEST_F(EngineTest, IdleModelsAreCheckpointedInTheBackground) {
  EngineOptions options;
  options.checkpoint_min_events = 5;
  options.checkpoint_idle = absl::Milliseconds(300);
  options.checkpoint_poll = absl::Milliseconds(5);
  Reopen(options);
  ASSERT_TRUE(engine_->CreateUser("lee", SmallConfig()).ok());
  std::mt19937_64 rng(13);
  for (int t = 0; t < 4; ++t) Bite("lee", rng);
  absl::SleepFor(absl::Milliseconds(100));
  EXPECT_EQ(engine_->Counters().checkpoints_written, 0);  // too few events
  for (int t = 0; t < 4; ++t) Bite("lee", rng);
  const absl::Time deadline = absl::Now() + absl::Seconds(10);
  while (engine_->Counters().checkpoints_written == 0 &&
         absl::Now() < deadline) {
    absl::SleepFor(absl::Milliseconds(5));
  }
  EXPECT_EQ(engine_->Counters().checkpoints_written, 1);
  absl::StatusOr<ModelCheckpoint> saved = store_->GetCheckpoint("lee");
  ASSERT_TRUE(saved.ok()) << saved.status();
  EXPECT_EQ(saved->model_version, 8);
}

// "checkpoint_max_events" holds while the user never pauses: two threads
// bite without a break, and checkpoints are written while the bites go on
// (the Update that makes one due wakes the background thread, which waits
// for the user's lock instead of finding it taken at every poll). How many
// events pass meanwhile at d = 2048 is measured by bandit_restart_bench.
TEST_F(EngineTest, ContinuousLoadIsStillCheckpointedAtMaxEvents) {
  EngineOptions options;
  options.checkpoint_min_events = 5;
  options.checkpoint_max_events = 40;
  options.checkpoint_idle = absl::Hours(1);  // never idle
  options.checkpoint_poll = absl::Milliseconds(5);
  Reopen(options);
  ASSERT_TRUE(engine_->CreateUser("ann", SmallConfig()).ok());
  std::atomic<bool> stop{false};
  std::atomic<int> bites{0};
  std::vector<std::thread> eaters;
  for (int i = 0; i < 2; ++i) {
    eaters.emplace_back([&, i] {
      std::mt19937_64 rng(100 + i);
      while (!stop.load()) {
        Bite("ann", rng);
        bites.fetch_add(1);
      }
    });
  }
  const absl::Time deadline = absl::Now() + absl::Seconds(60);
  while (engine_->Counters().checkpoints_written < 3 &&
         absl::Now() < deadline) {
    absl::SleepFor(absl::Milliseconds(5));
  }
  const int64_t written = engine_->Counters().checkpoints_written;
  const int at = bites.load();
  stop.store(true);
  for (std::thread& t : eaters) t.join();
  EXPECT_GE(written, 3) << "after " << at << " bites";
  absl::StatusOr<ModelCheckpoint> saved = store_->GetCheckpoint("ann");
  ASSERT_TRUE(saved.ok()) << saved.status();
  EXPECT_GE(saved->model_version, 3 * 40);
}

TEST_F(EngineTest, CacheBudgetEvictsAndReloadsTransparently) {
  for (const char* user : {"u1", "u2", "u3"}) {
    ASSERT_TRUE(engine_->CreateUser(user, SmallConfig()).ok());
  }
  // At most the model in use stays loaded (a budget no model fits: new
  // users could not be created under it, existing ones still load).
  EngineOptions options;
  options.cache_budget_bytes = 1;
  Reopen(options);
  std::mt19937_64 rng(5);
  for (int t = 0; t < 20; ++t) {
    for (const char* user : {"u1", "u2", "u3"}) Bite(user, rng);
    EXPECT_LE(engine_->CachedModels(), 1);
  }
  // Reloaded models equal a model that was never evicted.
  std::unique_ptr<BanditEngine> roomy =
      std::make_unique<BanditEngine>(store_.get(), EngineOptions());
  const std::vector<double> probe = RandomVector(8, rng);
  for (const char* user : {"u1", "u2", "u3"}) {
    absl::StatusOr<ModelExport> a = engine_->GetModel(user);
    absl::StatusOr<ModelExport> b = roomy->GetModel(user);
    ASSERT_TRUE(a.ok() && b.ok());
    EXPECT_EQ(a->user.model_version, 20);
    for (int i = 0; i < 6; ++i)
      EXPECT_EQ(a->actions[i].theta, b->actions[i].theta);
  }
}

TEST_F(EngineTest, ConcurrentCallsKeepEveryUpdate) {
  for (const char* user : {"p0", "p1", "p2", "shared"}) {
    ASSERT_TRUE(engine_->CreateUser(user, SmallConfig()).ok());
  }
  std::vector<std::thread> threads;
  for (int i = 0; i < 4; ++i) {
    threads.emplace_back([this, i] {
      std::mt19937_64 rng(100 + i);
      const std::string own = i < 3 ? "p" + std::to_string(i) : "shared";
      for (int t = 0; t < 25; ++t) {
        Bite(own, rng);
        Bite("shared", rng);
      }
    });
  }
  for (std::thread& t : threads) t.join();
  EXPECT_EQ(engine_->GetUser("shared")->model_version, 25 + 4 * 25);
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(engine_->GetUser("p" + std::to_string(i))->model_version, 25);
  }
  // The live model of the shared user equals one rebuilt from its log.
  absl::StatusOr<ModelExport> live = engine_->GetModel("shared");
  Reopen();
  absl::StatusOr<ModelExport> rebuilt = engine_->GetModel("shared");
  for (int a = 0; a < 6; ++a) {
    EXPECT_EQ(live->actions[a].count, rebuilt->actions[a].count);
    for (int j = 0; j < 8; ++j) {
      EXPECT_NEAR(live->actions[a].theta[j], rebuilt->actions[a].theta[j],
                  1e-10);
    }
  }
}

TEST_F(EngineTest, UserLifecycle) {
  EXPECT_EQ(engine_->CreateUser("eve", SmallConfig()).status().code(),
            absl::StatusCode::kOk);
  EXPECT_EQ(engine_->CreateUser("eve", SmallConfig()).status().code(),
            absl::StatusCode::kAlreadyExists);
  BanditConfig bad = SmallConfig();
  bad.alpha = -1;
  EXPECT_EQ(engine_->CreateUser("frank", bad).status().code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(engine_->GetUser("frank").status().code(),
            absl::StatusCode::kNotFound);
  std::mt19937_64 rng(6);
  Bite("eve", rng, "lunch");
  Bite("eve", rng, "dinner");
  EXPECT_EQ(engine_->ListEvents("eve", "lunch", Page())->items.size(), 1u);
  EXPECT_EQ(engine_->ListEvents("eve", "", Page())->items.size(), 2u);
  ASSERT_TRUE(engine_->DeleteUser("eve").ok());
  EXPECT_EQ(engine_->GetModel("eve").status().code(),
            absl::StatusCode::kNotFound);
  EXPECT_EQ(engine_->DeleteUser("eve").code(), absl::StatusCode::kNotFound);
  // The id can be used again, from scratch.
  ASSERT_TRUE(engine_->CreateUser("eve", SmallConfig()).ok());
  EXPECT_EQ(engine_->GetModel("eve")->user.model_version, 0);
}

// The population prior end to end in the engine: no pool is a clear
// error; pooling takes like users only, one model at a time; a new user
// starts from the pool (exactly the dense reference of the prior's
// formulas), and keeps it across a restart.
TEST_F(EngineTest, PopulationPriorPoolsLikeUsersAndPrimesNewOnes) {
  using ::bitewise::testing::IsOk;
  using ::bitewise::testing::StatusIs;
  using ::testing::HasSubstr;
  EXPECT_THAT(engine_->CreateUser("early", SmallConfig(), /*prior_rounds=*/5),
              StatusIs(absl::StatusCode::kFailedPrecondition,
                       HasSubstr("BuildPopulationPrior")));
  EXPECT_THAT(engine_->BuildPopulationPool(SmallConfig()),
              StatusIs(absl::StatusCode::kFailedPrecondition,
                       HasSubstr("nothing to pool")));
  EXPECT_THAT(
      engine_->CreateUser("bad", SmallConfig(), /*prior_rounds=*/-1),
      StatusIs(absl::StatusCode::kInvalidArgument, HasSubstr("prior_rounds")));

  std::mt19937_64 rng(5);
  for (const char* user : {"u1", "u2"}) {
    ASSERT_TRUE(engine_->CreateUser(user, SmallConfig()).ok());
    for (int t = 0; t < 30; ++t) Bite(user, rng);
  }
  BanditConfig wide = SmallConfig();
  wide.context_dim = 9;  // unlike: not pooled
  ASSERT_TRUE(engine_->CreateUser("wide", wide).ok());
  ASSERT_TRUE(engine_->CreateUser("idle", SmallConfig()).ok());  // no rounds
  absl::StatusOr<PoolRecord> pool = engine_->BuildPopulationPool(SmallConfig());
  ASSERT_THAT(pool, IsOk());
  EXPECT_EQ(pool->users, 2);
  EXPECT_GE(pool->pool_version, 1);

  absl::StatusOr<UserRecord> primed =
      engine_->CreateUser("primed", SmallConfig(), /*prior_rounds=*/5.0);
  ASSERT_TRUE(primed.ok()) << primed.status();
  EXPECT_EQ(primed->config.prior.pool_version, pool->pool_version);
  EXPECT_EQ(primed->config.prior.rounds, 5.0);
  for (int restart = 0; restart < 2; ++restart) {
    absl::StatusOr<ModelExport> model = engine_->GetModel("primed");
    ASSERT_TRUE(model.ok()) << model.status();
    const std::vector<testing::DenseActionModel> ref =
        testing::DenseReference(model->user.config, {});
    double started_from = 0.0;
    for (int a = 0; a < 6; ++a) {
      const Eigen::Map<const Eigen::VectorXd> theta(
          model->actions[a].theta.data(), model->actions[a].theta.size());
      EXPECT_LT((theta - ref[a].theta).norm(),
                1e-10 * std::max(1.0, ref[a].theta.norm()));
      started_from += ref[a].theta.norm();
    }
    EXPECT_GT(started_from, 0.0);  // it did start from the pool (odd actions
                                   // always failed for u1 and u2)
    Reopen();                      // the prior persists with the user
  }
}

}  // namespace
}  // namespace bitewise::bandit

namespace bitewise::bandit {
namespace {

// poLinUCB in the engine as the other learners: a cold load starts from its
// checkpoint and equals the live model, and a population prior pooled from
// poLinUCB users starts a new one where the dense reference says.
TEST_F(EngineTest, PoLinUcbCheckpointsAndPoolsAsTheOtherLearners) {
  EngineOptions options;
  options.primal_threshold = 20;
  options.checkpoint_min_events = 0;
  Reopen(options);
  BanditConfig config = SmallConfig();
  config.learner = Learner::kPoLinUcb;
  std::mt19937_64 rng(31);
  for (const char* user : {"po1", "po2"}) {
    ASSERT_TRUE(engine_->CreateUser(user, config).ok());
    for (int t = 0; t < 60; ++t) Bite(user, rng);
  }
  ASSERT_TRUE(engine_->CheckpointUser("po1").ok());
  for (int t = 0; t < 9; ++t) Bite("po1", rng);
  const auto live = Thetas(*engine_, "po1");
  Reopen(options);
  ExpectNear(Thetas(*engine_, "po1"), live);
  EXPECT_EQ(engine_->Counters().checkpoint_loads, 1);
  EXPECT_EQ(engine_->Counters().checkpoints_ignored, 0);

  absl::StatusOr<PoolRecord> pool = engine_->BuildPopulationPool(config);
  ASSERT_TRUE(pool.ok()) << pool.status();
  EXPECT_EQ(pool->users, 2);
  absl::StatusOr<UserRecord> primed =
      engine_->CreateUser("po-primed", config, /*prior_rounds=*/3.0);
  ASSERT_TRUE(primed.ok()) << primed.status();
  ASSERT_TRUE(primed->config.prior.enabled());
  EXPECT_EQ(primed->config.learner, Learner::kPoLinUcb);
  absl::StatusOr<ModelExport> model = engine_->GetModel("po-primed");
  ASSERT_TRUE(model.ok()) << model.status();
  const std::vector<double> at = RandomVector(8, rng);
  const testing::DensePoLinUcb ref =
      testing::DensePoLinUcbReference(model->user.config, {}, at);
  for (int a = 0; a < 6; ++a) {
    const Eigen::Map<const Eigen::VectorXd> theta(
        model->actions[a].theta.data(), model->actions[a].theta.size());
    const Eigen::Map<const Eigen::VectorXd> phi(model->actions[a].phi.data(),
                                                model->actions[a].phi.size());
    EXPECT_TRUE(bitewise::testing::RelNear(theta, ref.theta[a], 1e-10));
    EXPECT_TRUE(bitewise::testing::RelNear(phi, ref.beta[a], 1e-10));
  }
}

// `n` bites of `user` at random contexts (8 values), each learned at once
// with loss 1, 0 every third, and a random post hoc context (4 values): the
// rounds learned, in order. `each` sees every Select.
std::vector<Round> LearnRandomRounds(
    BanditEngine& engine, const std::string& user, int n, std::mt19937_64& rng,
    const std::function<void(const SelectResult&)>& each = nullptr) {
  std::vector<Round> seen;
  for (int t = 0; t < n; ++t) {
    SelectInput select{user, RandomVector(8, rng), "m", "item"};
    absl::StatusOr<SelectResult> chosen = engine.Select(select);
    EXPECT_TRUE(chosen.ok()) << chosen.status();
    if (!chosen.ok()) return seen;
    if (each) each(*chosen);
    UpdateInput update{chosen->event_id, t % 3 ? 1.0 : 0.0,
                       RandomVector(4, rng)};
    EXPECT_TRUE(engine.Update(update).ok());
    seen.push_back(Round{select.context, chosen->action, update.loss,
                         update.posthoc, 1.0});
  }
  return seen;
}

// SetLearner moves a user to another learner and keeps the log: the model
// is then the new learner's on every round learned, as the dense float64
// reference computes it from the same rounds, after a restart too (the old
// learner's checkpoint is gone), and back again. Refused for a user started
// from a population pool, an unknown learner or user; the same learner
// changes nothing.
TEST_F(EngineTest, SetLearnerRebuildsTheModelFromTheLogUnderTheNewLearner) {
  EngineOptions options;
  options.checkpoint_min_events = 0;
  Reopen(options);
  ASSERT_TRUE(engine_->CreateUser("mo", SmallConfig()).ok());
  std::mt19937_64 rng(53);
  const std::vector<Round> seen = LearnRandomRounds(*engine_, "mo", 30, rng);
  ASSERT_EQ(seen.size(), 30u);
  ASSERT_TRUE(engine_->CheckpointUser("mo").ok());
  const std::vector<double> at = RandomVector(8, rng);

  absl::StatusOr<UserRecord> same =
      engine_->SetLearner("mo", Learner::kPostHoc);
  ASSERT_TRUE(same.ok()) << same.status();
  EXPECT_EQ(same->config.learner, Learner::kPostHoc);

  absl::StatusOr<UserRecord> moved =
      engine_->SetLearner("mo", Learner::kPoLinUcb);
  ASSERT_TRUE(moved.ok()) << moved.status();
  EXPECT_EQ(moved->config.learner, Learner::kPoLinUcb);
  EXPECT_EQ(moved->model_version, 30);
  for (int restart = 0; restart < 2; ++restart) {
    if (restart == 1) Reopen(options);
    absl::StatusOr<EstimateResult> estimated = engine_->Estimate("mo", at);
    ASSERT_TRUE(estimated.ok()) << estimated.status();
    EXPECT_EQ(estimated->model_version, 30);
    const testing::DensePoLinUcb ref =
        testing::DensePoLinUcbReference(moved->config, seen, at);
    const Eigen::Map<const Eigen::VectorXd> predicted(
        estimated->predicted_posthoc.data(),
        estimated->predicted_posthoc.size());
    EXPECT_TRUE(bitewise::testing::RelNear(predicted, ref.p_hat, 1e-10));
    for (int a = 0; a < 6; ++a) {
      EXPECT_NEAR(estimated->estimates[a].predicted_loss, ref.predicted[a],
                  1e-10 * std::max(1.0, std::abs(ref.predicted[a])))
          << a;
      EXPECT_NEAR(estimated->estimates[a].lcb, ref.lcb[a],
                  1e-10 * std::max(1.0, std::abs(ref.lcb[a])))
          << a;
    }
  }
  EXPECT_EQ(engine_->Counters().checkpoint_loads, 0);  // the old one is gone
  EXPECT_EQ(engine_->Counters().checkpoints_ignored, 0);

  absl::StatusOr<UserRecord> back =
      engine_->SetLearner("mo", Learner::kPostHoc);
  ASSERT_TRUE(back.ok()) << back.status();
  absl::StatusOr<ModelExport> model = engine_->GetModel("mo");
  ASSERT_TRUE(model.ok()) << model.status();
  const std::vector<testing::DenseActionModel> ref =
      testing::DenseReference(back->config, seen);
  for (int a = 0; a < 6; ++a) {
    const Eigen::Map<const Eigen::VectorXd> theta(
        model->actions[a].theta.data(), model->actions[a].theta.size());
    EXPECT_TRUE(bitewise::testing::RelNear(theta, ref[a].theta, 1e-9)) << a;
  }

  EXPECT_EQ(engine_->SetLearner("nobody", Learner::kPoLinUcb).status().code(),
            absl::StatusCode::kNotFound);
  EXPECT_EQ(engine_->SetLearner("mo", static_cast<Learner>(9)).status().code(),
            absl::StatusCode::kInvalidArgument);
  // A refusal names why and leaves the user's learner as it was.
  const auto expect_refused = [&](const std::string& user, Learner to,
                                  const std::string& why, Learner kept) {
    absl::StatusOr<UserRecord> refused = engine_->SetLearner(user, to);
    EXPECT_EQ(refused.status().code(), absl::StatusCode::kFailedPrecondition);
    EXPECT_THAT(std::string(refused.status().message()),
                ::testing::HasSubstr(why));
    absl::StatusOr<UserRecord> after = engine_->GetUser(user);
    ASSERT_TRUE(after.ok());
    EXPECT_EQ(after->config.learner, kept);
  };
  // A context-only user's rounds without a post hoc context cannot be
  // learned by a post hoc learner: refused before anything is written.
  BanditConfig vision = SmallConfig();
  vision.learner = Learner::kContextOnly;
  ASSERT_TRUE(engine_->CreateUser("vi", vision).ok());
  for (int t = 0; t < 3; ++t) {
    absl::StatusOr<SelectResult> chosen =
        engine_->Select({"vi", RandomVector(8, rng), "m", "item"});
    ASSERT_TRUE(chosen.ok()) << chosen.status();
    ASSERT_TRUE(engine_->Update({chosen->event_id, 1.0, {}}).ok());
  }
  expect_refused("vi", Learner::kPostHoc, "cannot be learned by posthoc",
                 Learner::kContextOnly);
  EXPECT_TRUE(engine_->Select({"vi", RandomVector(8, rng), "m", "item"}).ok());
  // A user started from a pool keeps its learner: its prior is of that
  // learner's statistics.
  absl::StatusOr<PoolRecord> pool = engine_->BuildPopulationPool(SmallConfig());
  ASSERT_TRUE(pool.ok()) << pool.status();
  ASSERT_TRUE(engine_->CreateUser("primed", SmallConfig(), 2.0).ok());
  expect_refused("primed", Learner::kPoLinUcb, "population pool",
                 Learner::kPostHoc);
}

// A checkpoint is written outside the user's lock, so SetLearner can run
// while one of the old learner's is on its way to the store. The store
// refuses it (the user's learner no longer matches), and the engine drops
// only a model of that learner: the new learner's model, loaded meanwhile,
// stays loaded and keeps answering as the dense reference does, and no
// checkpoint is left behind. The store is the real SQLite one; the wrapper
// only holds PutCheckpoint until the test lets it go.
TEST_F(EngineTest, ALateCheckpointOfTheOldLearnerLeavesTheNewModelLoaded) {
  class HeldCheckpoints : public FaultWatchStore {
   public:
    using FaultWatchStore::FaultWatchStore;
    absl::Status PutCheckpoint(const std::string& user_id,
                               const ModelCheckpoint& checkpoint) override {
      {
        absl::MutexLock lock(&mu_);
        entered_ = true;
        mu_.Await(absl::Condition(&released_));
      }
      return FaultWatchStore::PutCheckpoint(user_id, checkpoint);
    }
    void AwaitEntered() {
      absl::MutexLock lock(&mu_);
      mu_.Await(absl::Condition(&entered_));
    }
    void Release() {
      absl::MutexLock lock(&mu_);
      released_ = true;
    }

   private:
    absl::Mutex mu_;
    bool entered_ = false, released_ = false;
  };
  engine_.reset();
  store_.reset();
  SqliteStoreOptions store_options;
  store_options.path = path_;
  store_options.synchronous_full = false;
  auto sqlite = SqliteEventStore::Open(store_options);
  ASSERT_TRUE(sqlite.ok()) << sqlite.status();
  HeldCheckpoints store(std::move(sqlite).value());
  EngineOptions options;
  options.checkpoint_min_events = 0;
  BanditEngine engine(&store, options);
  ASSERT_TRUE(engine.CreateUser("mo", SmallConfig()).ok());
  std::mt19937_64 rng(71);
  const std::vector<Round> seen = LearnRandomRounds(engine, "mo", 25, rng);
  ASSERT_EQ(seen.size(), 25u);
  const std::vector<double> at = RandomVector(8, rng);

  absl::Status late;
  std::thread writer([&] { late = engine.CheckpointUser("mo"); });
  store.AwaitEntered();  // the post hoc model's state is on its way
  absl::StatusOr<UserRecord> moved =
      engine.SetLearner("mo", Learner::kPoLinUcb);
  ASSERT_TRUE(moved.ok()) << moved.status();
  const testing::DensePoLinUcb ref =
      testing::DensePoLinUcbReference(moved->config, seen, at);
  const auto expect_reference = [&] {
    absl::StatusOr<EstimateResult> estimated = engine.Estimate("mo", at);
    ASSERT_TRUE(estimated.ok()) << estimated.status();
    EXPECT_EQ(estimated->model_version, 25);
    for (int a = 0; a < 6; ++a) {
      EXPECT_NEAR(estimated->estimates[a].lcb, ref.lcb[a],
                  1e-10 * std::max(1.0, std::abs(ref.lcb[a])))
          << a;
    }
  };
  expect_reference();  // loads the poLinUCB model from the log
  const int64_t rebuilds = engine.Counters().rebuilds;
  store.Release();
  writer.join();
  EXPECT_EQ(late.code(), absl::StatusCode::kFailedPrecondition) << late;
  EXPECT_EQ(store.GetCheckpoint("mo").status().code(),
            absl::StatusCode::kNotFound);
  expect_reference();
  EXPECT_EQ(engine.Counters().rebuilds, rebuilds);  // still loaded
  EXPECT_EQ(engine.Counters().checkpoints_written, 0);
}

// A poLinUCB user's Select carries the post hoc context the model predicts
// at the context, p_hat(c): the dense float64 reference's, from the rounds
// it has learned. Other learners predict none.
TEST_F(EngineTest, PoLinUcbSelectCarriesItsPredictedPosthocContext) {
  BanditConfig config = SmallConfig();
  config.learner = Learner::kPoLinUcb;
  ASSERT_TRUE(engine_->CreateUser("po", config).ok());
  ASSERT_TRUE(engine_->CreateUser("plain", SmallConfig()).ok());
  std::mt19937_64 rng(47);
  const std::vector<Round> seen = LearnRandomRounds(
      *engine_, "po", 25, rng,
      [](const SelectResult& r) { EXPECT_EQ(r.predicted_posthoc.size(), 4u); });
  ASSERT_EQ(seen.size(), 25u);
  absl::StatusOr<ModelExport> model = engine_->GetModel("po");
  ASSERT_TRUE(model.ok()) << model.status();
  const std::vector<double> at = RandomVector(8, rng);
  const testing::DensePoLinUcb ref =
      testing::DensePoLinUcbReference(model->user.config, seen, at);
  absl::StatusOr<SelectResult> chosen =
      engine_->Select(SelectInput{"po", at, "m", "item"});
  ASSERT_TRUE(chosen.ok()) << chosen.status();
  const Eigen::Map<const Eigen::VectorXd> predicted(
      chosen->predicted_posthoc.data(), chosen->predicted_posthoc.size());
  EXPECT_TRUE(bitewise::testing::RelNear(predicted, ref.p_hat, 1e-10));
  EXPECT_GT(ref.p_hat.norm(), 0.0);

  absl::StatusOr<SelectResult> plain =
      engine_->Select(SelectInput{"plain", at, "m", "item"});
  ASSERT_TRUE(plain.ok()) << plain.status();
  EXPECT_TRUE(plain->predicted_posthoc.empty());
}

}  // namespace
}  // namespace bitewise::bandit
