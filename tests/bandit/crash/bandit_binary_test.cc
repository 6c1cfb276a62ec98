// End-to-end tests of the real bitewise-bandit binary, started as a child
// process on a fresh SQLite file and on a fresh PostgreSQL database: no
// acknowledged update is lost to SIGKILL, the served estimates agree with
// the dense float64 reference, SIGTERM drains and exits 0, and bad input
// gets the documented status codes without touching the model.
#include <grpcpp/client_context.h>
#include <signal.h>
#include <stdlib.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <random>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "Eigen/Dense"
#include "absl/base/casts.h"
#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "absl/time/time.h"
#include "bitewise/v1/bandit.grpc.pb.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "services/bandit/core/config.h"
#include "services/bandit/core/linucb.h"
#include "services/common/channel.h"
#include "services/common/grpc_status.h"
#include "services/common/status_macros.h"
#include "tests/bandit/crash/bandit_process.h"
#include "tests/bandit/dense_reference.h"
#include "tests/common/child_process.h"
#include "tests/common/near.h"
#include "tests/common/postgres_server.h"

namespace bitewise {
namespace {

using testing::DescribeWaitStatus;
using ::testing::HasSubstr;
using testing::ReadFile;

std::vector<double> RandomVector(int n, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<double> v(n);
  for (double& x : v) x = u(rng);
  return v;
}

// Bit-for-bit equality, so that -0.0, subnormals and the last ulp count.
template <typename Container>
::testing::AssertionResult BitEqual(const Container& actual,
                                    const std::vector<double>& expected) {
  if (static_cast<size_t>(actual.size()) != expected.size()) {
    return ::testing::AssertionFailure()
           << "length " << actual.size() << " vs " << expected.size();
  }
  for (size_t i = 0; i < expected.size(); ++i) {
    const double a = actual[static_cast<int>(i)];
    if (absl::bit_cast<uint64_t>(a) != absl::bit_cast<uint64_t>(expected[i])) {
      return ::testing::AssertionFailure() << "[" << i << "]: " << a << " vs "
                                           << expected[i] << " (bits differ)";
    }
  }
  return ::testing::AssertionSuccess();
}

::testing::AssertionResult BitEqual(double actual, double expected) {
  if (absl::bit_cast<uint64_t>(actual) == absl::bit_cast<uint64_t>(expected)) {
    return ::testing::AssertionSuccess();
  }
  return ::testing::AssertionFailure()
         << actual << " vs " << expected << " (bits differ)";
}

// What the test sent for one completed round and what the server answered.
struct SentRound {
  std::string event_id;
  std::vector<double> context;
  int action = 0;
  double loss = 0.0;
  std::vector<double> posthoc;
  int64_t model_version = 0;  // returned by the acknowledged Update
};

bandit::Round ToRound(const SentRound& sent) {
  bandit::Round round;
  round.context = sent.context;
  round.action = sent.action;
  round.loss = sent.loss;
  round.posthoc = sent.posthoc;
  round.weight = 1.0;
  return round;
}

// Compares the served estimates at `context` with the dense reference.
void ExpectEstimatesMatchReference(
    const v1::SelectResponse& response,
    const std::vector<bandit::testing::DenseActionModel>& reference,
    const std::vector<double>& context, double alpha, double tol) {
  ASSERT_EQ(response.estimates_size(), static_cast<int>(reference.size()));
  const Eigen::Map<const Eigen::VectorXd> c(context.data(), context.size());
  for (int a = 0; a < response.estimates_size(); ++a) {
    const v1::ActionEstimate& got = response.estimates(a);
    const double predicted = reference[a].theta.dot(c);
    const double width = std::sqrt(c.dot(reference[a].sigma * c));
    const double lcb = predicted - alpha * width;
    EXPECT_EQ(got.action(), a);
    EXPECT_TRUE(
        bitewise::testing::RelNear(got.predicted_loss(), predicted, tol))
        << "action " << a << " predicted_loss";
    EXPECT_TRUE(bitewise::testing::RelNear(got.width(), width, tol))
        << "action " << a << " width";
    EXPECT_TRUE(bitewise::testing::RelNear(got.lcb(), lcb, tol))
        << "action " << a << " lcb";
  }
}

// Compares an exported model with the dense reference.
void ExpectModelMatchesReference(
    const v1::Model& model,
    const std::vector<bandit::testing::DenseActionModel>& reference,
    const std::vector<bandit::Round>& rounds, bool posthoc, double tol) {
  ASSERT_EQ(model.actions_size(), static_cast<int>(reference.size()));
  std::vector<int64_t> counts(reference.size(), 0);
  for (const bandit::Round& round : rounds) ++counts[round.action];
  for (int a = 0; a < model.actions_size(); ++a) {
    const v1::ActionModel& got = model.actions(a);
    EXPECT_EQ(got.action(), a);
    EXPECT_EQ(got.count(), counts[a]) << "action " << a;
    ASSERT_EQ(got.theta_size(), reference[a].theta.size()) << "action " << a;
    for (int i = 0; i < got.theta_size(); ++i) {
      EXPECT_TRUE(
          bitewise::testing::RelNear(got.theta(i), reference[a].theta(i), tol))
          << "action " << a << " theta[" << i << "]";
    }
    if (!posthoc) {
      EXPECT_EQ(got.phi_size(), 0) << "action " << a;
      continue;
    }
    ASSERT_EQ(got.phi_size(), reference[a].phi.size()) << "action " << a;
    for (int i = 0; i < got.phi_size(); ++i) {
      EXPECT_TRUE(
          bitewise::testing::RelNear(got.phi(i), reference[a].phi(i), tol))
          << "action " << a << " phi[" << i << "]";
    }
  }
}

// Each test runs on a fresh SQLite file and on a fresh database of a
// PostgreSQL server the test binary starts (tests/common/postgres_server.h).
class BanditBinaryTest : public ::testing::TestWithParam<std::string> {
 protected:
  void SetUp() override {
    std::string pattern =
        (std::filesystem::temp_directory_path() / "bandit_binary_test.XXXXXX")
            .string();
    ASSERT_NE(mkdtemp(pattern.data()), nullptr) << std::strerror(errno);
    dir_ = pattern;
    if (GetParam() == "postgresql") {
      testing::TestPostgres* server = testing::SharedTestPostgres();
      ASSERT_NE(server, nullptr);
      static int databases = 0;
      absl::StatusOr<std::string> conninfo =
          server->CreateDatabase(absl::StrCat("binary_test_", ++databases));
      ASSERT_TRUE(conninfo.ok()) << conninfo.status();
      db_ = *conninfo;
    } else {
      db_ = dir_ + "/bandit.db";
    }
  }

