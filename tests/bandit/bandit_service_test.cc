// In-process tests of the BanditService: the real engine, a real SQLite
// file and a real gRPC server on a loopback port, called through a stub.
#include "services/bandit/bandit_service.h"

#include <stdlib.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "gtest/gtest.h"
#include "services/bandit/converters.h"
#include "services/bandit/store/sqlite_event_store.h"
#include "services/common/channel.h"
#include "services/common/server.h"
#include "tests/common/test_certs.h"

namespace bitewise::bandit {
namespace {

class BanditServiceTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string dir = ::testing::TempDir() + "/service_XXXXXX";
    ASSERT_NE(mkdtemp(dir.data()), nullptr);
    SqliteStoreOptions store_options;
    store_options.path = dir + "/bandit.db";
    store_options.synchronous_full = false;
    auto store = SqliteEventStore::Open(store_options);
    ASSERT_TRUE(store.ok()) << store.status();
    store_ = std::move(store).value();
    engine_ = std::make_unique<BanditEngine>(store_.get(), EngineOptions());
    BanditConfig defaults;
    defaults.context_dim = 6;
    service_ =
        std::make_unique<BanditServiceImpl>(&env_, engine_.get(), defaults);
    auto server = ServiceServer::Start(ServerOptions(), &env_, {service_.get()},
                                       {"bitewise.v1.BanditService"});
    ASSERT_TRUE(server.ok()) << server.status();
    server_ = std::move(server).value();
    server_->SetServing(true);
    auto channel = MakeChannel(server_->address(), ChannelOptions());
    ASSERT_TRUE(channel.ok());
    ASSERT_TRUE(
        WaitForServing(*channel, "bitewise.v1.BanditService", absl::Seconds(10))
            .ok());
    stub_ = v1::BanditService::NewStub(*channel);
  }

  void TearDown() override {
    if (server_) server_->Shutdown();
  }

  std::unique_ptr<grpc::ClientContext> Ctx() {
    auto context = std::make_unique<grpc::ClientContext>();
    context->set_deadline(std::chrono::system_clock::now() +
                          std::chrono::seconds(10));
    return context;
  }

  v1::User CreateUser(const std::string& id) {
    v1::CreateUserRequest request;
    request.set_user_id(id);
    v1::User user;
    grpc::Status status = stub_->CreateUser(Ctx().get(), request, &user);
    EXPECT_TRUE(status.ok()) << status.error_message();
    return user;
  }

  grpc::Status Select(const std::string& user, std::vector<double> context,
                      v1::SelectResponse* response,
                      const std::string& meal = "") {
    v1::SelectRequest request;
    request.set_user_id(user);
    request.set_meal_id(meal);
    request.mutable_context()->Add(context.begin(), context.end());
    return stub_->Select(Ctx().get(), request, response);
  }

  grpc::Status Update(const std::string& event_id, double loss,
                      std::vector<double> posthoc,
                      v1::UpdateResponse* response) {
    v1::UpdateRequest request;
    request.set_event_id(event_id);
    request.set_loss(loss);
    request.mutable_posthoc()->Add(posthoc.begin(), posthoc.end());
    return stub_->Update(Ctx().get(), request, response);
  }

  RpcEnvironment env_;
  std::unique_ptr<SqliteEventStore> store_;
  std::unique_ptr<BanditEngine> engine_;
  std::unique_ptr<BanditServiceImpl> service_;
  std::unique_ptr<ServiceServer> server_;
  std::unique_ptr<v1::BanditService::Stub> stub_;
};

