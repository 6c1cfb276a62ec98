// BanditEngine replicas: several engines, each on its own PostgresEventStore
// (its own connections, as separate processes have), serving the same users
// of one database on a real PostgreSQL server the test starts. Checked: a
// scripted meal whose Selects and Updates alternate between two replicas
// chooses exactly what one engine alone chooses (same actions, same
// propensities, the same seeded random draws) with the same estimates;
// replicas hammering the same users from threads keep every update, in order,
// and every replica's model equals the dense float64 reference on the union
// of the events; a reset on one replica is seen by the other (and a
// checkpoint of the older log's model is refused and the model dropped).
#include <atomic>
#include <cmath>
#include <memory>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "absl/strings/str_cat.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "services/bandit/engine.h"
#include "services/bandit/store/postgres_event_store.h"
#include "tests/bandit/dense_reference.h"
#include "tests/common/postgres_server.h"

namespace bitewise::bandit {
namespace {

constexpr int kDim = 8;
constexpr int kPostHocDim = 4;

std::vector<double> RandomVector(int n, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<double> v(n);
  for (double& x : v) x = u(rng);
  return v;
}

BanditConfig ConfigWith(Strategy strategy) {
  BanditConfig config;
  config.context_dim = kDim;
  config.posthoc_dim = kPostHocDim;
  config.strategy = strategy;
  config.alpha = 0.3;
  config.lambda_c = 2.0;
  config.epsilon = 0.4;
  config.seed = 2021;
  return config;
}

// A database on the test's server and the engines (replicas) serving it.
class Deployment {
 public:
  explicit Deployment(const std::string& name, int replicas) {
    bitewise::testing::TestPostgres* server =
        bitewise::testing::SharedTestPostgres();
    EXPECT_NE(server, nullptr);
    if (server == nullptr) return;
    static int databases = 0;
    server_ = server;
    database_ = absl::StrCat(name, "_", ++databases);
    absl::StatusOr<std::string> conninfo = server->CreateDatabase(database_);
    EXPECT_TRUE(conninfo.ok()) << conninfo.status();
    conninfo_ = conninfo.value_or("");
    for (int r = 0; r < replicas; ++r) AddReplica();
  }

  void AddReplica() {
    PostgresStoreOptions options;
    options.conninfo = conninfo_;
    options.connections = 3;
    auto store = PostgresEventStore::Open(options);
    ASSERT_TRUE(store.ok()) << store.status();
    stores_.push_back(std::move(store).value());
    EngineOptions engine_options;
    engine_options.checkpoint_min_events = 0;  // no background writes
    engines_.push_back(
        std::make_unique<BanditEngine>(stores_.back().get(), engine_options));
  }

  BanditEngine& replica(size_t i) { return *engines_.at(i); }
  EventStore& store() { return *stores_.at(0); }
  size_t size() const { return engines_.size(); }
  // SQL on the database, as an administrator's shell would run it.
  void Sql(const std::string& sql) {
    absl::StatusOr<std::string> done = server_->Query(database_, sql);
    EXPECT_TRUE(done.ok()) << done.status();
  }