  void TearDown() override {
    server_.Kill();
    if (HasFailure()) {
      for (int i = 0; i < starts_; ++i) {
        std::cerr << "---- " << LogPath(i) << "\n"
                  << ReadFile(LogPath(i)) << "----\n";
      }
    }
    std::error_code ignored;
    std::filesystem::remove_all(dir_, ignored);
  }

  std::string LogPath(int start) const {
    return absl::StrCat(dir_, "/server-", start, ".log");
  }

  // Starts (or restarts) the binary on the test's database, with a fresh
  // log file per start.
  absl::Status StartServer() { return server_.Start(db_, LogPath(starts_++)); }

  v1::BanditService::Stub& stub() { return server_.stub(); }

  // A post hoc user with small dimensions and non-default hyperparameters.
  absl::StatusOr<v1::User> CreateUser(const std::string& user_id,
                                      v1::Learner learner, int context_dim,
                                      int posthoc_dim, double alpha,
                                      double lambda_c, double lambda_p,
                                      std::optional<double> phi_radius = {}) {
    v1::CreateUserRequest request;
    request.set_user_id(user_id);
    v1::UserConfig* config = request.mutable_config();
    config->set_learner(learner);
    config->set_strategy(v1::STRATEGY_LINUCB);
    config->set_context_dim(context_dim);
    config->set_posthoc_dim(posthoc_dim);
    config->set_alpha(alpha);
    config->set_lambda_c(lambda_c);
    config->set_lambda_p(lambda_p);
    if (phi_radius.has_value()) config->set_phi_radius(*phi_radius);
    config->set_seed(7);
    return Call(stub(), &v1::BanditService::Stub::CreateUser, request);
  }