// An audited call whose record the audit store refuses stands (it has
// happened), and the lost record is counted for the engineer on call (it
// was only printed). The audit store here: another SQLite store whose file
// was removed under it.
TEST_F(BanditServiceTest, ALostAuditRecordIsCounted) {
  std::string dir = ::testing::TempDir() + "/audit_XXXXXX";
  ASSERT_NE(mkdtemp(dir.data()), nullptr);
  SqliteStoreOptions options;
  options.path = dir + "/audit.db";
  options.create_if_missing = true;
  auto audit_store = SqliteEventStore::Open(options);
  ASSERT_TRUE(audit_store.ok()) << audit_store.status();
  ASSERT_TRUE(std::filesystem::remove(options.path));
  StoreAuditSink sink(audit_store->get());
  env_.set_audit_sink(&sink);
  EXPECT_EQ(env_.audit_records_lost(), 0);
  CreateUser("alice");  // OK, though its record is refused
  env_.set_audit_sink(nullptr);
  EXPECT_EQ(env_.audit_records_lost(), 1);
  v1::GetUserRequest get;
  get.set_user_id("alice");
  v1::User user;
  EXPECT_TRUE(stub_->GetUser(Ctx().get(), get, &user).ok());
}

// Administrative calls land in the store's audit log with what they
// concerned; ListAudit reads them; CheckStore reports on the whole store.
TEST_F(BanditServiceTest, AdministrativeCallsAreAuditedAndTheStoreCheckable) {
  StoreAuditSink sink(store_.get());
  env_.set_audit_sink(&sink);
  CreateUser("alice");
  v1::SelectResponse chosen;
  ASSERT_TRUE(Select("alice", {1, 0, 0, 0, 0, 0}, &chosen).ok());
  v1::DeleteUserRequest remove;
  remove.set_user_id("nobody");
  v1::DeleteUserResponse removed;
  EXPECT_EQ(stub_->DeleteUser(Ctx().get(), remove, &removed).error_code(),
            grpc::StatusCode::NOT_FOUND);
  // A new learner for alice: her event stays, her model is rebuilt.
  v1::SetLearnerRequest move;
  move.set_user_id("alice");
  v1::User moved;
  const grpc::Status unset = stub_->SetLearner(Ctx().get(), move, &moved);
  EXPECT_EQ(unset.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(unset.error_message().find("learner"), std::string::npos);
  move.set_learner(v1::LEARNER_POLINUCB);
  ASSERT_TRUE(stub_->SetLearner(Ctx().get(), move, &moved).ok());
  EXPECT_EQ(moved.config().learner(), v1::LEARNER_POLINUCB);
  EXPECT_EQ(moved.pending_events(), 1);
  v1::EstimateRequest estimate;
  estimate.set_user_id("alice");
  for (int i = 0; i < 6; ++i) estimate.add_context(0.5);
  v1::EstimateResponse estimated;
  ASSERT_TRUE(stub_->Estimate(Ctx().get(), estimate, &estimated).ok());
  EXPECT_EQ(estimated.predicted_posthoc_size(), 4);  // poLinUCB's now
  v1::CheckStoreResponse check;
  ASSERT_TRUE(
      stub_->CheckStore(Ctx().get(), v1::CheckStoreRequest(), &check).ok());
  env_.set_audit_sink(nullptr);
  EXPECT_TRUE(check.ok());
  EXPECT_EQ(check.findings_size(), 0);
  EXPECT_EQ(check.users_checked(), 1);
  EXPECT_EQ(check.events_checked(), 1);

  v1::ListAuditResponse audit;
  ASSERT_TRUE(
      stub_->ListAudit(Ctx().get(), v1::ListAuditRequest(), &audit).ok());
  // Select, Estimate and ListAudit are not audited.
  ASSERT_EQ(audit.records_size(), 5);
  EXPECT_EQ(audit.records(0).method(), "BanditService/CreateUser");
  EXPECT_EQ(audit.records(0).target(), "alice");
  EXPECT_EQ(audit.records(0).result(), "OK");
  EXPECT_EQ(audit.records(1).method(), "BanditService/DeleteUser");
  EXPECT_EQ(audit.records(1).target(), "nobody");
  EXPECT_EQ(audit.records(1).result(), "NOT_FOUND");
  EXPECT_EQ(audit.records(2).method(), "BanditService/SetLearner");
  EXPECT_EQ(audit.records(2).result(), "INVALID_ARGUMENT");
  EXPECT_EQ(audit.records(3).method(), "BanditService/SetLearner");
  EXPECT_EQ(audit.records(3).target(), "alice");
  EXPECT_EQ(audit.records(3).result(), "OK");
  EXPECT_EQ(audit.records(4).method(), "BanditService/CheckStore");
  EXPECT_NE(audit.records(4).peer(), "");
  EXPECT_GT(audit.records(4).time().seconds(), 1700000000);
}

TEST(ParseEventIdTest, TakesOnlyWhatSelectReturns) {
  EXPECT_EQ(*ParseEventId("1"), 1);
  EXPECT_EQ(*ParseEventId("9223372036854775807"), INT64_MAX);
  for (const char* bad : {"", " 1", "1 ", "+5", "-5", "05", "0", "1e3", "0x10",
                          "9223372036854775808", "12345678901234567890"}) {
    absl::StatusOr<int64_t> id = ParseEventId(bad);
    EXPECT_EQ(id.status().code(), absl::StatusCode::kInvalidArgument) << bad;
  }
}

TEST(WithholdContextsTest, LeavesVectorsOutAndSaysSo) {
  v1::ListEventsResponse response;
  v1::Event* event = response.add_events();
  event->set_event_id("7");
  event->add_context(0.5);
  event->add_posthoc(-1.0);
  event->set_action(3);
  WithholdContexts(&response);
  EXPECT_TRUE(response.contexts_withheld());
  EXPECT_EQ(response.events(0).context_size(), 0);
  EXPECT_EQ(response.events(0).posthoc_size(), 0);
  EXPECT_EQ(response.events(0).action(), 3);
  EXPECT_EQ(response.events(0).event_id(), "7");
}

TEST_F(BanditServiceTest, CreateUserTakesServerDefaults) {
  const v1::User user = CreateUser("alice");
  EXPECT_EQ(user.config().context_dim(), 6u);
  EXPECT_EQ(user.config().posthoc_dim(), 4u);
  EXPECT_EQ(user.config().learner(), v1::LEARNER_POSTHOC);
  EXPECT_EQ(user.config().strategy(), v1::STRATEGY_LINUCB);
  EXPECT_DOUBLE_EQ(user.config().alpha(), 0.01);
  EXPECT_DOUBLE_EQ(user.config().lambda_c(), 1000.0);
  EXPECT_DOUBLE_EQ(user.config().lambda_p(), 1.0);
  ASSERT_EQ(user.config().action_names_size(), 6);
  EXPECT_EQ(user.config().action_names(3), "TV90");
  EXPECT_TRUE(user.config().has_seed());

  v1::CreateUserRequest request;
  request.set_user_id("bob");
  request.mutable_config()->set_alpha(0.5);
  request.mutable_config()->set_context_dim(3);
  request.mutable_config()->set_learner(v1::LEARNER_CONTEXT_ONLY);
  request.mutable_config()->add_action_names("left");
  request.mutable_config()->add_action_names("right");
  request.mutable_config()->set_seed(7);
  v1::User bob;
  ASSERT_TRUE(stub_->CreateUser(Ctx().get(), request, &bob).ok());
  EXPECT_DOUBLE_EQ(bob.config().alpha(), 0.5);
  EXPECT_EQ(bob.config().context_dim(), 3u);
  EXPECT_EQ(bob.config().action_names_size(), 2);
  EXPECT_EQ(bob.config().seed(), 7u);

  grpc::Status status = stub_->CreateUser(Ctx().get(), request, &bob);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::ALREADY_EXISTS);
  request.set_user_id("carol");
  request.mutable_config()->set_lambda_c(-1);
  status = stub_->CreateUser(Ctx().get(), request, &bob);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(status.error_message().find("config.lambda_c"), std::string::npos)
      << status.error_message();
  request.mutable_config()->clear_lambda_c();
  request.mutable_config()->set_strategy(static_cast<v1::Strategy>(42));
  status = stub_->CreateUser(Ctx().get(), request, &bob);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  request.set_user_id("");
  status = stub_->CreateUser(Ctx().get(), request, &bob);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
}

