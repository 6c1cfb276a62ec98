// bandit_restart_bench: how long a restarted BanditService keeps a person
// waiting (docs/benchmarks.md, "Restarts"). For each log size it writes a
// SQLite store straight through the store library (--other_users users of
// d = 64 with 20 events each, and one d = --d user "u" with the given
// number of events), starts the real bitewise-bandit binary on it (shipped
// flags), loads u's model once, and then, several times each:
//   kill   --clients threads do Select+Update pairs on u without a pause;
//          SIGKILL at a random moment of the --load_s load;
//   term   the same with SIGTERM;
//   idle   --load_s of load, then --idle_s without calls, then SIGKILL.
// After each stop it starts the binary again and times process start to
// SERVING and to u's first Select answered; it also reads the store to say
// how many of u's events came after its newest checkpoint (the replay the
// first Select paid), and reports the Update latency during the load.
//
//   build/benchmarks/bandit_restart_bench                          # about 12
//   min build/benchmarks/bandit_restart_bench --sizes=4000 --kills=2   #
//   quicker
#include <grpcpp/create_channel.h>
#include <grpcpp/security/credentials.h>
#include <grpcpp/support/channel_arguments.h>
#include <signal.h>
#include <stdlib.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "absl/flags/flag.h"
#include "absl/flags/parse.h"
#include "absl/status/status.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "absl/time/clock.h"
#include "absl/time/time.h"
#include "benchmarks/bandit_bench_rounds.h"
#include "bitewise/v1/bandit.grpc.pb.h"
#include "services/bandit/store/sqlite_event_store.h"
#include "services/common/channel.h"
#include "tests/common/child_process.h"

ABSL_FLAG(std::string, server, BITEWISE_BANDIT_BINARY,
          "The bitewise-bandit binary to start.");
ABSL_FLAG(std::string, sizes, "1000,4000,50000", "u's log sizes (events).");
ABSL_FLAG(int, d, 2048, "u's context dimension.");
ABSL_FLAG(int, other_users, 200, "Other users in the database.");
ABSL_FLAG(int, clients, 2, "Threads feeding u during the load.");
ABSL_FLAG(double, load_s, 20, "Seconds of load before a stop.");
ABSL_FLAG(double, idle_s, 35,
          "Seconds without calls before the idle SIGKILL (the shipped "
          "--checkpoint_idle_s is 30).");
ABSL_FLAG(int, kills, 3, "Stops of each kind per size.");
ABSL_FLAG(std::string, server_args, "",
          "Extra flags for the server, space separated (e.g. "
          "--checkpoint_max_events=1000).");
ABSL_FLAG(bool, keep, false,
          "Keep each size's database directory (its path is printed) to "
          "time a start by hand.");