 private:
  bitewise::testing::TestPostgres* server_ = nullptr;
  std::string database_;
  std::string conninfo_;
  std::vector<std::unique_ptr<PostgresEventStore>> stores_;
  std::vector<std::unique_ptr<BanditEngine>> engines_;
};

// Every action's theta and phi against the dense reference on the log the
// store holds (relative 1e-9).
void ExpectDenseReference(BanditEngine& engine, EventStore& store,
                          const std::string& user) {
  absl::StatusOr<ModelExport> model = engine.GetModel(user);
  ASSERT_TRUE(model.ok()) << model.status();
  absl::StatusOr<std::vector<EventRecord>> log = store.CompletedEvents(user);
  ASSERT_TRUE(log.ok()) << log.status();
  std::vector<Round> rounds;
  for (const EventRecord& event : *log) rounds.push_back(EventRound(event));
  const std::vector<testing::DenseActionModel> reference =
      testing::DenseReference(model->user.config, rounds);
  ASSERT_EQ(model->actions.size(), reference.size());
  for (size_t a = 0; a < reference.size(); ++a) {
    for (int i = 0; i < kDim; ++i) {
      const double want = reference[a].theta(i);
      EXPECT_NEAR(model->actions[a].theta[i], want,
                  1e-9 * std::max(1.0, std::abs(want)))
          << user << " action " << a << " theta " << i;
    }
    for (int i = 0; i < kPostHocDim; ++i) {
      const double want = reference[a].phi(i);
      EXPECT_NEAR(model->actions[a].phi[i], want,
                  1e-9 * std::max(1.0, std::abs(want)))
          << user << " action " << a << " phi " << i;
    }
  }
}

struct Choice {
  int action = 0;
  double propensity = 0.0;
  int64_t model_version = 0;
  std::vector<ActionEstimate> estimates;
};

TEST(ReplicaTest, TwoReplicasChooseExactlyWhatOneEngineChooses) {
  Deployment alone("alone", 1);
  Deployment pair("pair", 2);
  const std::vector<std::pair<std::string, Strategy>> users = {
      {"eps", Strategy::kEpsilonGreedy},
      {"thompson", Strategy::kThompson},
      {"ucb", Strategy::kLinUcb}};
  for (const auto& [user, strategy] : users) {
    ASSERT_TRUE(alone.replica(0).CreateUser(user, ConfigWith(strategy)).ok());
    ASSERT_TRUE(pair.replica(1).CreateUser(user, ConfigWith(strategy)).ok());
  }
  // The same script on both deployments: each bite is a Select and its
  // Update; in the pair, the replica of each call is drawn at random, and
  // some bites leave their Update for after the next bite's Select.
  constexpr int kBites = 90;
  std::vector<Choice> chosen[2];
  for (int run = 0; run < 2; ++run) {
    Deployment& deployment = run == 0 ? alone : pair;
    std::mt19937_64 script(77);
    std::bernoulli_distribution coin(0.5);
    std::vector<std::pair<int64_t, UpdateInput>> held;  // Updates held back
    for (int t = 0; t < kBites; ++t) {
      const std::string& user = users[t % users.size()].first;
      SelectInput select{user, RandomVector(kDim, script), "meal", "item"};
      const size_t select_on = coin(script) ? 1 : 0;
      absl::StatusOr<SelectResult> selected =
          deployment.replica(select_on % deployment.size()).Select(select);
      ASSERT_TRUE(selected.ok()) << selected.status();
      chosen[run].push_back({selected->action, selected->propensity,
                             selected->model_version, selected->estimates});
      UpdateInput update{selected->event_id,
                         std::uniform_real_distribution<double>(0, 1)(script),
                         RandomVector(kPostHocDim, script)};
      const size_t update_on = coin(script) ? 1 : 0;
      const bool hold = coin(script);
      held.push_back({static_cast<int64_t>(update_on), update});
      // Every Update is sent before the user's next Select (the
      // orchestrator's order); held ones after another user's Select.
      while (held.size() > (hold ? 1u : 0u)) {
        auto [on, input] = held.front();
        held.erase(held.begin());
        absl::StatusOr<UpdateResult> updated =
            deployment.replica(static_cast<size_t>(on) % deployment.size())
                .Update(input);
        ASSERT_TRUE(updated.ok()) << updated.status();
      }
    }
    for (auto& [on, input] : held) {
      ASSERT_TRUE(
          deployment.replica(static_cast<size_t>(on) % deployment.size())
              .Update(input)
              .ok());
    }
  }
  ASSERT_EQ(chosen[0].size(), chosen[1].size());
  int explored = 0;
  for (size_t t = 0; t < chosen[0].size(); ++t) {
    EXPECT_EQ(chosen[1][t].action, chosen[0][t].action) << "bite " << t;
    EXPECT_EQ(chosen[1][t].propensity, chosen[0][t].propensity) << "bite " << t;
    EXPECT_EQ(chosen[1][t].model_version, chosen[0][t].model_version)
        << "bite " << t;
    for (size_t a = 0; a < chosen[0][t].estimates.size(); ++a) {
      EXPECT_NEAR(chosen[1][t].estimates[a].lcb, chosen[0][t].estimates[a].lcb,
                  1e-12)
          << "bite " << t << " action " << a;
    }
    if (chosen[0][t].propensity < 1.0) ++explored;
  }
  EXPECT_GT(explored, 10);  // the random draws mattered
  std::mt19937_64 probe(5);
  const std::vector<double> context = RandomVector(kDim, probe);
  for (const auto& [user, strategy] : users) {
    for (size_t r = 0; r < pair.size(); ++r) {
      ExpectDenseReference(pair.replica(r), pair.store(), user);
    }
    // Either replica's Estimate is caught up with the other's writes: the
    // same answer as the one engine's.
    absl::StatusOr<EstimateResult> one =
        alone.replica(0).Estimate(user, context);
    ASSERT_TRUE(one.ok()) << one.status();
    for (size_t r = 0; r < pair.size(); ++r) {
      absl::StatusOr<EstimateResult> each =
          pair.replica(r).Estimate(user, context);
      ASSERT_TRUE(each.ok()) << each.status();
      EXPECT_EQ(each->model_version, one->model_version) << user;
      ASSERT_EQ(each->estimates.size(), one->estimates.size());
      for (size_t a = 0; a < one->estimates.size(); ++a) {
        EXPECT_NEAR(each->estimates[a].predicted_loss,
                    one->estimates[a].predicted_loss, 1e-12)
            << user << " action " << a;
        EXPECT_NEAR(each->estimates[a].lcb, one->estimates[a].lcb, 1e-12)
            << user << " action " << a;
      }
    }
  }
}

TEST(ReplicaTest, ConcurrentReplicasKeepEveryUpdateOfTheSameUsers) {
  Deployment pair("concurrent", 2);
  constexpr int kUsers = 3;
  constexpr int kPairsPerThread = 25;
  for (int u = 0; u < kUsers; ++u) {
    ASSERT_TRUE(
        pair.replica(0)
            .CreateUser(absl::StrCat("u", u), ConfigWith(Strategy::kLinUcb))
            .ok());
  }
  std::atomic<int> failures{0};
  std::atomic<bool> writing{true};
  // A reader on replica 1 while both write: each GetModel's version is the
  // position of the numbers it returns (it once came from a second read of
  // the store, a version ahead of the numbers).
  std::atomic<int> models_read{0};
  std::thread reader([&] {
    while (writing.load()) {
      absl::StatusOr<ModelExport> model = pair.replica(1).GetModel("u0");
      ASSERT_TRUE(model.ok()) << model.status();
      int64_t counted = 0;
      for (const ActionModelExport& action : model->actions) {
        counted += action.count;
      }
      ASSERT_EQ(model->user.model_version, counted);
      ++models_read;
    }
  });
  std::vector<std::thread> threads;
  for (size_t r = 0; r < pair.size(); ++r) {
    for (int worker = 0; worker < 2; ++worker) {
      threads.emplace_back([&, r, worker] {
        std::mt19937_64 rng(100 * r + worker);
        for (int i = 0; i < kPairsPerThread; ++i) {
          const std::string user = absl::StrCat("u", (i + worker) % kUsers);
          absl::StatusOr<SelectResult> selected = pair.replica(r).Select(
              {user, RandomVector(kDim, rng), "meal", "item"});
          if (!selected.ok()) {
            ++failures;
            continue;
          }
          // The Update on either replica.
          const size_t other = (r + i) % pair.size();
          if (!pair.replica(other)
                   .Update({selected->event_id,
                            std::uniform_real_distribution<double>(0, 1)(rng),
                            RandomVector(kPostHocDim, rng)})
                   .ok()) {
            ++failures;
          }
        }
      });
    }
  }
  for (std::thread& thread : threads) thread.join();
  writing = false;
  reader.join();
  EXPECT_GT(models_read.load(), 0);
  EXPECT_EQ(failures.load(), 0);
  int64_t total = 0;
  for (int u = 0; u < kUsers; ++u) {
    const std::string user = absl::StrCat("u", u);
    absl::StatusOr<std::vector<EventRecord>> log =
        pair.store().CompletedEvents(user);
    ASSERT_TRUE(log.ok()) << log.status();
    for (size_t k = 0; k < log->size(); ++k) {
      EXPECT_EQ((*log)[k].model_version, static_cast<int64_t>(k) + 1);
    }
    total += static_cast<int64_t>(log->size());
    for (size_t r = 0; r < pair.size(); ++r) {
      ExpectDenseReference(pair.replica(r), pair.store(), user);
    }
  }
  EXPECT_EQ(total, 2 * 2 * kPairsPerThread);
  // The replicas learned each other's updates by catching up.
  const int64_t caught_up = pair.replica(0).Counters().caught_up_events +
                            pair.replica(1).Counters().caught_up_events;
  EXPECT_GT(caught_up, 0);
  // Each Select after the other replica's Update of the user met it: the
  // write was refused, the model caught up, and the Select tried again.
  EXPECT_GT(pair.replica(0).Counters().write_conflicts +
                pair.replica(1).Counters().write_conflicts,
            0);
}

TEST(ReplicaTest, AResetOnOneReplicaIsSeenByTheOther) {
  Deployment pair("reset", 2);
  ASSERT_TRUE(
      pair.replica(0).CreateUser("ann", ConfigWith(Strategy::kLinUcb)).ok());
  std::mt19937_64 rng(5);
  for (int t = 0; t < 6; ++t) {
    BanditEngine& engine = pair.replica(t % 2);
    absl::StatusOr<SelectResult> selected =
        engine.Select({"ann", RandomVector(kDim, rng), "m", "i"});
    ASSERT_TRUE(selected.ok()) << selected.status();
    ASSERT_TRUE(
        engine.Update({selected->event_id, 1.0, RandomVector(kPostHocDim, rng)})
            .ok());
  }
  // Both have ann's model loaded, at version 6; replica 0 resets her.
  ASSERT_EQ(pair.replica(1).GetUser("ann")->model_version, 6);
  ASSERT_TRUE(pair.replica(0).ResetUser("ann").ok());
  absl::StatusOr<SelectResult> after =
      pair.replica(1).Select({"ann", RandomVector(kDim, rng), "m", "i"});
  ASSERT_TRUE(after.ok()) << after.status();
  EXPECT_EQ(after->model_version, 0);
  EXPECT_GE(pair.replica(1).Counters().dropped_stale, 1);
  ASSERT_TRUE(
      pair.replica(1)
          .Update({after->event_id, 0.0, RandomVector(kPostHocDim, rng)})
          .ok());
  ExpectDenseReference(pair.replica(1), pair.store(), "ann");
  // A new learner on replica 0: replica 1 drops its cached model and
  // rebuilds ann's from the log under poLinUCB.
  ASSERT_TRUE(pair.replica(0).SetLearner("ann", Learner::kPoLinUcb).ok());
  absl::StatusOr<SelectResult> moved =
      pair.replica(1).Select({"ann", RandomVector(kDim, rng), "m", "i"});
  ASSERT_TRUE(moved.ok()) << moved.status();
  EXPECT_EQ(moved->model_version, 1);
  EXPECT_EQ(moved->predicted_posthoc.size(), static_cast<size_t>(kPostHocDim));
  EXPECT_GE(pair.replica(1).Counters().dropped_stale, 2);
  ASSERT_TRUE(
      pair.replica(1)
          .Update({moved->event_id, 0.0, RandomVector(kPostHocDim, rng)})
          .ok());
  // And back: replica 1's poLinUCB model is not saved as ann's checkpoint
  // (its events are all there, its learner is not ann's), and is dropped.
  ASSERT_TRUE(pair.replica(0).SetLearner("ann", Learner::kPostHoc).ok());
  ASSERT_EQ(pair.replica(1).CachedModels(), 1);
  EXPECT_EQ(pair.replica(1).CheckpointUser("ann").code(),
            absl::StatusCode::kFailedPrecondition);
  EXPECT_EQ(pair.replica(1).CachedModels(), 0);
  absl::StatusOr<SelectResult> back =
      pair.replica(1).Select({"ann", RandomVector(kDim, rng), "m", "i"});
  ASSERT_TRUE(back.ok()) << back.status();
  EXPECT_TRUE(back->predicted_posthoc.empty());
  ASSERT_TRUE(pair.replica(1)
                  .Update({back->event_id, 1.0, RandomVector(kPostHocDim, rng)})
                  .ok());
  ExpectDenseReference(pair.replica(1), pair.store(), "ann");
  // Reset again: replica 1's cached model (version 3) is of the old log. A
  // checkpoint of it is refused, and the model is dropped rather than
  // offered again at every poll.
  ASSERT_TRUE(pair.replica(0).ResetUser("ann").ok());
  ASSERT_EQ(pair.replica(1).CachedModels(), 1);
  EXPECT_EQ(pair.replica(1).CheckpointUser("ann").code(),
            absl::StatusCode::kFailedPrecondition);
  EXPECT_EQ(pair.replica(1).CachedModels(), 0);
  // And a deleted user is gone for the other replica too.
  ASSERT_TRUE(pair.replica(0).DeleteUser("ann").ok());
  EXPECT_EQ(pair.replica(1)
                .Select({"ann", RandomVector(kDim, rng), "m", "i"})
                .status()
                .code(),
            absl::StatusCode::kNotFound);
}

TEST(ReplicaTest, AWriteThatKeepsMeetingOthersGivesUpAsUnavailable) {
  // Every append made to look as if another replica had just written (a
  // trigger drops the update of the user's count of selections): the
  // engine catches up and tries again, and after its last attempt answers
  // UNAVAILABLE naming the user, which clients retry; nothing is written.
  Deployment one("conflicts", 1);
  ASSERT_TRUE(
      one.replica(0).CreateUser("ann", ConfigWith(Strategy::kLinUcb)).ok());
  std::mt19937_64 rng(9);
  one.Sql(
      "CREATE FUNCTION keep_selections() RETURNS trigger LANGUAGE plpgsql AS "
      "$$ BEGIN IF NEW.selections <> OLD.selections THEN RETURN NULL; END IF; "
      "RETURN NEW; END $$; CREATE TRIGGER keep_selections BEFORE UPDATE ON "
      "users FOR EACH ROW EXECUTE FUNCTION keep_selections()");
  const absl::StatusOr<SelectResult> refused =
      one.replica(0).Select({"ann", RandomVector(kDim, rng), "m", "i"});
  EXPECT_EQ(refused.status().code(), absl::StatusCode::kUnavailable)
      << refused.status();
  EXPECT_THAT(std::string(refused.status().message()),
              ::testing::HasSubstr("user \"ann\""));
  EXPECT_THAT(std::string(refused.status().message()),
              ::testing::HasSubstr("at each of 8 attempts"));
  EXPECT_EQ(one.replica(0).Counters().write_conflicts, 8);
  EXPECT_EQ(one.store().GetUser("ann")->pending_events, 0);
  // The trigger gone, the next Select goes through.
  one.Sql("DROP TRIGGER keep_selections ON users");
  const absl::StatusOr<SelectResult> selected =
      one.replica(0).Select({"ann", RandomVector(kDim, rng), "m", "i"});
  ASSERT_TRUE(selected.ok()) << selected.status();
  EXPECT_EQ(one.store().GetUser("ann")->pending_events, 1);
  // The same for an Update whose completion always looks overtaken.
  one.Sql(
      "CREATE FUNCTION keep_version() RETURNS trigger LANGUAGE plpgsql AS $$ "
      "BEGIN IF NEW.model_version <> OLD.model_version THEN RETURN NULL; END "
      "IF; RETURN NEW; END $$; CREATE TRIGGER keep_version BEFORE UPDATE ON "
      "users FOR EACH ROW EXECUTE FUNCTION keep_version()");
  const UpdateInput update{selected->event_id, 0.5,
                           RandomVector(kPostHocDim, rng)};
  const absl::StatusOr<UpdateResult> not_applied =
      one.replica(0).Update(update);
  EXPECT_EQ(not_applied.status().code(), absl::StatusCode::kUnavailable)
      << not_applied.status();
  EXPECT_EQ(one.replica(0).Counters().write_conflicts, 16);
  EXPECT_FALSE(one.store().GetEvent(selected->event_id)->completed);
  one.Sql("DROP TRIGGER keep_version ON users");
  const absl::StatusOr<UpdateResult> applied = one.replica(0).Update(update);
  ASSERT_TRUE(applied.ok()) << applied.status();
  EXPECT_EQ(applied->model_version, 1);
  ExpectDenseReference(one.replica(0), one.store(), "ann");
}

}  // namespace
}  // namespace bitewise::bandit
