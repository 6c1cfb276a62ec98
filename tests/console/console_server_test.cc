// bitewise-console's server over the four real services in this process:
// the HTTP API as a browser uses it (httplib's client), who may do what
// (access file, roles, cross-site requests), a meal driven apart from any
// browser (disconnect, reconnect, two watchers, a second meal refused), and
// the researcher's numbers against ListEvents.
#include "clients/console/console_server.h"

#include <arpa/inet.h>
#include <httplib.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <fstream>
#include <memory>
#include <string>
#include <thread>

#include "absl/strings/escaping.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "absl/time/clock.h"
#include "clients/console/access_list.h"
#include "clients/console/meal_host.h"
#include "clients/console/research.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "services/common/channel.h"
#include "tests/meal/four_services.h"

namespace bitewise::console {
namespace {

using ::bitewise::testing::FourServices;
using ::bitewise::testing::FourServicesOptions;
using ::bitewise::testing::SharedFourServicesTest;
using ::testing::HasSubstr;
using ::testing::Not;

const httplib::Headers kPost = {{"X-Bitewise-Request", "1"}};

class ConsoleServerTest : public SharedFourServicesTest<ConsoleServerTest> {
 public:
  static FourServicesOptions Options() {
    FourServicesOptions options;
    options.foods = {"strawberry", "carrot", "banana",    "grape",
                     "kiwi",       "celery", "cantaloupe"};
    return options;
  }

 protected:
  void SetUp() override {
    ASSERT_NE(services_, nullptr);
    clients_ = std::make_unique<meals::ServiceClients>(services_->channels(),
                                                       meals::CallDeadlines());
    MealHostOptions host_options;
    host_options.journal_path = absl::StrCat(
        services_->dir(), "/",
        ::testing::UnitTest::GetInstance()->current_test_info()->name(),
        ".journal");
    host_ = std::make_unique<MealHost>(clients_.get(), host_options);
  }

  void TearDown() override {
    if (server_) server_->Shutdown();
    server_.reset();
    host_.reset();
  }

  void StartServer(ConsoleServerOptions options = {}) {
    options.port = 0;
    auto server =
        ConsoleServer::Start(std::move(options), host_.get(), clients_.get());
    ASSERT_TRUE(server.ok()) << server.status();
    server_ = *std::move(server);
  }

  httplib::Client Client() {
    httplib::Client client("127.0.0.1", server_->port());
    client.set_read_timeout(30, 0);
    return client;
  }

  // Waits until the meal's phase is one of `phases`.
  mealpb::MealState WaitForPhase(std::vector<std::string> phases) {
    const absl::Time deadline = absl::Now() + absl::Seconds(60);
    mealpb::MealState state;
    while (absl::Now() < deadline) {
      state = host_->State();
      for (const std::string& phase : phases) {
        if (state.phase() == phase) return state;
      }
      absl::SleepFor(absl::Milliseconds(20));
    }
    ADD_FAILURE() << "phase stayed " << state.phase();
    return state;
  }