namespace bitewise {
namespace {

using bandit::EventStore;
using bandit::SqliteEventStore;
using bandit::SqliteStoreOptions;
using bandit::UserRecord;
using Clock = std::chrono::steady_clock;

double Ms(Clock::duration t) {
  return std::chrono::duration<double, std::milli>(t).count();
}

struct Server {
  testing::ChildProcess process;
  std::shared_ptr<grpc::Channel> channel;
  std::unique_ptr<v1::BanditService::Stub> stub;
  std::string address;
};

// Starts the binary and returns once it is SERVING; the time that took.
absl::StatusOr<double> Start(Server& server, const std::string& db,
                             const std::string& log) {
  absl::StatusOr<int> port = testing::PickFreePort();
  if (!port.ok()) return port.status();
  server.address = absl::StrCat("127.0.0.1:", *port);
  const auto t0 = Clock::now();
  std::vector<std::string> argv = {absl::GetFlag(FLAGS_server),
                                   absl::StrCat("--db=", db),
                                   absl::StrCat("--listen=", server.address)};
  for (absl::string_view arg : absl::StrSplit(absl::GetFlag(FLAGS_server_args),
                                              ' ', absl::SkipEmpty())) {
    argv.emplace_back(arg);
  }
  absl::Status started = server.process.Start(argv, log);
  if (!started.ok()) return started;
  // Reconnect attempts every 5 ms, not gRPC's backoff of a second or more
  // after the first attempt finds no listener yet.
  grpc::ChannelArguments args;
  args.SetInt(GRPC_ARG_INITIAL_RECONNECT_BACKOFF_MS, 5);
  args.SetInt(GRPC_ARG_MIN_RECONNECT_BACKOFF_MS, 5);
  args.SetInt(GRPC_ARG_MAX_RECONNECT_BACKOFF_MS, 20);
  server.channel = grpc::CreateCustomChannel(
      server.address, grpc::InsecureChannelCredentials(), args);
  // Polled every 5 ms: the time is that of the first SERVING answer.
  while (true) {
    absl::StatusOr<ServingStatus> health = CheckHealth(
        server.channel, "bitewise.v1.BanditService", absl::Seconds(1));
    if (health.ok() && *health == ServingStatus::kServing) break;
    if (Ms(Clock::now() - t0) > 120000) {
      return absl::DeadlineExceededError(
          absl::StrCat("not SERVING after 120 s:\n", server.process.log()));
    }
    absl::SleepFor(absl::Milliseconds(5));
  }
  const double ms = Ms(Clock::now() - t0);
  server.stub = v1::BanditService::NewStub(server.channel);
  return ms;
}

v1::SelectRequest SelectFor(int d, std::mt19937_64& rng) {
  v1::SelectRequest select;
  select.set_user_id("u");
  select.set_meal_id("bench");
  select.set_item_label("carrot");
  const bandit::Round round = bandit::bench::RandomRound(d, rng);
  select.mutable_context()->Add(round.context.begin(), round.context.end());
  return select;
}

// One Select of u; false on error.
bool SelectOnce(Server& server, int d, std::mt19937_64& rng,
                v1::SelectResponse* response) {
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() +
                       std::chrono::seconds(120));
  return server.stub->Select(&context, SelectFor(d, rng), response).ok();
}

// --clients threads doing Select+Update pairs on u until `stop`.
class Load {
 public:
  Load(Server& server, int d) {
    for (int i = 0; i < absl::GetFlag(FLAGS_clients); ++i) {
      threads_.emplace_back([this, &server, d, i] {
        std::mt19937_64 rng(1000 + i);
        auto stub = v1::BanditService::NewStub(server.channel);
        while (!stop_.load()) {
          v1::SelectResponse selected;
          {
            grpc::ClientContext context;
            context.set_deadline(std::chrono::system_clock::now() +
                                 std::chrono::seconds(30));
            if (!stub->Select(&context, SelectFor(d, rng), &selected).ok()) {
              return;
            }
          }
          v1::UpdateRequest update;
          update.set_event_id(selected.event_id());
          update.set_loss(rng() % 3 == 0 ? 1.0 : 0.0);
          for (int q = 0; q < bandit::bench::kPostHocDim; ++q) {
            update.add_posthoc(q == 0 ? 1.0 : 0.0);
          }
          v1::UpdateResponse updated;
          grpc::ClientContext context;
          context.set_deadline(std::chrono::system_clock::now() +
                               std::chrono::seconds(30));
          const auto t0 = Clock::now();
          if (!stub->Update(&context, update, &updated).ok()) return;
          const double ms = Ms(Clock::now() - t0);
          absl::MutexLock lock(&mu_);
          update_ms_.push_back(ms);
        }
      });
    }
  }
  ~Load() { Stop(); }
  void Stop() {
    stop_.store(true);
    for (std::thread& t : threads_) {
      if (t.joinable()) t.join();
    }
  }
  std::vector<double> update_ms() {
    absl::MutexLock lock(&mu_);
    return update_ms_;
  }

 private:
  std::atomic<bool> stop_{false};
  std::vector<std::thread> threads_;
  absl::Mutex mu_;
  std::vector<double> update_ms_;
};

double Percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0.0;
  const size_t k = std::min(v.size() - 1, static_cast<size_t>(p * v.size()));
  std::nth_element(v.begin(), v.begin() + k, v.end());
  return v[k];
}

// u's completed events, and those after its newest checkpoint, read from
// the store (the service is stopped).
struct LogState {
  int64_t events = -1;
  int64_t after_checkpoint = -1;
};
LogState ReadLogState(const std::string& db) {
  SqliteStoreOptions options;
  options.path = db;
  auto store = SqliteEventStore::Open(options);
  if (!store.ok()) return {};
  absl::StatusOr<UserRecord> user = (*store)->GetUser("u");
  if (!user.ok()) return {};
  absl::StatusOr<bandit::ModelCheckpoint> checkpoint =
      (*store)->GetCheckpoint("u");
  return {
      user->model_version,
      user->model_version - (checkpoint.ok() ? checkpoint->model_version : 0)};
}