TEST_F(BanditServiceTest, SelectUpdateGetModelListEvents) {
  CreateUser("alice");
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int t = 0; t < 30; ++t) {
    std::vector<double> c(6);
    for (double& x : c) x = u(rng);
    v1::SelectResponse chosen;
    ASSERT_TRUE(Select("alice", c, &chosen, t < 10 ? "m1" : "m2").ok());
    ASSERT_EQ(chosen.estimates_size(), 6);
    for (const v1::ActionEstimate& e : chosen.estimates()) {
      EXPECT_NEAR(e.lcb(), e.predicted_loss() - 0.01 * e.width(), 1e-15);
    }
    EXPECT_EQ(chosen.action_name(),
              chosen.estimates(chosen.action()).action_name());
    EXPECT_EQ(chosen.propensity(), 1.0);
    EXPECT_EQ(chosen.model_version(), t);
    v1::UpdateResponse updated;
    ASSERT_TRUE(
        Update(chosen.event_id(), u(rng) < 0.5, {1, 0, 0, 0}, &updated).ok());
    EXPECT_EQ(updated.model_version(), t + 1);
  }
  v1::GetModelRequest model_request;
  model_request.set_user_id("alice");
  v1::Model model;
  ASSERT_TRUE(stub_->GetModel(Ctx().get(), model_request, &model).ok());
  EXPECT_EQ(model.model_version(), 30);
  int64_t total = 0;
  for (const v1::ActionModel& a : model.actions()) {
    EXPECT_EQ(a.theta_size(), 6);
    EXPECT_EQ(a.phi_size(), 4);
    total += a.count();
  }
  EXPECT_EQ(total, 30);

  v1::ListEventsRequest list;
  list.set_user_id("alice");
  list.set_meal_id("m2");
  list.set_page_size(7);
  int seen = 0;
  for (int page = 0; page < 10; ++page) {
    v1::ListEventsResponse events;
    ASSERT_TRUE(stub_->ListEvents(Ctx().get(), list, &events).ok());
    for (const v1::Event& e : events.events()) {
      EXPECT_EQ(e.meal_id(), "m2");
      EXPECT_TRUE(e.completed());
      EXPECT_EQ(e.context_size(), 6);
      ++seen;
    }
    if (events.next_page_token().empty()) break;
    list.set_page_token(events.next_page_token());
  }
  EXPECT_EQ(seen, 20);
}