  std::string dir_;
  std::string db_;
  int starts_ = 0;
  ServerProcess server_;
};

INSTANTIATE_TEST_SUITE_P(Stores, BanditBinaryTest,
                         ::testing::Values("sqlite", "postgresql"),
                         [](const ::testing::TestParamInfo<std::string>& info) {
                           return info.param;
                         });

TEST_P(BanditBinaryTest, SigkillLosesNoAcknowledgedUpdate) {
  constexpr char kUser[] = "kill-user";
  // 600 features: each context (4,800 bytes) lives in the SQLite store's
  // contexts file, beside the database, as SPANet's would.
  constexpr int kDim = 600;
  constexpr int kPostHocDim = 4;
  constexpr int kRounds = 60;
  absl::Status started = StartServer();
  ASSERT_TRUE(started.ok()) << started;
  {
    absl::StatusOr<v1::User> user = CreateUser(kUser, v1::LEARNER_POSTHOC, kDim,
                                               kPostHocDim, 0.3, 2.0, 1.0);
    ASSERT_TRUE(user.ok()) << user.status();
  }

  std::mt19937_64 rng(20210530);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<SentRound> acknowledged;
  for (int t = 0; t < kRounds; ++t) {
    SentRound sent;
    sent.context = RandomVector(kDim, rng);
    // Values a lossy encoding would change: signed zero and a subnormal.
    if (t % 7 == 0) sent.context[t % kDim] = -0.0;
    if (t % 11 == 0) sent.context[(t + 3) % kDim] = 4.9e-324;
    absl::StatusOr<v1::SelectResponse> selected =
        Select(stub(), kUser, sent.context);
    ASSERT_TRUE(selected.ok()) << "round " << t << ": " << selected.status();
    EXPECT_EQ(selected->model_version(), t);
    sent.event_id = selected->event_id();
    sent.action = selected->action();
    // Arbitrary doubles, plus the integral values SQLite likes to rewrite.
    switch (t % 10) {
      case 0:
        sent.loss = 0.0;
        break;
      case 1:
        sent.loss = 1.0;
        break;
      case 2:
        sent.loss = -0.0;
        break;
      default:
        sent.loss = unit(rng);
    }
    sent.posthoc = RandomVector(kPostHocDim, rng);
    absl::StatusOr<v1::UpdateResponse> updated =
        Update(stub(), sent.event_id, sent.loss, sent.posthoc);
    ASSERT_TRUE(updated.ok()) << "round " << t << ": " << updated.status();
    EXPECT_FALSE(updated->already_applied());
    EXPECT_EQ(updated->user_id(), kUser);
    EXPECT_EQ(updated->model_version(), t + 1);
    sent.model_version = updated->model_version();
    acknowledged.push_back(std::move(sent));
  }

  // Two bites selected but never reported.
  struct Pending {
    std::string event_id;
    std::vector<double> context;
    int action = 0;
  };
  std::vector<Pending> pending;
  for (int i = 0; i < 2; ++i) {
    Pending p;
    p.context = RandomVector(kDim, rng);
    absl::StatusOr<v1::SelectResponse> selected =
        Select(stub(), kUser, p.context);
    ASSERT_TRUE(selected.ok()) << selected.status();
    p.event_id = selected->event_id();
    p.action = selected->action();
    pending.push_back(std::move(p));
  }

  absl::StatusOr<v1::Model> model_before = GetModel(stub(), kUser);
  ASSERT_TRUE(model_before.ok()) << model_before.status();
  EXPECT_EQ(model_before->model_version(), kRounds);
  // The probe's Select is one more pending event; that is fine.
  const std::vector<double> probe = RandomVector(kDim, rng);
  absl::StatusOr<v1::SelectResponse> probe_before =
      Select(stub(), kUser, probe);
  ASSERT_TRUE(probe_before.ok()) << probe_before.status();

  absl::StatusOr<int> killed = server_.SignalAndWait(SIGKILL, kExitTimeout);
  ASSERT_TRUE(killed.ok()) << killed.status();
  ASSERT_TRUE(WIFSIGNALED(*killed) && WTERMSIG(*killed) == SIGKILL)
      << DescribeWaitStatus(*killed);

  absl::Status restarted = StartServer();
  ASSERT_TRUE(restarted.ok()) << restarted;

  absl::StatusOr<v1::User> user = GetUser(stub(), kUser);
  ASSERT_TRUE(user.ok()) << user.status();
  EXPECT_EQ(user->model_version(), static_cast<int64_t>(acknowledged.size()));
  EXPECT_EQ(user->pending_events(), 3);
  if (GetParam() == "sqlite") {
    // The contexts were in the contexts file, one 4 KB-aligned 4,800-byte
    // range (two blocks) per event.
    EXPECT_GE(std::filesystem::file_size(db_ + ".contexts"),
              static_cast<uintmax_t>(acknowledged.size()) * 8192);
  }
  EXPECT_EQ(user->config().context_dim(), static_cast<uint32_t>(kDim));
  EXPECT_EQ(user->config().alpha(), 0.3);
  EXPECT_EQ(user->config().lambda_c(), 2.0);

  // The log: every acknowledged event completed exactly as sent, and the
  // pending ones still pending with their contexts.
  absl::StatusOr<std::vector<v1::Event>> events = ListAllEvents(stub(), kUser);
  ASSERT_TRUE(events.ok()) << events.status();
  EXPECT_EQ(events->size(), acknowledged.size() + 3);
  std::map<std::string, const v1::Event*> by_id;
  for (const v1::Event& event : *events) by_id[event.event_id()] = &event;
  for (const SentRound& sent : acknowledged) {
    SCOPED_TRACE(absl::StrCat("event ", sent.event_id));
    auto it = by_id.find(sent.event_id);
    ASSERT_NE(it, by_id.end());
    const v1::Event& event = *it->second;
    EXPECT_EQ(event.user_id(), kUser);
    EXPECT_TRUE(event.completed());
    EXPECT_EQ(event.action(), sent.action);
    EXPECT_TRUE(BitEqual(event.loss(), sent.loss));
    EXPECT_TRUE(BitEqual(event.context(), sent.context));
    EXPECT_TRUE(BitEqual(event.posthoc(), sent.posthoc));
    EXPECT_EQ(event.model_version(), sent.model_version);
    EXPECT_EQ(event.meal_id(), "meal-1");
    EXPECT_EQ(event.item_label(), "banana");
  }
  for (const Pending& p : pending) {
    SCOPED_TRACE(absl::StrCat("pending event ", p.event_id));
    auto it = by_id.find(p.event_id);
    ASSERT_NE(it, by_id.end());
    EXPECT_FALSE(it->second->completed());
    EXPECT_EQ(it->second->action(), p.action);
    EXPECT_TRUE(BitEqual(it->second->context(), p.context));
  }
  ASSERT_NE(by_id.find(probe_before->event_id()), by_id.end());
  EXPECT_FALSE(by_id[probe_before->event_id()]->completed());

  // The model rebuilt from the log is the model that was served.
  absl::StatusOr<v1::Model> model_after = GetModel(stub(), kUser);
  ASSERT_TRUE(model_after.ok()) << model_after.status();
  EXPECT_EQ(model_after->model_version(), model_before->model_version());
  ASSERT_EQ(model_after->actions_size(), model_before->actions_size());
  for (int a = 0; a < model_after->actions_size(); ++a) {
    const v1::ActionModel& before = model_before->actions(a);
    const v1::ActionModel& after = model_after->actions(a);
    EXPECT_EQ(after.count(), before.count()) << "action " << a;
    EXPECT_TRUE(bitewise::testing::RelNear(after.mean_loss(),
                                           before.mean_loss(), 1e-12))
        << "action " << a;
    ASSERT_EQ(after.theta_size(), kDim);
    ASSERT_EQ(before.theta_size(), kDim);
    for (int i = 0; i < kDim; ++i) {
      EXPECT_TRUE(
          bitewise::testing::RelNear(after.theta(i), before.theta(i), 1e-12))
          << "action " << a << " theta[" << i << "]";
    }
    ASSERT_EQ(after.phi_size(), kPostHocDim);
    ASSERT_EQ(before.phi_size(), kPostHocDim);
    for (int i = 0; i < kPostHocDim; ++i) {
      EXPECT_TRUE(
          bitewise::testing::RelNear(after.phi(i), before.phi(i), 1e-12))
          << "action " << a << " phi[" << i << "]";
    }
  }

  absl::StatusOr<v1::SelectResponse> probe_after = Select(stub(), kUser, probe);
  ASSERT_TRUE(probe_after.ok()) << probe_after.status();
  EXPECT_EQ(probe_after->model_version(), kRounds);
  EXPECT_EQ(probe_after->action(), probe_before->action());
  ASSERT_EQ(probe_after->estimates_size(), probe_before->estimates_size());
  for (int a = 0; a < probe_after->estimates_size(); ++a) {
    const v1::ActionEstimate& before = probe_before->estimates(a);
    const v1::ActionEstimate& after = probe_after->estimates(a);
    EXPECT_TRUE(bitewise::testing::RelNear(after.predicted_loss(),
                                           before.predicted_loss(), 1e-12))
        << "action " << a;
    EXPECT_TRUE(
        bitewise::testing::RelNear(after.width(), before.width(), 1e-12))
        << "action " << a;
    EXPECT_TRUE(bitewise::testing::RelNear(after.lcb(), before.lcb(), 1e-12))
        << "action " << a;
  }

  // A bite selected before the crash can still be reported: Select stored
  // its context and action durably.
  SentRound late;
  late.event_id = pending[0].event_id;
  late.context = pending[0].context;
  late.action = pending[0].action;
  late.loss = 1.0;
  late.posthoc = RandomVector(kPostHocDim, rng);
  absl::StatusOr<v1::UpdateResponse> late_update =
      Update(stub(), late.event_id, late.loss, late.posthoc);
  ASSERT_TRUE(late_update.ok()) << late_update.status();
  EXPECT_FALSE(late_update->already_applied());
  EXPECT_EQ(late_update->model_version(), kRounds + 1);
  acknowledged.push_back(late);

  // The model now includes that round with the context given to Select.
  {
    bandit::BanditConfig config;
    config.learner = bandit::Learner::kPostHoc;
    config.alpha = 0.3;
    config.lambda_c = 2.0;
    config.lambda_p = 1.0;
    config.context_dim = kDim;
    config.posthoc_dim = kPostHocDim;
    std::vector<bandit::Round> rounds;
    for (const SentRound& sent : acknowledged) rounds.push_back(ToRound(sent));
    absl::StatusOr<v1::Model> model = GetModel(stub(), kUser);
    ASSERT_TRUE(model.ok()) << model.status();
    EXPECT_EQ(model->model_version(), kRounds + 1);
    ExpectModelMatchesReference(
        *model, bandit::testing::DenseReference(config, rounds), rounds,
        /*posthoc=*/true, 1e-8);
  }

  // Retrying an update acknowledged before the crash changes nothing and
  // returns the recorded result; a retry with another outcome is a
  // conflict and changes nothing either.
  const SentRound& retried = acknowledged[10];
  absl::StatusOr<v1::UpdateResponse> conflict =
      Update(stub(), retried.event_id, 0.5, RandomVector(kPostHocDim, rng));
  EXPECT_EQ(conflict.status().code(), absl::StatusCode::kAlreadyExists);
  absl::StatusOr<v1::UpdateResponse> retry =
      Update(stub(), retried.event_id, retried.loss, retried.posthoc);
  ASSERT_TRUE(retry.ok()) << retry.status();
  EXPECT_TRUE(retry->already_applied());
  EXPECT_EQ(retry->model_version(), retried.model_version);
  EXPECT_EQ(retry->user_id(), kUser);
  absl::StatusOr<v1::UpdateResponse> retry_late =
      Update(stub(), late.event_id, late.loss, late.posthoc);
  ASSERT_TRUE(retry_late.ok()) << retry_late.status();
  EXPECT_TRUE(retry_late->already_applied());
  EXPECT_EQ(retry_late->model_version(), kRounds + 1);
  user = GetUser(stub(), kUser);
  ASSERT_TRUE(user.ok()) << user.status();
  EXPECT_EQ(user->model_version(), kRounds + 1);
  // Two probe Selects and one pending bite remain.
  EXPECT_EQ(user->pending_events(), 3);
}

TEST_P(BanditBinaryTest, ServedEstimatesMatchDenseReference) {
  constexpr int kDim = 12;
  constexpr int kPostHocDim = 4;
  // Enough rounds that actions pass d and switch to the primal form.
  constexpr int kRounds = 96;
  constexpr double kAlpha = 0.8;
  constexpr double kLambdaC = 1.5;
  constexpr double kLambdaP = 0.7;
  absl::Status started = StartServer();
  ASSERT_TRUE(started.ok()) << started;

  for (const v1::Learner learner :
       {v1::LEARNER_POSTHOC, v1::LEARNER_CONTEXT_ONLY}) {
    const bool posthoc = learner == v1::LEARNER_POSTHOC;
    const std::string user_id = posthoc ? "ref-posthoc" : "ref-context-only";
    SCOPED_TRACE(user_id);
    absl::StatusOr<v1::User> user = CreateUser(
        user_id, learner, kDim, kPostHocDim, kAlpha, kLambdaC, kLambdaP);
    ASSERT_TRUE(user.ok()) << user.status();
    // K comes from the server's default action names.
    ASSERT_EQ(user->config().action_names_size(), 6);
    EXPECT_EQ(user->config().learner(), learner);

    bandit::BanditConfig config;
    config.learner =
        posthoc ? bandit::Learner::kPostHoc : bandit::Learner::kContextOnly;
    config.alpha = kAlpha;
    config.lambda_c = kLambdaC;
    config.lambda_p = kLambdaP;
    config.context_dim = kDim;
    config.posthoc_dim = kPostHocDim;
    config.action_names.assign(user->config().action_names().begin(),
                               user->config().action_names().end());

    std::mt19937_64 rng(posthoc ? 11 : 12);
    std::bernoulli_distribution coin(0.5);
    std::vector<bandit::Round> rounds;
    for (int t = 0; t < kRounds; ++t) {
      const std::vector<double> context = RandomVector(kDim, rng);
      absl::StatusOr<v1::SelectResponse> selected =
          Select(stub(), user_id, context);
      ASSERT_TRUE(selected.ok()) << "round " << t << ": " << selected.status();
      // Every choice is made from estimates that match the reference.
      {
        SCOPED_TRACE(absl::StrCat("round ", t));
        ExpectEstimatesMatchReference(
            *selected, bandit::testing::DenseReference(config, rounds), context,
            kAlpha, 1e-8);
      }
      bandit::Round round;
      round.context = context;
      round.action = selected->action();
      round.loss = coin(rng) ? 1.0 : 0.0;
      // The context-only learner ignores post hoc contexts; send one anyway
      // for half of the rounds.
      if (posthoc || t % 2 == 0) round.posthoc = RandomVector(kPostHocDim, rng);
      absl::StatusOr<v1::UpdateResponse> updated =
          Update(stub(), selected->event_id(), round.loss, round.posthoc);
      ASSERT_TRUE(updated.ok()) << "round " << t << ": " << updated.status();
      EXPECT_EQ(updated->model_version(), t + 1);
      rounds.push_back(std::move(round));
    }

    const std::vector<bandit::testing::DenseActionModel> reference =
        bandit::testing::DenseReference(config, rounds);
    for (int probe = 0; probe < 4; ++probe) {
      SCOPED_TRACE(absl::StrCat("probe ", probe));
      const std::vector<double> context = RandomVector(kDim, rng);
      absl::StatusOr<v1::SelectResponse> selected =
          Select(stub(), user_id, context);
      ASSERT_TRUE(selected.ok()) << selected.status();
      EXPECT_EQ(selected->model_version(), kRounds);
      ExpectEstimatesMatchReference(*selected, reference, context, kAlpha,
                                    1e-8);
      // LinUCB: the lowest lower confidence bound, ties to the lowest index.
      int best = 0;
      for (int a = 1; a < selected->estimates_size(); ++a) {
        if (selected->estimates(a).lcb() < selected->estimates(best).lcb()) {
          best = a;
        }
      }
      EXPECT_EQ(selected->action(), best);
    }

    absl::StatusOr<v1::Model> model = GetModel(stub(), user_id);
    ASSERT_TRUE(model.ok()) << model.status();
    EXPECT_EQ(model->model_version(), kRounds);
    ExpectModelMatchesReference(*model, reference, rounds, posthoc, 1e-8);
    // The data exercised both representations of A_a: some action has
    // more rounds than d (primal), every action has at least one.
    int64_t most = 0;
    for (const v1::ActionModel& action : model->actions()) {
      EXPECT_GT(action.count(), 0) << "action " << action.action();
      most = std::max(most, action.count());
    }
    EXPECT_GT(most, kDim);
  }
}

// poLinUCB through gRPC: every Select's estimates agree with the dense
// reference of its formulas, before and after a SIGKILL (the model then
// comes back from its checkpoint or the log), and an Update without the
// post hoc context it learns from is refused.
TEST_P(BanditBinaryTest, ServedPoLinUcbMatchesDenseReference) {
  constexpr int kDim = 10;
  constexpr int kPostHocDim = 3;
  constexpr int kRounds = 90;
  constexpr double kAlpha = 0.6;
  // Not the default: the user's own radius is stored and served, before
  // and after the restart below.
  constexpr double kPhiRadius = 0.45;
  absl::Status started = StartServer();
  ASSERT_TRUE(started.ok()) << started;
  absl::StatusOr<v1::User> user =
      CreateUser("ref-polinucb", v1::LEARNER_POLINUCB, kDim, kPostHocDim,
                 kAlpha, 1.5, 0.7, kPhiRadius);
  ASSERT_TRUE(user.ok()) << user.status();
  EXPECT_EQ(user->config().learner(), v1::LEARNER_POLINUCB);
  EXPECT_EQ(user->config().phi_radius(), kPhiRadius);
  bandit::BanditConfig config;
  config.learner = bandit::Learner::kPoLinUcb;
  config.alpha = kAlpha;
  config.lambda_c = 1.5;
  config.lambda_p = 0.7;
  config.phi_radius = kPhiRadius;
  config.context_dim = kDim;
  config.posthoc_dim = kPostHocDim;
  config.action_names.assign(user->config().action_names().begin(),
                             user->config().action_names().end());
  auto expect_matches = [&](const v1::SelectResponse& got,
                            const std::vector<bandit::Round>& seen,
                            const std::vector<double>& context) {
    const bandit::testing::DensePoLinUcb ref =
        bandit::testing::DensePoLinUcbReference(config, seen, context);
    ASSERT_EQ(got.estimates_size(), config.num_actions());
    for (int a = 0; a < got.estimates_size(); ++a) {
      EXPECT_TRUE(bitewise::testing::RelNear(got.estimates(a).predicted_loss(),
                                             ref.predicted[a], 1e-8))
          << "action " << a;
      EXPECT_TRUE(bitewise::testing::RelNear(got.estimates(a).width(),
                                             ref.width[a], 1e-8))
          << "action " << a;
      EXPECT_TRUE(
          bitewise::testing::RelNear(got.estimates(a).lcb(), ref.lcb[a], 1e-8))
          << "action " << a;
    }
  };
  std::mt19937_64 rng(21);
  std::bernoulli_distribution coin(0.4);
  std::vector<bandit::Round> rounds;
  for (int t = 0; t < kRounds; ++t) {
    SCOPED_TRACE(absl::StrCat("round ", t));
    const std::vector<double> context = RandomVector(kDim, rng);
    absl::StatusOr<v1::SelectResponse> selected =
        Select(stub(), "ref-polinucb", context);
    ASSERT_TRUE(selected.ok()) << selected.status();
    expect_matches(*selected, rounds, context);
    bandit::Round round;
    round.context = context;
    round.action = selected->action();
    round.loss = coin(rng) ? 1.0 : 0.0;
    // The post hoc context depends on the context, as the paper's.
    round.posthoc = {context[0] + 0.1 * context[1], context[2] - context[3],
                     0.5 * context[4] + 0.2};
    if (t == 5) {
      absl::StatusOr<v1::UpdateResponse> refused =
          Update(stub(), selected->event_id(), round.loss, {});
      EXPECT_EQ(refused.status().code(), absl::StatusCode::kInvalidArgument);
      EXPECT_THAT(refused.status().message(), HasSubstr("posthoc"));
    }
    ASSERT_TRUE(
        Update(stub(), selected->event_id(), round.loss, round.posthoc).ok());
    rounds.push_back(std::move(round));
  }
  ASSERT_TRUE(server_.SignalAndWait(SIGKILL, kExitTimeout).ok());
  started = StartServer();
  ASSERT_TRUE(started.ok()) << started;
  for (int probe = 0; probe < 3; ++probe) {
    const std::vector<double> context = RandomVector(kDim, rng);
    absl::StatusOr<v1::SelectResponse> selected =
        Select(stub(), "ref-polinucb", context);
    ASSERT_TRUE(selected.ok()) << selected.status();
    EXPECT_EQ(selected->model_version(), kRounds);
    expect_matches(*selected, rounds, context);
  }
}

TEST_P(BanditBinaryTest, SigtermDrainsAndExitsZero) {
  absl::Status started = StartServer();
  ASSERT_TRUE(started.ok()) << started;
  ASSERT_TRUE(
      CreateUser("term-user", v1::LEARNER_POSTHOC, 8, 4, 0.3, 2.0, 1.0).ok());
  absl::StatusOr<v1::SelectResponse> selected =
      Select(stub(), "term-user", std::vector<double>(8, 0.25));
  ASSERT_TRUE(selected.ok()) << selected.status();
  absl::StatusOr<v1::UpdateResponse> updated =
      Update(stub(), selected->event_id(), 0.0, {0.1, 0.2, 0.3, 0.4});
  ASSERT_TRUE(updated.ok()) << updated.status();

  const std::string log_path = server_.log_path();
  const absl::Time start = absl::Now();
  absl::StatusOr<int> exited = server_.SignalAndWait(SIGTERM, kExitTimeout);
  const absl::Duration elapsed = absl::Now() - start;
  ASSERT_TRUE(exited.ok()) << exited.status();
  EXPECT_TRUE(WIFEXITED(*exited) && WEXITSTATUS(*exited) == 0)
      << DescribeWaitStatus(*exited);
  // Nothing is in flight, so draining must not wait out its timeout.
  EXPECT_LT(elapsed, absl::Seconds(4));
  std::cout << "SIGTERM to exit: " << absl::FormatDuration(elapsed) << "\n";
  const std::string log = ReadFile(log_path);
  EXPECT_THAT(log, HasSubstr("bitewise-bandit: serving on 127.0.0.1:"));
  EXPECT_THAT(log, HasSubstr("bitewise: received SIGTERM, draining"));
  EXPECT_THAT(log, HasSubstr("bitewise: drained in "));

  // A clean stop keeps the data too.
  absl::Status restarted = StartServer();
  ASSERT_TRUE(restarted.ok()) << restarted;
  absl::StatusOr<v1::User> user = GetUser(stub(), "term-user");
  ASSERT_TRUE(user.ok()) << user.status();
  EXPECT_EQ(user->model_version(), 1);
}

TEST_P(BanditBinaryTest, BadInputGetsTheRightStatusAndChangesNothing) {
  constexpr char kUser[] = "bad-input-user";
  constexpr int kDim = 16;
  constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  constexpr double kInf = std::numeric_limits<double>::infinity();
  absl::Status started = StartServer();
  ASSERT_TRUE(started.ok()) << started;
  ASSERT_TRUE(
      CreateUser(kUser, v1::LEARNER_POSTHOC, kDim, 4, 0.3, 2.0, 1.0).ok());
  std::mt19937_64 rng(99);

  // One completed round, so model_version is not trivially 0.
  absl::StatusOr<v1::SelectResponse> first =
      Select(stub(), kUser, RandomVector(kDim, rng));
  ASSERT_TRUE(first.ok()) << first.status();
  ASSERT_TRUE(
      Update(stub(), first->event_id(), 0.0, RandomVector(4, rng)).ok());
  // The pending event every bad Update is aimed at.
  absl::StatusOr<v1::SelectResponse> target =
      Select(stub(), kUser, RandomVector(kDim, rng));
  ASSERT_TRUE(target.ok()) << target.status();

  auto expect_user_unchanged = [&](const std::string& what) {
    absl::StatusOr<v1::User> user = GetUser(stub(), kUser);
    ASSERT_TRUE(user.ok()) << user.status();
    EXPECT_EQ(user->model_version(), 1) << "after " << what;
    EXPECT_EQ(user->pending_events(), 1) << "after " << what;
  };

  // Bad contexts: nothing is recorded.
  {
    absl::StatusOr<v1::SelectResponse> r =
        Select(stub(), kUser, RandomVector(kDim - 1, rng));
    EXPECT_EQ(r.status().code(), absl::StatusCode::kInvalidArgument)
        << r.status();
    EXPECT_THAT(r.status().message(), HasSubstr("context"));
    EXPECT_THAT(r.status().message(), HasSubstr("16"));
    EXPECT_THAT(r.status().message(), HasSubstr("15"));
    expect_user_unchanged("short context");
  }
  {
    absl::StatusOr<v1::SelectResponse> r =
        Select(stub(), kUser, RandomVector(kDim + 1, rng));
    EXPECT_EQ(r.status().code(), absl::StatusCode::kInvalidArgument)
        << r.status();
    EXPECT_THAT(r.status().message(), HasSubstr("context"));
    EXPECT_THAT(r.status().message(), HasSubstr("17"));
    expect_user_unchanged("long context");
  }
  for (const double bad : {kNaN, kInf, -kInf}) {
    std::vector<double> context = RandomVector(kDim, rng);
    context[5] = bad;
    absl::StatusOr<v1::SelectResponse> r = Select(stub(), kUser, context);
    EXPECT_EQ(r.status().code(), absl::StatusCode::kInvalidArgument)
        << bad << ": " << r.status();
    EXPECT_THAT(r.status().message(), HasSubstr("context"));
    expect_user_unchanged(absl::StrCat("context with ", bad));
  }

  // Bad outcomes: the pending event stays pending, the model unchanged.
  struct BadUpdate {
    std::string what;
    double loss;
    std::vector<double> posthoc;
    std::string field;
  };
  std::vector<double> nan_posthoc = RandomVector(4, rng);
  nan_posthoc[2] = kNaN;
  const std::vector<BadUpdate> bad_updates = {
      {"loss 1.5", 1.5, RandomVector(4, rng), "loss"},
      {"loss -0.25", -0.25, RandomVector(4, rng), "loss"},
      {"loss NaN", kNaN, RandomVector(4, rng), "loss"},
      {"loss inf", kInf, RandomVector(4, rng), "loss"},
      {"posthoc of length 3", 0.5, RandomVector(3, rng), "posthoc"},
      {"posthoc of length 5", 0.5, RandomVector(5, rng), "posthoc"},
      {"empty posthoc", 0.5, {}, "posthoc"},
      {"posthoc with NaN", 0.5, nan_posthoc, "posthoc"},
  };
  for (const BadUpdate& bad : bad_updates) {
    absl::StatusOr<v1::UpdateResponse> r =
        Update(stub(), target->event_id(), bad.loss, bad.posthoc);
    EXPECT_EQ(r.status().code(), absl::StatusCode::kInvalidArgument)
        << bad.what << ": " << r.status();
    EXPECT_THAT(r.status().message(), HasSubstr(bad.field)) << bad.what;
    expect_user_unchanged(bad.what);
  }

  // Unknown and malformed names.
  {
    absl::StatusOr<v1::SelectResponse> r =
        Select(stub(), "no-such-user", RandomVector(kDim, rng));
    EXPECT_EQ(r.status().code(), absl::StatusCode::kNotFound) << r.status();
    EXPECT_EQ(GetUser(stub(), "no-such-user").status().code(),
              absl::StatusCode::kNotFound);
    EXPECT_EQ(GetModel(stub(), "no-such-user").status().code(),
              absl::StatusCode::kNotFound);
    EXPECT_EQ(GetUser(stub(), "bad user!").status().code(),
              absl::StatusCode::kInvalidArgument);
  }
  {
    absl::StatusOr<v1::UpdateResponse> r =
        Update(stub(), "999999", 0.5, RandomVector(4, rng));
    EXPECT_EQ(r.status().code(), absl::StatusCode::kNotFound) << r.status();
    expect_user_unchanged("unknown event id");
  }
  for (const char* malformed : {"abc", "", "0", "-3", "12abc", "1.5"}) {
    absl::StatusOr<v1::UpdateResponse> r =
        Update(stub(), malformed, 0.5, RandomVector(4, rng));
    EXPECT_EQ(r.status().code(), absl::StatusCode::kInvalidArgument)
        << "\"" << malformed << "\": " << r.status();
    EXPECT_THAT(r.status().message(), HasSubstr("event_id"));
    expect_user_unchanged(absl::StrCat("event id \"", malformed, "\""));
  }

  // None of the failures consumed the pending event.
  absl::StatusOr<v1::UpdateResponse> good =
      Update(stub(), target->event_id(), 1.0, RandomVector(4, rng));
  ASSERT_TRUE(good.ok()) << good.status();
  EXPECT_FALSE(good->already_applied());
  EXPECT_EQ(good->model_version(), 2);
}

}  // namespace
}  // namespace bitewise