int Run() {
  const int d = absl::GetFlag(FLAGS_d);
  const double load_s = absl::GetFlag(FLAGS_load_s);
  std::printf(
      "bitewise-bandit restarts: u at d = %d with %d other users, %d "
      "clients without pauses during the load (%.0f s), server flags "
      "[%s]; times from process start\n\n",
      d, absl::GetFlag(FLAGS_other_users), absl::GetFlag(FLAGS_clients), load_s,
      absl::GetFlag(FLAGS_server_args).c_str());
  std::printf("%8s %6s %10s %12s %14s %12s %14s\n", "events", "stop",
              "after_ckpt", "serving_ms", "first_select", "update_p50",
              "update_p99");
  std::mt19937_64 rng(7);
  for (absl::string_view size :
       absl::StrSplit(absl::GetFlag(FLAGS_sizes), ',', absl::SkipEmpty())) {
    int n = 0;
    if (!absl::SimpleAtoi(size, &n) || n < 1) return 2;
    std::string dir =
        std::filesystem::temp_directory_path() / "bitewise_restart_XXXXXX";
    if (mkdtemp(dir.data()) == nullptr) return 1;
    const std::string db = dir + "/bandit.db";
    {
      SqliteStoreOptions options;
      options.path = db;
      options.create_if_missing = true;
      options.synchronous_full = false;  // setup only
      auto store = SqliteEventStore::Open(options);
      if (!store.ok()) {
        std::fprintf(stderr, "%s\n", store.status().ToString().c_str());
        return 1;
      }
      for (int i = 0; i < absl::GetFlag(FLAGS_other_users); ++i) {
        UserRecord other;
        other.user_id = absl::StrCat("other-", i);
        other.config = bandit::bench::Config(64);
        other.created_at = absl::Now();
        if (!(*store)->CreateUser(other).ok()) return 1;
        bandit::bench::WriteEvents(**store, other.user_id, 64, 20, rng);
      }
      UserRecord u;
      u.user_id = "u";
      u.config = bandit::bench::Config(d);
      u.created_at = absl::Now();
      if (!(*store)->CreateUser(u).ok()) return 1;
      bandit::bench::WriteEvents(**store, "u", d, n, rng);
    }
    int starts = 0;
    auto next_log = [&] {
      return absl::StrCat(dir, "/server-", starts++, ".log");
    };
    Server server;
    absl::StatusOr<double> serving = Start(server, db, next_log());
    if (!serving.ok()) {
      std::fprintf(stderr, "%s\n", serving.status().ToString().c_str());
      return 1;
    }
    v1::SelectResponse first;
    const auto t0 = Clock::now();
    if (!SelectOnce(server, d, rng, &first)) return 1;
    std::printf("%8d %6s %10d %12.0f %14.0f %12s %14s   (the whole log)\n", n,
                "first", n, *serving, *serving + Ms(Clock::now() - t0), "", "");
    std::fflush(stdout);
    for (const char* kind : {"kill", "term", "idle"}) {
      for (int k = 0; k < absl::GetFlag(FLAGS_kills); ++k) {
        std::vector<double> update_ms;
        {
          Load load(server, d);
          if (std::string(kind) == "idle") {
            absl::SleepFor(absl::Seconds(load_s));
            load.Stop();
            absl::SleepFor(absl::Seconds(absl::GetFlag(FLAGS_idle_s)));
          } else {
            std::uniform_real_distribution<double> at(load_s / 2, load_s);
            absl::SleepFor(absl::Seconds(at(rng)));
          }
          const int signal = std::string(kind) == "term" ? SIGTERM : SIGKILL;
          if (!server.process.SignalAndWait(signal, absl::Seconds(60)).ok()) {
            return 1;
          }
          load.Stop();
          update_ms = load.update_ms();
        }
        const LogState log_state = ReadLogState(db);
        serving = Start(server, db, next_log());
        if (!serving.ok()) {
          std::fprintf(stderr, "%s\n", serving.status().ToString().c_str());
          return 1;
        }
        const auto t1 = Clock::now();
        if (!SelectOnce(server, d, rng, &first)) return 1;
        std::printf("%8lld %6s %10lld %12.0f %14.0f %12.1f %14.1f\n",
                    static_cast<long long>(log_state.events), kind,
                    static_cast<long long>(log_state.after_checkpoint),
                    *serving, *serving + Ms(Clock::now() - t1),
                    Percentile(update_ms, 0.5), Percentile(update_ms, 0.99));
        std::fflush(stdout);
      }
    }
    server.process.Kill();
    if (absl::GetFlag(FLAGS_keep)) {
      std::printf("kept %s\n", dir.c_str());
      continue;
    }
    std::error_code ignored;
    std::filesystem::remove_all(dir, ignored);
  }
  return 0;
}

}  // namespace
}  // namespace bitewise

int main(int argc, char** argv) {
  absl::ParseCommandLine(argc, argv);
  return bitewise::Run();
}