// Estimate answers what a Select at the same context would weigh, for
// every learner (poLinUCB's prediction included), and records nothing: no
// event, no pending bite, the same model version. Bad input is refused by
// name, as Select refuses it.
TEST_F(BanditServiceTest, EstimateIsSelectsAnswerWithoutAnEvent) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (v1::Learner learner :
       {v1::LEARNER_POSTHOC, v1::LEARNER_CONTEXT_ONLY, v1::LEARNER_POLINUCB}) {
    const std::string id = absl::StrCat("est-", v1::Learner_Name(learner));
    v1::CreateUserRequest create;
    create.set_user_id(id);
    create.mutable_config()->set_learner(learner);
    create.mutable_config()->set_lambda_c(1.0);
    v1::User user;
    ASSERT_TRUE(stub_->CreateUser(Ctx().get(), create, &user).ok());
    for (int t = 0; t < 12; ++t) {
      std::vector<double> c(6);
      for (double& x : c) x = u(rng);
      v1::SelectResponse chosen;
      ASSERT_TRUE(Select(id, c, &chosen).ok());
      v1::UpdateResponse updated;
      ASSERT_TRUE(Update(chosen.event_id(), u(rng) < 0.0,
                         {u(rng), u(rng), u(rng), u(rng)}, &updated)
                      .ok());
    }
    v1::EstimateRequest request;
    request.set_user_id(id);
    std::vector<double> c(6);
    for (double& x : c) x = u(rng);
    request.mutable_context()->Add(c.begin(), c.end());
    v1::EstimateResponse estimated;
    grpc::Status status = stub_->Estimate(Ctx().get(), request, &estimated);
    ASSERT_TRUE(status.ok()) << status.error_message();
    EXPECT_EQ(estimated.model_version(), 12);
    v1::GetUserRequest get;
    get.set_user_id(id);
    ASSERT_TRUE(stub_->GetUser(Ctx().get(), get, &user).ok());
    EXPECT_EQ(user.model_version(), 12);
    EXPECT_EQ(user.pending_events(), 0);

    v1::SelectResponse chosen;
    ASSERT_TRUE(Select(id, c, &chosen).ok());
    ASSERT_EQ(estimated.estimates_size(), 6);
    ASSERT_EQ(chosen.estimates_size(), 6);
    bool learned = false;
    for (int a = 0; a < 6; ++a) {
      const v1::ActionEstimate& e = estimated.estimates(a);
      const v1::ActionEstimate& s = chosen.estimates(a);
      EXPECT_EQ(e.action(), a);
      EXPECT_EQ(e.action_name(), s.action_name());
      EXPECT_EQ(e.predicted_loss(), s.predicted_loss()) << id << " " << a;
      EXPECT_EQ(e.width(), s.width()) << id << " " << a;
      EXPECT_EQ(e.lcb(), s.lcb()) << id << " " << a;
      learned |= e.predicted_loss() != 0.0;
    }
    EXPECT_TRUE(learned) << id;
    EXPECT_EQ(estimated.predicted_posthoc_size(),
              learner == v1::LEARNER_POLINUCB ? 4 : 0);
    for (int k = 0; k < estimated.predicted_posthoc_size(); ++k) {
      EXPECT_EQ(estimated.predicted_posthoc(k), chosen.predicted_posthoc(k));
    }
  }

  v1::EstimateRequest bad;
  bad.set_user_id("est-LEARNER_POSTHOC");
  v1::EstimateResponse out;
  for (const std::vector<double>& context :
       {std::vector<double>{1, 2, 3},
        std::vector<double>{1, 2, NAN, 4, 5, 6}}) {
    bad.clear_context();
    bad.mutable_context()->Add(context.begin(), context.end());
    const grpc::Status status = stub_->Estimate(Ctx().get(), bad, &out);
    EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_NE(status.error_message().find("context"), std::string::npos)
        << status.error_message();
  }
  bad.set_user_id("nobody");
  bad.clear_context();
  for (int i = 0; i < 6; ++i) bad.add_context(0.5);
  EXPECT_EQ(stub_->Estimate(Ctx().get(), bad, &out).error_code(),
            grpc::StatusCode::NOT_FOUND);
  bad.set_user_id("no body");
  EXPECT_EQ(stub_->Estimate(Ctx().get(), bad, &out).error_code(),
            grpc::StatusCode::INVALID_ARGUMENT);
  // The refused calls left the user as it was: no event beyond the 13.
  v1::ListEventsRequest list;
  list.set_user_id("est-LEARNER_POSTHOC");
  list.set_page_size(100);
  v1::ListEventsResponse events;
  ASSERT_TRUE(stub_->ListEvents(Ctx().get(), list, &events).ok());
  EXPECT_EQ(events.events_size(), 13);
}

