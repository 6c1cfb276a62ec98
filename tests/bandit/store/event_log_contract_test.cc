// The event log role of the store contract (event_log.h), on every
// backend: users, events, pages, exactness, durability, group commits.
#include "tests/bandit/store/store_test_fixture.h"

namespace bitewise::bandit::store_test {
namespace {

class EventLogContractTest : public StoreContractTest {
 protected:
  // alice (alpha 0.5) with one completed event and one pending, and bob
  // with none: what a reset or a new learner is tried on.
  struct Alice {
    UserRecord user;
    int64_t done = 0;
    int64_t pending = 0;
  };
  Alice AliceWithTwoEvents() {
    Alice alice{MakeUser("alice")};
    alice.user.config.alpha = 0.5;
    EXPECT_TRUE(store_->CreateUser(alice.user).ok());
    EXPECT_TRUE(store_->CreateUser(MakeUser("bob")).ok());
    alice.done = MustAppend(MakeEvent("alice", "m"));
    MustComplete(alice.done);
    alice.pending = MustAppend(MakeEvent("alice", "m"));
    return alice;
  }
};
INSTANTIATE_TEST_SUITE_P(Stores, EventLogContractTest, kAllBackends,
                         BackendName);

TEST_P(EventLogContractTest, CreateAndGetUserRoundTripsConfig) {
  UserRecord user = MakeUser("alice");
  BanditConfig& c = user.config;
  c.learner = Learner::kContextOnly;
  c.strategy = Strategy::kThompson;
  c.alpha = 0.1 + 0.2;
  c.lambda_c = std::numeric_limits<double>::denorm_min();
  c.lambda_p = 1e300;
  c.epsilon = -0.0;
  c.phi_radius = 1.0 / 3;
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
  EXPECT_EQ(Bits(got.config.phi_radius), Bits(1.0 / 3));
  EXPECT_TRUE(got.config.importance_weighting);
  EXPECT_EQ(got.config.context_dim, 7);
  EXPECT_EQ(got.config.posthoc_dim, 0);
  EXPECT_EQ(got.config.action_names, c.action_names);
  EXPECT_EQ(got.config.seed, std::numeric_limits<uint64_t>::max());
  EXPECT_EQ(got.created_at, user.created_at);
  EXPECT_EQ(got.model_version, 0);
  EXPECT_EQ(got.pending_events, 0);
}

TEST_P(EventLogContractTest, DuplicateUserIsAlreadyExistsAndKeepsOriginal) {
  ASSERT_TRUE(store_->CreateUser(MakeUser("alice")).ok());
  UserRecord again = MakeUser("alice");
  again.config.alpha = 5.0;
  const absl::Status status = store_->CreateUser(again);
  EXPECT_EQ(status.code(), absl::StatusCode::kAlreadyExists) << status;
  EXPECT_THAT(status.message(), HasSubstr("alice"));
  EXPECT_EQ(MustGetUser("alice").config.alpha, SmallConfig().alpha);
}

TEST_P(EventLogContractTest, CreateUserRejectsInvalidInput) {
  EXPECT_EQ(store_->CreateUser(MakeUser("")).code(),
            absl::StatusCode::kInvalidArgument);
  UserRecord bad = MakeUser("bob");
  bad.config.context_dim = 0;
  EXPECT_EQ(store_->CreateUser(bad).code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(store_->GetUser("bob").status().code(),
            absl::StatusCode::kNotFound);
}

TEST_P(EventLogContractTest, UnknownUserIsNotFoundEverywhere) {
  EXPECT_EQ(store_->GetUser("nobody").status().code(),
            absl::StatusCode::kNotFound);
  EXPECT_EQ(store_->DeleteUser("nobody").code(), absl::StatusCode::kNotFound);
  EXPECT_EQ(store_->ResetUser("nobody").code(), absl::StatusCode::kNotFound);
  EXPECT_EQ(store_->SetLearner("nobody", Learner::kPoLinUcb, 0).code(),
            absl::StatusCode::kNotFound);
  const auto appended = store_->AppendPending(MakeEvent("nobody", "m"));
  EXPECT_EQ(appended.status().code(), absl::StatusCode::kNotFound);
  EXPECT_THAT(appended.status().message(), HasSubstr("nobody"));
  EXPECT_EQ(store_->ListEvents("nobody", "", Page()).status().code(),
            absl::StatusCode::kNotFound);
  EXPECT_EQ(store_->CompletedEvents("nobody").status().code(),
            absl::StatusCode::kNotFound);
}

TEST_P(EventLogContractTest, ListUsersPagesInUserIdOrder) {
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

TEST_P(EventLogContractTest, ListUsersExactPageHasNoNextToken) {
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

TEST_P(EventLogContractTest, ListUsersClampsPageSizeTo1000) {
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

TEST_P(EventLogContractTest, InvalidPageTokensAreInvalidArgument) {
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

TEST_P(EventLogContractTest, AppendAndCompleteEvent) {
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

TEST_P(EventLogContractTest, DoubleCompletionIsRejectedAndChangesNothing) {
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
TEST_P(EventLogContractTest, ConcurrentWritesCommitInGroupsAndFailAlone) {
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

TEST_P(EventLogContractTest, UnknownEventIsNotFound) {
  ASSERT_TRUE(store_->CreateUser(MakeUser("alice")).ok());
  auto completed =
      store_->CompleteEvent(123, 1.0, {}, 1.0, absl::FromUnixMicros(0));
  EXPECT_EQ(completed.status().code(), absl::StatusCode::kNotFound);
  EXPECT_EQ(completed.status().message(), "event 123 not found");
  EXPECT_EQ(store_->GetEvent(123).status().code(), absl::StatusCode::kNotFound);
  EXPECT_EQ(MustGetUser("alice").model_version, 0);
}

TEST_P(EventLogContractTest, DoublesRoundTripExactly) {
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

TEST_P(EventLogContractTest, EmptyVectorsRoundTrip) {
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

TEST_P(EventLogContractTest, NanScalarsAreRejected) {
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

TEST_P(EventLogContractTest, ListEventsFiltersByMealWithPaging) {
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

TEST_P(EventLogContractTest, CompletedEventsAreInModelVersionOrder) {
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

TEST_P(EventLogContractTest, ResetUserDeletesEventsAndKeepsConfig) {
  const auto [user, done, pending] = AliceWithTwoEvents();
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

TEST_P(EventLogContractTest, SetLearnerKeepsEveryEventAndTheRestOfTheConfig) {
  const auto [user, done, pending] = AliceWithTwoEvents();
  const UserRecord before = MustGetUser("alice");

  // Only on the log it was checked on: one completed event.
  const absl::Status moved_on =
      store_->SetLearner("alice", Learner::kPoLinUcb, 0);
  EXPECT_EQ(moved_on.code(), absl::StatusCode::kAborted);
  EXPECT_THAT(std::string(moved_on.message()),
              HasSubstr("has 1 completed events, not the 0"));
  EXPECT_EQ(MustGetUser("alice").config.learner, before.config.learner);
  ASSERT_TRUE(store_->SetLearner("alice", Learner::kPoLinUcb, 1).ok());
  const UserRecord moved = MustGetUser("alice");
  EXPECT_EQ(moved.config.learner, Learner::kPoLinUcb);
  EXPECT_EQ(moved.config.alpha, 0.5);
  EXPECT_EQ(moved.config.seed, before.config.seed);
  EXPECT_EQ(moved.model_version, 1);
  EXPECT_EQ(moved.pending_events, 1);
  EXPECT_EQ(moved.created_at, before.created_at);
  EXPECT_TRUE(MustGetEvent(done).completed);
  EXPECT_FALSE(MustGetEvent(pending).completed);
  EXPECT_EQ(MustGetUser("bob").config.learner, MakeUser("bob").config.learner);
  // The log goes on where it was.
  EXPECT_EQ(MustComplete(pending).model_version, 2);
}

TEST_P(EventLogContractTest, DeleteUserCascadesToEvents) {
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

TEST_P(EventLogContractTest, DataSurvivesReopening) {
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

TEST_P(EventLogContractTest, AcknowledgedUpdateSurvivesKill9) {
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

TEST_P(EventLogContractTest, AlteredEventIsDataLossNamingIt) {
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
TEST_P(EventLogContractTest, PagesEndByBytesToo) {
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

TEST_P(EventLogContractTest, WriteStatsCountTheHotPath) {
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

TEST_P(EventLogContractTest, CorruptVectorIsDataLoss) {
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

TEST_P(EventLogContractTest, FailedCompletionRollsBackEverything) {
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

TEST_P(EventLogContractTest, ConcurrentWritersKeepCountsRight) {
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

}  // namespace
}  // namespace bitewise::bandit::store_test