namespace bitewise {
namespace {

// Runs the binary on a database `name`.db that does not exist, with `flags`,
// expecting it to stop before serving; its log.
std::string StartThatFails(const std::string& name,
                           const std::vector<std::string>& flags) {
  const std::string db = ::testing::TempDir() + "/" + name + ".db";
  std::remove(db.c_str());
  const std::string log = ::testing::TempDir() + "/" + name + ".log";
  std::remove(log.c_str());
  std::vector<std::string> args = {BITEWISE_BANDIT_BINARY,
                                   absl::StrCat("--db=", db),
                                   "--listen=127.0.0.1:0"};
  args.insert(args.end(), flags.begin(), flags.end());
  testing::ChildProcess child;
  const absl::Status started = child.Start(args, log);
  EXPECT_TRUE(started.ok()) << started;
  const absl::StatusOr<int> status = child.Wait(absl::Seconds(30));
  EXPECT_TRUE(status.ok()) << status.status();
  if (status.ok()) {
    EXPECT_TRUE(WIFEXITED(*status) && WEXITSTATUS(*status) != 0)
        << testing::DescribeWaitStatus(*status);
  }
  EXPECT_NE(access(db.c_str(), F_OK), 0);  // nothing was made
  return child.log();
}

TEST(BanditBinaryStartTest, AMistypedDbStopsTheStartUnlessCreateIsGiven) {
  const std::string db = ::testing::TempDir() + "/no-such-dir-typo.db";
  EXPECT_THAT(StartThatFails("no-such-dir-typo", {}),
              HasSubstr(db + "\" does not exist; pass --create"));
}

// Checked before the store is opened, so --create makes nothing.
TEST(BanditBinaryStartTest, SelectThreadsOtherThanOneOrTwoStopTheStart) {
  EXPECT_THAT(StartThatFails("bandit_select_threads",
                             {"--create", "--select_threads=3"}),
              HasSubstr("--select_threads must be 1 or 2, not 3"));
}

// Two bitewise-bandit processes (replicas) on one new database of the test
// binary's PostgreSQL server, logging into a temporary directory; both are
// killed and the directory removed at the end.
struct ReplicaPair {
  absl::Status Start(const std::string& database) {
    testing::TestPostgres* pg = testing::SharedTestPostgres();
    if (pg == nullptr) return absl::UnavailableError("no test PostgreSQL");
    absl::StatusOr<std::string> conninfo = pg->CreateDatabase(database);
    if (!conninfo.ok()) return conninfo.status();
    db = *conninfo;
    dir = (std::filesystem::temp_directory_path() / "bandit_replicas.XXXXXX")
              .string();
    if (mkdtemp(dir.data()) == nullptr) {
      return absl::InternalError(std::strerror(errno));
    }
    for (int r = 0; r < 2; ++r) {
      absl::Status started =
          replicas[r].Start(db, absl::StrCat(dir, "/replica-", r, ".log"));
      if (!started.ok()) return started;
    }
    return absl::OkStatus();
  }
  ~ReplicaPair() {
    for (ServerProcess& replica : replicas) replica.Kill();
    std::error_code ignored;
    if (!dir.empty()) std::filesystem::remove_all(dir, ignored);
  }