// Over real mutual TLS with a roles file: a researcher may ask Estimate; a
// researcher the contexts are withheld from may not (widths at contexts of
// its choosing would give away the learned ones), and its ListEvents has
// no contexts. The robot role may not ask Estimate.
TEST_F(BanditServiceTest, EstimateIsRefusedWhereContextsAreWithheld) {
  ASSERT_EQ(testing::Certs().error, "");
  BanditConfig config;
  config.context_dim = 6;
  ASSERT_TRUE(engine_->CreateUser("tia", config).ok());
  for (int t = 0; t < 3; ++t) {
    absl::StatusOr<SelectResult> selected =
        engine_->Select({"tia", {0.1 * t, 0.2, 0.3, 0.4, 0.5, 0.6}, "m", ""});
    ASSERT_TRUE(selected.ok()) << selected.status();
    ASSERT_TRUE(engine_->Update({selected->event_id, 1.0, {1, 0, 0, 0}}).ok());
  }
  const std::vector<double> context = {0.3, 0.1, 0.4, 0.1, 0.5, 0.9};
  for (const char* roles : {"bitewise-client researcher\n",
                            "bitewise-client researcher without_contexts\n",
                            "bitewise-client robot\n"}) {
    ServerOptions options = testing::TlsServerOptions(/*mutual=*/true);
    options.authz_file = testing::WriteRoles(roles);
    RpcEnvironment env;
    BanditServiceImpl service(&env, engine_.get(), BanditConfig());
    auto server = ServiceServer::Start(options, &env, {&service},
                                       {"bitewise.v1.BanditService"});
    ASSERT_TRUE(server.ok()) << server.status();
    (*server)->SetServing(true);
    auto channel =
        MakeChannel((*server)->address(), testing::TlsChannelOptions(true));
    ASSERT_TRUE(channel.ok());
    auto stub = v1::BanditService::NewStub(*channel);
    v1::EstimateRequest request;
    request.set_user_id("tia");
    request.mutable_context()->Add(context.begin(), context.end());
    v1::EstimateResponse estimated;
    const grpc::Status status =
        stub->Estimate(Ctx().get(), request, &estimated);
    v1::ListEventsRequest list;
    list.set_user_id("tia");
    v1::ListEventsResponse events;
    const grpc::Status listed = stub->ListEvents(Ctx().get(), list, &events);
    const std::string role = roles;
    if (role == "bitewise-client researcher\n") {
      ASSERT_TRUE(status.ok()) << status.error_message();
      absl::StatusOr<EstimateResult> direct = engine_->Estimate("tia", context);
      ASSERT_TRUE(direct.ok());
      ASSERT_EQ(estimated.estimates_size(), 6);
      for (int a = 0; a < 6; ++a) {
        EXPECT_EQ(estimated.estimates(a).width(), direct->estimates[a].width);
      }
      ASSERT_TRUE(listed.ok());
      EXPECT_FALSE(events.contexts_withheld());
      EXPECT_EQ(events.events(0).context_size(), 6);
    } else if (role == "bitewise-client robot\n") {
      EXPECT_EQ(status.error_code(), grpc::StatusCode::PERMISSION_DENIED);
      EXPECT_NE(status.error_message().find("BanditService/Estimate"),
                std::string::npos)
          << status.error_message();
    } else {
      EXPECT_EQ(status.error_code(), grpc::StatusCode::PERMISSION_DENIED);
      EXPECT_NE(status.error_message().find("without_contexts"),
                std::string::npos)
          << status.error_message();
      ASSERT_TRUE(listed.ok());
      EXPECT_TRUE(events.contexts_withheld());
      EXPECT_EQ(events.events(0).context_size(), 0);
    }
    (*server)->Shutdown();
  }
}