  std::unique_ptr<meals::ServiceClients> clients_;
  std::unique_ptr<MealHost> host_;
  std::unique_ptr<ConsoleServer> server_;
};

TEST(IsLoopbackTest, OnlyLoopbackAddresses) {
  EXPECT_TRUE(IsLoopback("127.0.0.1"));
  EXPECT_TRUE(IsLoopback("127.3.2.1"));
  EXPECT_TRUE(IsLoopback("::1"));
  EXPECT_TRUE(IsLoopback("localhost"));
  EXPECT_FALSE(IsLoopback("0.0.0.0"));
  EXPECT_FALSE(IsLoopback("192.0.2.7"));
  EXPECT_FALSE(IsLoopback("::"));
}

TEST_F(ConsoleServerTest, OffLoopbackNeedsTlsAndAnAccessFile) {
  ConsoleServerOptions options;
  options.host = "0.0.0.0";
  auto server = ConsoleServer::Start(options, host_.get(), clients_.get());
  EXPECT_EQ(server.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(server.status().message(), HasSubstr("needs HTTPS"));
  options.host = "127.0.0.1";
  options.tls_cert_file = "only-one.pem";
  server = ConsoleServer::Start(options, host_.get(), clients_.get());
  EXPECT_EQ(server.status().code(), absl::StatusCode::kInvalidArgument);
}

TEST_F(ConsoleServerTest, ServesTheBundledAppAndNothingElse) {
  StartServer();
  httplib::Client client = Client();
  auto page = client.Get("/");
  ASSERT_TRUE(page);
  EXPECT_EQ(page->status, 200);
  EXPECT_THAT(page->get_header_value("Content-Type"), HasSubstr("text/html"));
  EXPECT_THAT(page->body, HasSubstr("app.js"));
  EXPECT_THAT(page->get_header_value("Content-Security-Policy"),
              HasSubstr("default-src 'self'"));
  auto script = client.Get("/app.js");
  ASSERT_TRUE(script);
  EXPECT_EQ(script->status, 200);
  auto missing = client.Get("/../etc/passwd");
  ASSERT_TRUE(missing);
  EXPECT_EQ(missing->status, 404);
}

TEST_F(ConsoleServerTest, AMealRunsApartFromTheBrowserAndASecondIsRefused) {
  StartServer();
  httplib::Client client = Client();
  // Without the header a state change is refused (cross-site protection).
  auto refused =
      client.Post("/api/meals", R"({"user_id":"ann"})", "application/json");
  ASSERT_TRUE(refused);
  EXPECT_EQ(refused->status, 403);
  auto cross = client.Post(
      "/api/meals",
      {{"X-Bitewise-Request", "1"}, {"Origin", "http://evil.example"}},
      R"({"user_id":"ann"})", "application/json");
  ASSERT_TRUE(cross);
  EXPECT_EQ(cross->status, 403);
  EXPECT_THAT(cross->body, HasSubstr("cross-origin"));
  auto bad_id = client.Post("/api/meals", kPost, R"({"user_id":"a b"})",
                            "application/json");
  ASSERT_TRUE(bad_id);
  EXPECT_EQ(bad_id->status, 400);
  EXPECT_THAT(bad_id->body, HasSubstr("user_id"));
  EXPECT_EQ(host_->State().phase(), "idle");

  auto started = client.Post("/api/meals", kPost,
                             R"({"user_id":"ann","meal_id":"lunch-1"})",
                             "application/json");
  ASSERT_TRUE(started);
  ASSERT_EQ(started->status, 201) << started->body;
  auto second = client.Post("/api/meals", kPost,
                            R"({"user_id":"bob","meal_id":"lunch-2"})",
                            "application/json");
  ASSERT_TRUE(second);
  EXPECT_EQ(second->status, 409);
  EXPECT_THAT(second->body, HasSubstr("meal lunch-1 for ann is running"));

  const mealpb::MealState plate = WaitForPhase({"choosing"});
  ASSERT_GT(plate.items_size(), 0);
  auto jpeg = client.Get("/api/meal/plate.jpg");
  ASSERT_TRUE(jpeg);
  EXPECT_EQ(jpeg->status, 200);
  EXPECT_EQ(jpeg->get_header_value("Content-Type"), "image/jpeg");
  EXPECT_EQ(jpeg->body.substr(0, 2), "\xff\xd8");

  auto off_plate = client.Post("/api/meal/bite", kPost, R"({"item_index":99})",
                               "application/json");
  ASSERT_TRUE(off_plate);
  EXPECT_EQ(off_plate->status, 400);
  EXPECT_THAT(off_plate->body, HasSubstr("not on the plate"));

  // A browser watches the bite start, then goes away mid-bite.
  {
    httplib::Client watcher = Client();
    std::string seen;
    auto bite = client.Post("/api/meal/bite", kPost, R"({"item_index":-1})",
                            "application/json");
    ASSERT_TRUE(bite);
    ASSERT_EQ(bite->status, 202) << bite->body;
    auto busy = client.Post("/api/meal/bite", kPost, R"({"item_index":0})",
                            "application/json");
    ASSERT_TRUE(busy);
    EXPECT_EQ(busy->status, 409);
    watcher.Get("/api/meal/stream", [&](const char* data, size_t length) {
      seen.append(data, length);
      // Disconnects at the first progress report.
      return !absl::StrContains(seen, "event: progress");
    });
    EXPECT_THAT(seen, HasSubstr("event: state"));
    EXPECT_THAT(seen, HasSubstr("STEP_ACQUIRE"));
  }
  // The bite went on without the browser, once.
  const mealpb::MealState after = WaitForPhase({"choosing", "ended"});
  ASSERT_EQ(after.bites_size(), 1);
  EXPECT_EQ(after.bites(0).learned(), "learned");
  // A browser that connects now is sent the current state first.
  std::string first;
  Client().Get("/api/meal/stream", [&](const char* data, size_t length) {
    first.append(data, length);
    return first.find("\n\n") == std::string::npos;
  });
  EXPECT_THAT(first, HasSubstr("event: state"));
  EXPECT_THAT(first, HasSubstr("\"bite\":1"));

  auto ended = client.Post("/api/meal/end", kPost, "", "application/json");
  ASSERT_TRUE(ended);
  EXPECT_EQ(ended->status, 202);
  const mealpb::MealState over = WaitForPhase({"ended"});
  EXPECT_THAT(over.message(), HasSubstr("1 attempt,"));
  // Now another meal may start.
  auto next = client.Post("/api/meals", kPost, R"({"user_id":"bob"})",
                          "application/json");
  ASSERT_TRUE(next);
  EXPECT_EQ(next->status, 201);
  WaitForPhase({"choosing"});
}

// Two browsers watching at once see the same bite: the same event, the
// same phases.
TEST_F(ConsoleServerTest, TwoBrowsersSeeTheSameMeal) {
  StartServer();
  auto started = Client().Post("/api/meals", kPost, R"({"user_id":"duo"})",
                               "application/json");
  ASSERT_TRUE(started);
  ASSERT_EQ(started->status, 201);
  WaitForPhase({"choosing"});
  std::string seen[2];
  std::thread watchers[2];
  for (int i = 0; i < 2; ++i) {
    watchers[i] = std::thread([this, &seen, i] {
      Client().Get(
          "/api/meal/stream", [&seen, i](const char* data, size_t length) {
            seen[i].append(data, length);
            return !absl::StrContains(seen[i], "\"learned\":\"learned\"");
          });
    });
  }
  // Both are subscribed once each has been sent the current state.
  const absl::Time deadline = absl::Now() + absl::Seconds(10);
  while (absl::Now() < deadline &&
         !(absl::StrContains(seen[0], "event: state") &&
           absl::StrContains(seen[1], "event: state"))) {
    absl::SleepFor(absl::Milliseconds(10));
  }
  auto bite = Client().Post("/api/meal/bite", kPost, R"({"item_index":-1})",
                            "application/json");
  ASSERT_TRUE(bite);
  ASSERT_EQ(bite->status, 202);
  for (std::thread& watcher : watchers) watcher.join();
  const mealpb::MealState state = WaitForPhase({"choosing", "ended"});
  ASSERT_EQ(state.bites_size(), 1);
  const std::string event =
      absl::StrCat("\"event_id\":\"", state.bites(0).event_id(), "\"");
  for (const std::string& stream : seen) {
    EXPECT_THAT(stream, HasSubstr(event));
    EXPECT_THAT(stream, HasSubstr("ACQUIRE_PHASE_DESCEND"));
    EXPECT_THAT(stream, HasSubstr("\"learned\":\"learned\""));
  }
}

TEST(HostIsLoopbackTest, OnlyLoopbackNamesWithOrWithoutAPort) {
  EXPECT_TRUE(HostIsLoopback("127.0.0.1:8080"));
  EXPECT_TRUE(HostIsLoopback("127.0.0.1"));
  EXPECT_TRUE(HostIsLoopback("localhost:8080"));
  EXPECT_TRUE(HostIsLoopback("[::1]:8080"));
  EXPECT_FALSE(HostIsLoopback(""));
  EXPECT_FALSE(HostIsLoopback("evil.example:8080"));
  EXPECT_FALSE(HostIsLoopback("127.0.0.1.evil.example:8080"));
  EXPECT_FALSE(HostIsLoopback("[::2]:8080"));
}

// Without an access file every caller is `local`: a page whose own name was
// re-pointed at 127.0.0.1 (DNS rebinding) sends that name as Host, and is
// refused, for reading and for acting alike.
TEST_F(ConsoleServerTest, WithoutAnAccessFileOnlyLoopbackNamesAreAnswered) {
  StartServer();
  const std::string rebound = absl::StrCat("evil.example:", server_->port());
  httplib::Headers post = kPost;
  post.emplace("Host", rebound);
  post.emplace("Origin", absl::StrCat("http://", rebound));
  auto started = Client().Post("/api/meals", post, "{}", "application/json");
  ASSERT_TRUE(started);
  EXPECT_EQ(started->status, 403);
  EXPECT_THAT(started->body, HasSubstr("addressed to localhost, 127.x.x.x or "
                                       "[::1] (Host: \\\"evil.example"));
  auto read = Client().Get("/api/people", {{"Host", rebound}});
  ASSERT_TRUE(read);
  EXPECT_EQ(read->status, 403);
  auto own = Client().Get("/api/people");
  ASSERT_TRUE(own);
  EXPECT_EQ(own->status, 200) << own->body;
}

TEST_F(ConsoleServerTest, StopAnswersWithOrWithoutAMeal) {
  StartServer();
  auto stopped = Client().Post("/api/stop", kPost, "", "application/json");
  ASSERT_TRUE(stopped);
  EXPECT_EQ(stopped->status, 200);
  EXPECT_THAT(stopped->body, HasSubstr("\"was_moving\":false"));
}

// A raw TCP connection to the console that sends `request` (maybe nothing)
// and is held open until destroyed.
class HeldConnection {
 public:
  HeldConnection(int port, const std::string& request) {
    fd_ = socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_port = htons(port);
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    connected_ = fd_ >= 0 &&
                 connect(fd_, reinterpret_cast<sockaddr*>(&address),
                         sizeof(address)) == 0 &&
                 send(fd_, request.data(), request.size(), MSG_NOSIGNAL) ==
                     static_cast<ssize_t>(request.size());
  }
  ~HeldConnection() {
    if (fd_ >= 0) close(fd_);
  }
  bool connected() const { return connected_; }
  // The reply's first line ("HTTP/1.1 200 OK"), read within 10 s.
  std::string StatusLine() {
    timeval timeout{10, 0};
    setsockopt(fd_, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof(timeout));
    std::string line;
    char c;
    while (line.size() < 200 && recv(fd_, &c, 1, 0) == 1 && c != '\n') {
      if (c != '\r') line += c;
    }
    return line;
  }

 private:
  int fd_ = -1;
  bool connected_ = false;
};

TEST_F(ConsoleServerTest, StopFindsAThreadWhilePagesHoldConnections) {
  StartServer();
  const std::string stream_request =
      "GET /api/meal/stream HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n";
  std::vector<std::unique_ptr<HeldConnection>> held;
  for (int i = 0; i < ConsoleServer::kMaxEventStreams; ++i) {
    held.push_back(
        std::make_unique<HeldConnection>(server_->port(), stream_request));
    ASSERT_TRUE(held.back()->connected());
    EXPECT_EQ(held.back()->StatusLine(), "HTTP/1.1 200 OK") << i;
  }
  HeldConnection one_more(server_->port(), stream_request);
  ASSERT_TRUE(one_more.connected());
  EXPECT_EQ(one_more.StatusLine(), "HTTP/1.1 503 Service Unavailable");
  // Connections that send nothing, as idle keep-alive connections and
  // half-open requests do: each holds a request thread for up to 5 s.
  for (int i = 0; i < 100; ++i) {
    held.push_back(std::make_unique<HeldConnection>(server_->port(), ""));
    ASSERT_TRUE(held.back()->connected());
  }
  // Before the thread pool outgrew the held connections, STOP waited for
  // one of them to time out (5 s).
  httplib::Client client = Client();
  client.set_read_timeout(3, 0);
  auto stopped = client.Post("/api/stop", kPost, "", "application/json");
  ASSERT_TRUE(stopped) << httplib::to_string(stopped.error());
  EXPECT_EQ(stopped->status, 200);
  // A stream closed frees its place.
  held.erase(held.begin());
  // (The server sees the close at its next ping, within 4 s.)
  for (int attempt = 0; attempt < 150; ++attempt) {
    HeldConnection again(server_->port(), stream_request);
    ASSERT_TRUE(again.connected());
    if (again.StatusLine() == "HTTP/1.1 200 OK") return;
    absl::SleepFor(absl::Milliseconds(100));
  }
  ADD_FAILURE() << "a closed stream's place was not freed";
}

TEST_F(ConsoleServerTest, ResearchersNumbersAreListEvents) {
  StartServer();
  // Two short meals for one person, through the meal library.
  for (const char* meal_id : {"breakfast", "lunch"}) {
    meals::UpdateJournal journal(
        absl::StrCat(services_->dir(), "/research.journal"));
    meals::MealOptions options;
    options.user_id = "rita";
    options.meal_id = meal_id;
    meals::Meal meal(clients_.get(), &journal, options, nullptr);
    for (int bite = 0; bite < 2; ++bite) {
      ASSERT_TRUE(meal.LookAtPlate().ok());
      ASSERT_TRUE(meal.Bite(std::nullopt).ok());
    }
  }
  httplib::Client client = Client();
  auto meals_reply = client.Get("/api/people/rita/meals");
  ASSERT_TRUE(meals_reply);
  ASSERT_EQ(meals_reply->status, 200) << meals_reply->body;
  bool withheld = false;
  absl::StatusOr<std::vector<v1::Event>> events =
      AllEvents(clients_->bandit, "rita", "", false, &withheld);
  ASSERT_TRUE(events.ok());
  ASSERT_EQ(events->size(), 4u);
  int failures = 0;
  for (const v1::Event& e : *events) failures += e.loss() >= 0.5;
  const webapi::v1::MealsReply tally = MealsOf("rita", *events);
  ASSERT_EQ(tally.meals_size(), 2);
  EXPECT_EQ(tally.meals(0).meal_id(), "breakfast");
  EXPECT_EQ(tally.meals(0).attempts() + tally.meals(1).attempts(), 4);
  EXPECT_EQ(tally.meals(0).failures() + tally.meals(1).failures(), failures);
  EXPECT_EQ(meals_reply->body, ToJson(tally));

  auto csv = client.Get("/api/people/rita/events.csv?meal_id=lunch");
  ASSERT_TRUE(csv);
  EXPECT_EQ(csv->status, 200);
  std::vector<std::string> rows = absl::StrSplit(csv->body, "\r\n");
  ASSERT_EQ(rows.size(), 4u);  // header, two events, the last line break
  EXPECT_THAT(rows[0], ::testing::StartsWith("event_id,user_id,meal_id"));
  EXPECT_THAT(rows[1], HasSubstr(",rita,lunch,"));
  EXPECT_THAT(rows[0], ::testing::Not(HasSubstr("context")));
  EXPECT_EQ(csv->get_header_value("Content-Disposition"),
            "attachment; filename=\"rita-lunch-events.csv\"");
  // A quote in the meal id cannot end the file's name early.
  auto quoted = client.Get("/api/people/rita/events.csv?meal_id=a%22b%3Bc");
  ASSERT_TRUE(quoted);
  EXPECT_EQ(quoted->get_header_value("Content-Disposition"),
            "attachment; filename=\"rita-a_b_c-events.csv\"");
  auto with_contexts =
      client.Get("/api/people/rita/events.csv?meal_id=lunch&contexts=1");
  ASSERT_TRUE(with_contexts);
  EXPECT_THAT(with_contexts->body, HasSubstr(",context\r\n"));
  // The whole history, sent a page at a time, is the CSV of every event;
  // so is the stream read one event a page.
  absl::StatusOr<std::vector<v1::Event>> with_vectors =
      AllEvents(clients_->bandit, "rita", "", true, nullptr);
  ASSERT_TRUE(with_vectors.ok());
  auto all = client.Get("/api/people/rita/events.csv?contexts=1");
  ASSERT_TRUE(all);
  EXPECT_EQ(all->status, 200);
  EXPECT_EQ(all->body, EventsCsv(*with_vectors, true));
  EXPECT_EQ(all->get_header_value("Transfer-Encoding"), "chunked");
  absl::StatusOr<std::unique_ptr<EventsCsvStream>> one_a_page =
      EventsCsvStream::Start(clients_->bandit, "rita", "", true,
                             /*page_size=*/1);
  ASSERT_TRUE(one_a_page.ok()) << one_a_page.status();
  std::string pieces;
  int reads = 0;
  for (absl::StatusOr<std::string> piece = (*one_a_page)->Next();
       piece.ok() && !piece->empty(); piece = (*one_a_page)->Next()) {
    pieces += *piece;
    ++reads;
  }
  EXPECT_EQ(pieces, EventsCsv(*with_vectors, true));
  EXPECT_GE(reads, 4);
  auto nobody = client.Get("/api/people/nobody/events.csv");
  ASSERT_TRUE(nobody);
  EXPECT_EQ(nobody->status, 404);

  auto page = client.Get("/api/people/rita/events?page_size=3");
  ASSERT_TRUE(page);
  EXPECT_EQ(page->status, 200);
  EXPECT_THAT(page->body, HasSubstr("\"next_page_token\":\""));
  EXPECT_THAT(page->body, HasSubstr("\"context\":[]"));
  auto too_big = client.Get("/api/people/rita/events?page_size=5000");
  ASSERT_TRUE(too_big);
  EXPECT_EQ(too_big->status, 400);
  auto bad_user = client.Get("/api/people/r%20ta/meals");
  ASSERT_TRUE(bad_user);
  EXPECT_EQ(bad_user->status, 400);
  auto unknown = client.Get("/api/people/nobody/meals");
  ASSERT_TRUE(unknown);
  EXPECT_EQ(unknown->status, 404);

  auto estimates = client.Get(absl::StrCat(
      "/api/people/rita/estimates?event_id=", (*events)[0].event_id()));
  ASSERT_TRUE(estimates);
  ASSERT_EQ(estimates->status, 200) << estimates->body;
  EXPECT_THAT(estimates->body, HasSubstr("\"action_name\":\"VS0\""));
  auto bad_event = client.Get("/api/people/rita/estimates?event_id=x");
  ASSERT_TRUE(bad_event);
  EXPECT_EQ(bad_event->status, 400);
  // An id the BanditService would never return ("+7", " 7", "07") is a
  // bad request, not "not one of rita's".
  for (const std::string& odd : {absl::StrCat("%2B", (*events)[0].event_id()),
                                 absl::StrCat("%20", (*events)[0].event_id()),
                                 absl::StrCat("0", (*events)[0].event_id())}) {
    auto refused =
        client.Get(absl::StrCat("/api/people/rita/estimates?event_id=", odd));
    ASSERT_TRUE(refused);
    EXPECT_EQ(refused->status, 400) << odd << ": " << refused->body;
  }

  auto health = client.Get("/api/health");
  ASSERT_TRUE(health);
  EXPECT_EQ(health->status, 200);
}

// A service's address that reaches a server of another service: the server
// answered, so it is SERVICE_UNKNOWN, not UNREACHABLE (it was).
TEST_F(ConsoleServerTest, HealthTellsAnotherServiceFromNoneAtAll) {
  ConsoleServerOptions options;
  auto channel = MakeChannel(services_->haptic_address(), ChannelOptions());
  ASSERT_TRUE(channel.ok()) << channel.status();
  options.services.push_back(
      {"bitewise.v1.BanditService", services_->haptic_address(), *channel});
  StartServer(options);
  httplib::Client client = Client();
  auto health = client.Get("/api/health");
  ASSERT_TRUE(health);
  ASSERT_EQ(health->status, 200) << health->body;
  EXPECT_THAT(health->body, HasSubstr("\"status\":\"SERVICE_UNKNOWN\""));
  EXPECT_THAT(health->body, Not(HasSubstr("UNREACHABLE")));
}

TEST_F(ConsoleServerTest, WithAnAccessFileEverythingNeedsCredentials) {
  const std::string path = absl::StrCat(services_->dir(), "/access");
  {
    absl::StatusOr<std::string> carer = HashPassword("table-pass", 1000);
    absl::StatusOr<std::string> researcher = HashPassword("lab-pass", 1000);
    ASSERT_TRUE(carer.ok() && researcher.ok());
    std::ofstream out(path);
    out << "# who may use the console\n"
        << "carol caregiver " << *carer << "\n"
        << "rex researcher " << *researcher << "\n";
  }
  absl::StatusOr<AccessList> access = AccessList::Load(path);
  ASSERT_TRUE(access.ok()) << access.status();
  ConsoleServerOptions options;
  options.access = std::make_shared<const AccessList>(*access);
  StartServer(options);

  httplib::Client anonymous = Client();
  for (const char* path : {"/", "/app.js", "/api/session", "/api/meal",
                           "/api/people", "/api/meal/stream", "/api/health",
                           "/api/people/x/events.csv", "/api/meal/plate.jpg"}) {
    auto reply = anonymous.Get(path);
    ASSERT_TRUE(reply) << path;
    EXPECT_EQ(reply->status, 401) << path;
    EXPECT_THAT(reply->get_header_value("WWW-Authenticate"),
                HasSubstr("Basic"));
    EXPECT_THAT(reply->body, ::testing::Not(HasSubstr("users")));
  }
  auto stop = anonymous.Post("/api/stop", kPost, "", "application/json");
  ASSERT_TRUE(stop);
  EXPECT_EQ(stop->status, 401);

  httplib::Client wrong = Client();
  wrong.set_basic_auth("carol", "not-it");
  auto denied = wrong.Get("/api/session");
  ASSERT_TRUE(denied);
  EXPECT_EQ(denied->status, 401);

  httplib::Client carer = Client();
  carer.set_basic_auth("carol", "table-pass");
  auto session = carer.Get("/api/session");
  ASSERT_TRUE(session);
  EXPECT_EQ(session->status, 200);
  EXPECT_THAT(session->body, HasSubstr("\"role\":\"caregiver\""));
  auto research = carer.Get("/api/health");
  ASSERT_TRUE(research);
  EXPECT_EQ(research->status, 403);
  auto carer_stop = carer.Post("/api/stop", kPost, "", "application/json");
  ASSERT_TRUE(carer_stop);
  EXPECT_EQ(carer_stop->status, 200);

  httplib::Client researcher = Client();
  researcher.set_basic_auth("rex", "lab-pass");
  auto start = researcher.Post("/api/meals", kPost, R"({"user_id":"ann"})",
                               "application/json");
  ASSERT_TRUE(start);
  EXPECT_EQ(start->status, 403);
  auto health = researcher.Get("/api/health");
  ASSERT_TRUE(health);
  EXPECT_EQ(health->status, 200);
  auto researcher_stop =
      researcher.Post("/api/stop", kPost, "", "application/json");
  ASSERT_TRUE(researcher_stop);
  EXPECT_EQ(researcher_stop->status, 200);
}

TEST_F(ConsoleServerTest, WrongPasswordsInBulkDoNotHoldUpStop) {
  const std::string path = absl::StrCat(services_->dir(), "/access-bulk");
  {
    // 10^6 iterations: a check takes a quarter of a second or more here, so
    // the wrong passwords below all arrive while the first is checked.
    absl::StatusOr<std::string> carer = HashPassword("table-pass", 1000000);
    ASSERT_TRUE(carer.ok());
    std::ofstream out(path);
    out << "carol caregiver " << *carer << "\n";
  }
  absl::StatusOr<AccessList> access = AccessList::Load(path);
  ASSERT_TRUE(access.ok()) << access.status();
  ConsoleServerOptions options;
  options.access = std::make_shared<const AccessList>(*access);
  StartServer(options);
  httplib::Client carer = Client();
  carer.set_basic_auth("carol", "table-pass");
  auto session = carer.Get("/api/session");  // verifies the password once
  ASSERT_TRUE(session);
  ASSERT_EQ(session->status, 200);

  constexpr int kGuesses = 40;
  std::vector<int> statuses(kGuesses, 0);
  std::vector<std::string> bodies(kGuesses);
  std::vector<std::thread> guessers;
  std::atomic<int> answered{0};
  for (int i = 0; i < kGuesses; ++i) {
    guessers.emplace_back([this, i, &statuses, &bodies, &answered] {
      httplib::Client guesser = Client();
      guesser.set_read_timeout(120, 0);  // 17 checks in turn on a busy CI
      guesser.set_basic_auth("carol", absl::StrCat("guess-", i));
      auto reply = guesser.Get("/api/session");
      ++answered;
      if (reply) {
        statuses[i] = reply->status;
        bodies[i] = reply->body;
        if (reply->status == 429) {
          EXPECT_FALSE(reply->has_header("WWW-Authenticate"));
        }
      }
    });
  }
  absl::SleepFor(absl::Milliseconds(100));
  // A verified password is not queued behind the guesses: STOP is answered
  // while checks still run (had it waited, every guess would be answered).
  auto stopped = carer.Post("/api/stop", kPost, "", "application/json");
  const int answered_at_stop = answered.load();
  for (std::thread& guesser : guessers) guesser.join();
  EXPECT_LT(answered_at_stop, kGuesses);
  ASSERT_TRUE(stopped);
  EXPECT_EQ(stopped->status, 200);
  int refused_at_once = 0;
  for (int i = 0; i < kGuesses; ++i) {
    if (statuses[i] == 429) {
      ++refused_at_once;
      EXPECT_THAT(bodies[i], HasSubstr("too many password checks at once"));
    } else {
      EXPECT_EQ(statuses[i], 401) << i;
    }
  }
  // One check runs and AccessList::kMaxWaitingChecks wait; the rest are
  // refused without running PBKDF2.
  EXPECT_GE(refused_at_once, 1);
  EXPECT_LE(kGuesses - refused_at_once, 1 + AccessList::kMaxWaitingChecks + 8)
      << "more checks ran than the queue allows (late arrivals aside)";
}

TEST(AccessListTest, MalformedFilesAreRefusedNamingTheLine) {
  const std::string path = ::testing::TempDir() + "/bad_access";
  {
    std::ofstream out(path);
    out << "carol caregiver pbkdf2-sha256$10$00$00\n";
  }
  absl::StatusOr<AccessList> access = AccessList::Load(path);
  EXPECT_EQ(access.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(access.status().message(), HasSubstr(":1:"));
  {
    std::ofstream out(path);
    absl::StatusOr<std::string> hash = HashPassword("x", 1000);
    out << "carol chef " << *hash << "\n";
  }
  EXPECT_THAT(AccessList::Load(path).status().message(),
              HasSubstr("unknown role \"chef\""));
  EXPECT_EQ(AccessList::Load(path + ".absent").status().code(),
            absl::StatusCode::kFailedPrecondition);
}

}  // namespace
}  // namespace bitewise::console