  std::string db;
  std::string dir;
  ServerProcess replicas[2];
};

// Two bitewise-bandit processes on one PostgreSQL database, as two
// workstations behind one client-side target list: the client sends each
// Select to one and its Update to the other, every choice is made from
// estimates that match the dense reference on all the rounds either one
// learned, one replica is killed with SIGKILL mid-stream (with an event of
// its Select still pending), and the other finishes the meal, that event
// included; nothing acknowledged is lost, and both (the killed one
// restarted) export the reference model.
TEST(BanditReplicaBinaryTest, TwoReplicasServeOneLogAndOneCanBeKilled) {
  constexpr int kDim = 10;
  constexpr int kPostHocDim = 4;
  constexpr int kRounds = 40;
  constexpr int kKillAt = 22;  // even: replica 0 selects
  constexpr double kAlpha = 0.6;
  ReplicaPair pair;
  absl::Status started = pair.Start("replica_binary");
  ASSERT_TRUE(started.ok()) << started;
  ServerProcess* const replicas = pair.replicas;
  v1::CreateUserRequest create;
  create.set_user_id("shared");
  create.mutable_config()->set_learner(v1::LEARNER_POSTHOC);
  create.mutable_config()->set_strategy(v1::STRATEGY_LINUCB);
  create.mutable_config()->set_context_dim(kDim);
  create.mutable_config()->set_posthoc_dim(kPostHocDim);
  create.mutable_config()->set_alpha(kAlpha);
  create.mutable_config()->set_lambda_c(1.5);
  create.mutable_config()->set_lambda_p(0.7);
  absl::StatusOr<v1::User> user =
      Call(replicas[1].stub(), &v1::BanditService::Stub::CreateUser, create);
  ASSERT_TRUE(user.ok()) << user.status();
  bandit::BanditConfig config;
  config.alpha = kAlpha;
  config.lambda_c = 1.5;
  config.lambda_p = 0.7;
  config.context_dim = kDim;
  config.posthoc_dim = kPostHocDim;
  config.action_names.assign(user->config().action_names().begin(),
                             user->config().action_names().end());

  std::mt19937_64 rng(31);
  std::vector<bandit::Round> rounds;
  bool killed = false;
  for (int t = 0; t < kRounds; ++t) {
    SCOPED_TRACE(absl::StrCat("round ", t));
    const std::vector<double> context = RandomVector(kDim, rng);
    ServerProcess& selector = replicas[killed ? 1 : t % 2];
    absl::StatusOr<v1::SelectResponse> selected =
        Select(selector.stub(), "shared", context);
    ASSERT_TRUE(selected.ok()) << selected.status();
    EXPECT_EQ(selected->model_version(), t);
    ExpectEstimatesMatchReference(
        *selected, bandit::testing::DenseReference(config, rounds), context,
        kAlpha, 1e-8);
    if (t == kKillAt) {
      // Replica 0 made this Select; it dies before the Update.
      ASSERT_EQ(&selector, &replicas[0]);
      absl::StatusOr<int> status =
          replicas[0].SignalAndWait(SIGKILL, kExitTimeout);
      ASSERT_TRUE(status.ok()) << status.status();
      killed = true;
    }
    bandit::Round round;
    round.context = context;
    round.action = selected->action();
    round.loss = t % 3 == 0 ? 1.0 : 0.0;
    round.posthoc = RandomVector(kPostHocDim, rng);
    ServerProcess& updater = replicas[killed ? 1 : (t + 1) % 2];
    absl::StatusOr<v1::UpdateResponse> updated =
        Update(updater.stub(), selected->event_id(), round.loss, round.posthoc);
    ASSERT_TRUE(updated.ok()) << updated.status();
    EXPECT_EQ(updated->model_version(), t + 1);
    rounds.push_back(std::move(round));
  }
  absl::StatusOr<v1::User> after = GetUser(replicas[1].stub(), "shared");
  ASSERT_TRUE(after.ok()) << after.status();
  EXPECT_EQ(after->model_version(), kRounds);
  EXPECT_EQ(after->pending_events(), 0);
  const auto reference = bandit::testing::DenseReference(config, rounds);
  absl::StatusOr<v1::Model> model = GetModel(replicas[1].stub(), "shared");
  ASSERT_TRUE(model.ok()) << model.status();
  ExpectModelMatchesReference(*model, reference, rounds, true, 1e-8);
  absl::Status restarted = replicas[0].Start(
      pair.db, absl::StrCat(pair.dir, "/replica-0-again.log"));
  ASSERT_TRUE(restarted.ok()) << restarted;
  model = GetModel(replicas[0].stub(), "shared");
  ASSERT_TRUE(model.ok()) << model.status();
  ExpectModelMatchesReference(*model, reference, rounds, true, 1e-8);
}

// PostgreSQL stopped under a running service: calls fail with UNAVAILABLE
// naming the database, health turns NOT_SERVING, and when the database
// returns the same process serves again, without a restart, with nothing
// acknowledged lost.
TEST(BanditReplicaBinaryTest, ADatabaseThatStopsAndReturnsNeedsNoRestart) {
  absl::StatusOr<std::unique_ptr<testing::TestPostgres>> own =
      testing::TestPostgres::Create();
  ASSERT_TRUE(own.ok()) << own.status();
  testing::TestPostgres& pg = **own;
  absl::StatusOr<std::string> db = pg.CreateDatabase("outage");
  ASSERT_TRUE(db.ok()) << db.status();
  ServerProcess server;
  absl::Status started = server.Start(*db, pg.dir() + "/service.log");
  ASSERT_TRUE(started.ok()) << started;
  v1::CreateUserRequest create;
  create.set_user_id("ann");
  create.mutable_config()->set_context_dim(6);
  create.mutable_config()->set_posthoc_dim(2);
  ASSERT_TRUE(
      Call(server.stub(), &v1::BanditService::Stub::CreateUser, create).ok());
  std::mt19937_64 rng(8);
  absl::StatusOr<v1::SelectResponse> first =
      Select(server.stub(), "ann", RandomVector(6, rng));
  ASSERT_TRUE(first.ok()) << first.status();
  ASSERT_TRUE(Update(server.stub(), first->event_id(), 1.0, {0.5, 0.5}).ok());

  ASSERT_TRUE(pg.Stop().ok());
  absl::StatusOr<v1::SelectResponse> down =
      Select(server.stub(), "ann", RandomVector(6, rng));
  EXPECT_EQ(down.status().code(), absl::StatusCode::kUnavailable);
  EXPECT_THAT(down.status().message(), HasSubstr("database \"outage\""));
  // Health follows within the readiness monitor's period.
  absl::StatusOr<ServingStatus> health;
  for (int i = 0; i < 50; ++i) {
    health = CheckHealth(server.channel(), kServiceName, absl::Seconds(5));
    if (health.ok() && *health == ServingStatus::kNotServing) break;
    absl::SleepFor(absl::Milliseconds(100));
  }
  ASSERT_TRUE(health.ok()) << health.status();
  EXPECT_EQ(*health, ServingStatus::kNotServing);

  ASSERT_TRUE(pg.Start().ok());
  absl::Status serving =
      WaitForServing(server.channel(), kServiceName, absl::Seconds(20));
  ASSERT_TRUE(serving.ok()) << serving;
  EXPECT_TRUE(server.running());
  absl::StatusOr<v1::SelectResponse> again =
      Select(server.stub(), "ann", RandomVector(6, rng));
  ASSERT_TRUE(again.ok()) << again.status();
  EXPECT_EQ(again->model_version(), 1);
  absl::StatusOr<v1::UpdateResponse> updated =
      Update(server.stub(), again->event_id(), 0.0, {0.1, 0.2});
  ASSERT_TRUE(updated.ok()) << updated.status();
  EXPECT_EQ(updated->model_version(), 2);
  server.Kill();
}

// The client side of a replica setup: one channel over both replicas'
// addresses (round robin, with retries as the orchestrator sets them)
// carries a meal; one replica is killed and the meal goes on through the
// other without an error reaching the caller.
TEST(BanditReplicaBinaryTest, OneChannelOverTwoReplicasFailsOver) {
  ReplicaPair pair;
  absl::Status started = pair.Start("replica_channel");
  ASSERT_TRUE(started.ok()) << started;
  ServerProcess* const replicas = pair.replicas;
  ChannelOptions options;
  options.max_attempts = 5;  // the orchestrator's default --retries=4
  options.initial_backoff = absl::Milliseconds(50);
  absl::StatusOr<std::shared_ptr<grpc::Channel>> channel = MakeChannel(
      absl::StrCat(replicas[0].address(), ",", replicas[1].address()), options);
  ASSERT_TRUE(channel.ok()) << channel.status();
  ASSERT_TRUE(WaitForServing(*channel, kServiceName, kServingTimeout).ok());
  std::unique_ptr<v1::BanditService::Stub> stub =
      v1::BanditService::NewStub(*channel);
  v1::CreateUserRequest create;
  create.set_user_id("ben");
  create.mutable_config()->set_context_dim(6);
  create.mutable_config()->set_posthoc_dim(2);
  ASSERT_TRUE(Call(*stub, &v1::BanditService::Stub::CreateUser, create).ok());
  std::mt19937_64 rng(12);
  constexpr int kPairs = 30;
  for (int t = 0; t < kPairs; ++t) {
    SCOPED_TRACE(absl::StrCat("pair ", t));
    if (t == kPairs / 2) {
      absl::StatusOr<int> status =
          replicas[t % 2].SignalAndWait(SIGKILL, kExitTimeout);
      ASSERT_TRUE(status.ok()) << status.status();
    }
    absl::StatusOr<v1::SelectResponse> selected =
        Select(*stub, "ben", RandomVector(6, rng));
    ASSERT_TRUE(selected.ok()) << selected.status();
    EXPECT_EQ(selected->model_version(), t);
    absl::StatusOr<v1::UpdateResponse> updated =
        Update(*stub, selected->event_id(), t % 2 ? 1.0 : 0.0, {0.3, 0.4});
    ASSERT_TRUE(updated.ok()) << updated.status();
    EXPECT_EQ(updated->model_version(), t + 1);
  }
}

}  // namespace
}  // namespace bitewise