TEST_F(BanditServiceTest, ErrorsNameTheFieldAndChangeNothing) {
  CreateUser("alice");
  v1::SelectResponse chosen;
  grpc::Status status = Select("alice", {1, 2, 3}, &chosen);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(status.error_message().find("context: expected 6 values, got 3"),
            std::string::npos)
      << status.error_message();
  status = Select("alice", {1, 2, NAN, 4, 5, 6}, &chosen);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  status = Select("nobody", {1, 2, 3, 4, 5, 6}, &chosen);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::NOT_FOUND);

  ASSERT_TRUE(Select("alice", {1, 2, 3, 4, 5, 6}, &chosen).ok());
  v1::UpdateResponse updated;
  status = Update(chosen.event_id(), 2.0, {1, 0, 0, 0}, &updated);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(status.error_message().find("loss"), std::string::npos);
  status = Update(chosen.event_id(), 1.0, {1, 0, 0}, &updated);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(status.error_message().find("posthoc: expected 4 values, got 3"),
            std::string::npos)
      << status.error_message();
  status = Update("abc", 1.0, {1, 0, 0, 0}, &updated);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(status.error_message().find("event_id"), std::string::npos);
  status = Update("987654", 1.0, {1, 0, 0, 0}, &updated);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::NOT_FOUND);

  v1::GetUserRequest get;
  get.set_user_id("alice");
  v1::User user;
  ASSERT_TRUE(stub_->GetUser(Ctx().get(), get, &user).ok());
  EXPECT_EQ(user.model_version(), 0);
  EXPECT_EQ(user.pending_events(), 1);

  ASSERT_TRUE(Update(chosen.event_id(), 1.0, {1, 0, 0, 0}, &updated).ok());
  EXPECT_FALSE(updated.already_applied());
  ASSERT_TRUE(Update(chosen.event_id(), 1.0, {1, 0, 0, 0}, &updated).ok());
  EXPECT_TRUE(updated.already_applied());
  EXPECT_EQ(updated.model_version(), 1);
  // Another outcome for a completed event is a conflict.
  const grpc::Status conflict =
      Update(chosen.event_id(), 0.0, {0, 1, 0, 0}, &updated);
  EXPECT_EQ(conflict.error_code(), grpc::StatusCode::ALREADY_EXISTS);
  EXPECT_NE(conflict.error_message().find("was completed with loss 1"),
            std::string::npos);
}

TEST_F(BanditServiceTest, OversizedMessageIsRejected) {
  CreateUser("alice");
  v1::SelectResponse chosen;
  // 1M doubles is 8 MB, over the 4 MiB default limit.
  grpc::Status status =
      Select("alice", std::vector<double>(1 << 20, 0.5), &chosen);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  v1::GetUserRequest get;
  get.set_user_id("alice");
  v1::User user;
  ASSERT_TRUE(stub_->GetUser(Ctx().get(), get, &user).ok());
  EXPECT_EQ(user.pending_events(), 0);
}

TEST_F(BanditServiceTest, ListResetDeleteUsers) {
  for (const char* id : {"u3", "u1", "u2"}) CreateUser(id);
  v1::ListUsersRequest list;
  list.set_page_size(2);
  v1::ListUsersResponse page;
  ASSERT_TRUE(stub_->ListUsers(Ctx().get(), list, &page).ok());
  ASSERT_EQ(page.users_size(), 2);
  EXPECT_EQ(page.users(0).user_id(), "u1");
  ASSERT_FALSE(page.next_page_token().empty());
  list.set_page_token(page.next_page_token());
  ASSERT_TRUE(stub_->ListUsers(Ctx().get(), list, &page).ok());
  ASSERT_EQ(page.users_size(), 1);
  EXPECT_EQ(page.users(0).user_id(), "u3");
  EXPECT_TRUE(page.next_page_token().empty());

  v1::SelectResponse chosen;
  ASSERT_TRUE(Select("u1", {1, 1, 1, 1, 1, 1}, &chosen).ok());
  v1::UpdateResponse updated;
  ASSERT_TRUE(Update(chosen.event_id(), 1, {0, 0, 1, 0}, &updated).ok());
  v1::ResetUserRequest reset;
  reset.set_user_id("u1");
  v1::User user;
  ASSERT_TRUE(stub_->ResetUser(Ctx().get(), reset, &user).ok());
  EXPECT_EQ(user.model_version(), 0);
  // The old event is gone with the reset.
  ASSERT_EQ(Update(chosen.event_id(), 1, {0, 0, 1, 0}, &updated).error_code(),
            grpc::StatusCode::NOT_FOUND);

  v1::DeleteUserRequest del;
  del.set_user_id("u2");
  v1::DeleteUserResponse deleted;
  ASSERT_TRUE(stub_->DeleteUser(Ctx().get(), del, &deleted).ok());
  EXPECT_EQ(stub_->DeleteUser(Ctx().get(), del, &deleted).error_code(),
            grpc::StatusCode::NOT_FOUND);
  v1::GetModelRequest model;
  model.set_user_id("u2");
  v1::Model out;
  EXPECT_EQ(stub_->GetModel(Ctx().get(), model, &out).error_code(),
            grpc::StatusCode::NOT_FOUND);
}

}  // namespace
}  // namespace bitewise::bandit
