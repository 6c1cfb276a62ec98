// bandit_service_bench: the BanditService as its clients see it, durable
// writes included (docs/benchmarks.md, "BanditService over gRPC"). It starts
// the real bitewise-bandit binary on a fresh SQLite file in a temporary
// directory (fsync on, as shipped), or with --store=postgresql on a new
// database of a PostgreSQL server it starts there (fsync on), creates --users
// post hoc users (d =
// --d, q = 4, six actions), plays one Select+Update pair per user to load
// every model, then runs --clients threads, each with its own connection,
// doing Select+Update pairs on random users for --seconds. It prints pairs
// per second, Select and Update latency percentiles, and the bytes the
// server wrote to storage per pair (SQLite: /proc/<pid>/io write_bytes of
// the service, the database and its write-ahead log; PostgreSQL: the disk's
// own count, every process included, so run it on an idle machine) against the
// event's raw size (8 (d + q) bytes of vectors plus 64 of ids, action,
// propensity, loss, weight and times).
//
//   build/benchmarks/bandit_service_bench                       # d 64, 16
//   clients build/benchmarks/bandit_service_bench --clients=1
//   build/benchmarks/bandit_service_bench --d=2048 --users=20 --clients=4
//   build/benchmarks/bandit_service_bench --store=postgresql
//   build/benchmarks/bandit_service_bench --store=postgresql --replicas=2
#include <grpcpp/create_channel.h>
#include <grpcpp/security/credentials.h>
#include <grpcpp/support/channel_arguments.h>
#include <signal.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "absl/flags/flag.h"
#include "absl/flags/parse.h"
#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "absl/strings/str_split.h"
#include "absl/time/clock.h"
#include "absl/time/time.h"
#include "bitewise/v1/bandit.grpc.pb.h"
#include "tests/common/child_process.h"
#include "tests/common/postgres_server.h"

ABSL_FLAG(std::string, server, BITEWISE_BANDIT_BINARY,
          "The bitewise-bandit binary to start.");
ABSL_FLAG(int, users, 200, "Users, each with its own model.");
ABSL_FLAG(int, d, 64, "Context dimension.");
ABSL_FLAG(int, clients, 16, "Concurrent clients, one connection each.");
ABSL_FLAG(double, seconds, 10, "Timed phase.");
ABSL_FLAG(bool, fsync, true, "The server's --sqlite_fsync.");
ABSL_FLAG(std::string, store, "sqlite", "sqlite or postgresql.");
ABSL_FLAG(int, replicas, 1,
          "bitewise-bandit processes on the one database (PostgreSQL); the "
          "clients call them round robin.");
ABSL_FLAG(std::string, server_args, "",
          "Extra flags for the server, space separated.");

namespace bitewise {
namespace {

using Clock = std::chrono::steady_clock;
constexpr int kPostHocDim = 4;
constexpr int kActions = 6;

double Ms(Clock::duration t) {
  return std::chrono::duration<double, std::milli>(t).count();
}

double Percentile(std::vector<double>& v, double p) {
  if (v.empty()) return 0.0;
  const size_t k = std::min(v.size() - 1, static_cast<size_t>(p * v.size()));
  std::nth_element(v.begin(), v.begin() + k, v.end());
  return v[k];
}

// Bytes the process has caused to be written to storage so far.
int64_t WriteBytes(pid_t pid) {
  std::ifstream io(absl::StrCat("/proc/", pid, "/io"));
  std::string key;
  int64_t value = 0;
  while (io >> key >> value) {
    if (key == "write_bytes:") return value;
  }
  return -1;
}

// Bytes written to the block device holding `path`, by every process
// (/proc/diskstats: sectors written, 512 bytes each). PostgreSQL's backends
// show hundreds of KB of write_bytes per commit in /proc/<pid>/io that
// never reach the device, so for it the device's own count is used.
int64_t DeviceWriteBytes(const std::string& path) {
  struct stat info {};
  if (stat(path.c_str(), &info) != 0) return -1;
  std::ifstream stats("/proc/diskstats");
  unsigned major_id = 0, minor_id = 0;
  std::string name;
  std::string line;
  while (std::getline(stats, line)) {
    std::istringstream fields(line);
    fields >> major_id >> minor_id >> name;
    if (major_id != major(info.st_dev) || minor_id != minor(info.st_dev)) {
      continue;
    }
    int64_t value = 0;
    for (int field = 4; field <= 10 && fields >> value; ++field) {
      if (field == 10) return value * 512;
    }
  }
  return -1;
}

// `target`: one address, or several (replicas) separated by commas, which
// the channel calls round robin, as the orchestrator's list does.
std::unique_ptr<v1::BanditService::Stub> NewStub(const std::string& target) {
  grpc::ChannelArguments args;
  // Its own connection, as separate robots would have.
  args.SetInt(GRPC_ARG_USE_LOCAL_SUBCHANNEL_POOL, 1);
  const bool list = target.find(',') != std::string::npos;
  if (list) {
    args.SetServiceConfigJSON(
        R"({"loadBalancingConfig": [{"round_robin": {}}]})");
  }
  return v1::BanditService::NewStub(
      grpc::CreateCustomChannel(list ? "ipv4:" + target : target,
                                grpc::InsecureChannelCredentials(), args));
}

struct Latencies {
  std::vector<double> select_ms, update_ms;
  int64_t errors = 0;
  std::string first_error;
};

// One unary call with a 30 s deadline; false (and the first error kept) if
// it fails.
template <typename Request, typename Response>
bool Call(grpc::Status (v1::BanditService::Stub::*method)(grpc::ClientContext*,
                                                          const Request&,
                                                          Response*),
          v1::BanditService::Stub& stub, const Request& request,
          Response* response, Latencies* out) {
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() +
                       std::chrono::seconds(30));
  const grpc::Status status = (stub.*method)(&context, request, response);
  if (status.ok()) return true;
  if (out->errors++ == 0) out->first_error = status.error_message();
  return false;
}

// One Select and the Update of its event; false if either fails.
bool Pair(v1::BanditService::Stub& stub, const std::string& user, int d,
          std::mt19937_64& rng, Latencies* out) {
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  v1::SelectRequest select;
  select.set_user_id(user);
  select.set_meal_id("bench");
  select.set_item_label("carrot");
  for (int i = 0; i < d; ++i) select.add_context(unit(rng));
  v1::SelectResponse selected;
  const auto t0 = Clock::now();
  if (!Call(&v1::BanditService::Stub::Select, stub, select, &selected, out)) {
    return false;
  }
  const auto t1 = Clock::now();
  v1::UpdateRequest update;
  update.set_event_id(selected.event_id());
  update.set_loss(unit(rng) < 0.4 ? 1.0 : 0.0);
  for (int i = 0; i < kPostHocDim; ++i) update.add_posthoc(unit(rng));
  v1::UpdateResponse updated;
  if (!Call(&v1::BanditService::Stub::Update, stub, update, &updated, out)) {
    return false;
  }
  const auto t2 = Clock::now();
  out->select_ms.push_back(Ms(t1 - t0));
  out->update_ms.push_back(Ms(t2 - t1));
  return true;
}

int Run() {
  const int users = absl::GetFlag(FLAGS_users);
  const int d = absl::GetFlag(FLAGS_d);
  const int clients = absl::GetFlag(FLAGS_clients);
  char dir_template[] = "/tmp/bitewise-service-bench-XXXXXX";
  const char* dir = mkdtemp(dir_template);
  if (dir == nullptr) {
    std::perror("mkdtemp");
    return 1;
  }
  std::string db = absl::StrCat(dir, "/bench.db");
  const bool postgres = absl::GetFlag(FLAGS_store) == "postgresql";
  std::unique_ptr<testing::TestPostgres> pg;
  if (postgres) {
    absl::StatusOr<std::unique_ptr<testing::TestPostgres>> started =
        testing::TestPostgres::Create();
    absl::StatusOr<std::string> conninfo =
        started.ok() ? (*started)->CreateDatabase("bench")
                     : absl::StatusOr<std::string>(started.status());
    if (!conninfo.ok()) {
      std::fprintf(stderr, "PostgreSQL: %s\n",
                   conninfo.status().ToString().c_str());
      return 1;
    }
    pg = *std::move(started);
    db = *conninfo;
  } else if (absl::GetFlag(FLAGS_store) != "sqlite") {
    std::fprintf(stderr, "--store: sqlite or postgresql\n");
    return 1;
  }
  auto written_now = [&](pid_t service) {
    return postgres ? DeviceWriteBytes(pg->dir()) : WriteBytes(service);
  };
  const int replicas = absl::GetFlag(FLAGS_replicas);
  if (replicas < 1 || (replicas > 1 && !postgres)) {
    std::fprintf(stderr, "--replicas: 1, or more with --store=postgresql\n");
    return 1;
  }
  std::vector<std::string> targets;
  std::vector<std::unique_ptr<testing::ChildProcess>> servers;
  for (int r = 0; r < replicas; ++r) {
    absl::StatusOr<int> port = testing::PickFreePort();
    if (!port.ok()) {
      std::fprintf(stderr, "%s\n", port.status().ToString().c_str());
      return 1;
    }
    targets.push_back(absl::StrCat("127.0.0.1:", *port));
    std::vector<std::string> argv = {
        absl::GetFlag(FLAGS_server), absl::StrCat("--db=", db), "--create",
        absl::StrCat("--listen=", targets.back()),
        absl::StrCat("--sqlite_fsync=", absl::GetFlag(FLAGS_fsync))};
    for (absl::string_view extra : absl::StrSplit(
             absl::GetFlag(FLAGS_server_args), ' ', absl::SkipEmpty())) {
      argv.emplace_back(extra);
    }
    servers.push_back(std::make_unique<testing::ChildProcess>());
    absl::Status status =
        servers.back()->Start(argv, absl::StrCat(dir, "/server-", r, ".log"));
    if (status.ok()) {
      status = servers.back()->WaitForLog(
          absl::StrCat("serving on ", targets.back(), " "), absl::Seconds(60));
    }
    if (!status.ok()) {
      std::fprintf(stderr, "server: %s\n", status.ToString().c_str());
      return 1;
    }
  }
  testing::ChildProcess& server = *servers.front();
  const std::string target = absl::StrJoin(targets, ",");

  std::unique_ptr<v1::BanditService::Stub> admin = NewStub(target);
  for (int u = 0; u < users; ++u) {
    v1::CreateUserRequest request;
    request.set_user_id(absl::StrCat("user-", u));
    v1::UserConfig* config = request.mutable_config();
    config->set_learner(v1::LEARNER_POSTHOC);
    config->set_strategy(v1::STRATEGY_LINUCB);
    config->set_context_dim(d);
    config->set_posthoc_dim(kPostHocDim);
    for (int a = 0; a < kActions; ++a) {
      config->add_action_names(absl::StrCat("action-", a));
    }
    config->set_seed(u + 1);
    grpc::ClientContext context;
    v1::User created;
    const grpc::Status s = admin->CreateUser(&context, request, &created);
    if (!s.ok()) {
      std::fprintf(stderr, "CreateUser: %s\n", s.error_message().c_str());
      return 1;
    }
  }
  // Every model loaded once.
  {
    std::mt19937_64 rng(1);
    Latencies warm;
    for (int u = 0; u < users; ++u) {
      if (!Pair(*admin, absl::StrCat("user-", u), d, rng, &warm)) {
        std::fprintf(stderr, "warm-up: %s\n", warm.first_error.c_str());
        return 1;
      }
    }
  }

  const int64_t written_before = written_now(server.pid());
  // PostgreSQL's own count of the WAL it generated (pg_stat_wal).
  auto wal = [&](const char* column) -> double {
    if (!postgres) return 0.0;
    absl::StatusOr<std::string> value = pg->Query(
        "bench", absl::StrCat("SELECT ", column, " FROM pg_stat_wal"));
    return value.ok() ? std::atof(value->c_str()) : 0.0;
  };
  const double wal_bytes_before = wal("wal_bytes"),
               wal_fpi_before = wal("wal_fpi"),
               wal_syncs_before = wal("wal_sync");
  std::vector<Latencies> per_client(clients);
  std::atomic<bool> stop{false};
  std::vector<std::thread> threads;
  const auto start = Clock::now();
  for (int c = 0; c < clients; ++c) {
    threads.emplace_back([&, c] {
      std::unique_ptr<v1::BanditService::Stub> stub = NewStub(target);
      std::mt19937_64 rng(1000 + c);
      std::uniform_int_distribution<int> pick(0, users - 1);
      while (!stop.load(std::memory_order_relaxed)) {
        Pair(*stub, absl::StrCat("user-", pick(rng)), d, rng, &per_client[c]);
      }
    });
  }
  std::this_thread::sleep_for(
      std::chrono::duration<double>(absl::GetFlag(FLAGS_seconds)));
  stop = true;
  for (std::thread& t : threads) t.join();
  const double seconds =
      std::chrono::duration<double>(Clock::now() - start).count();
  const int64_t written = written_now(server.pid()) - written_before;

  Latencies all;
  for (const Latencies& l : per_client) {
    all.select_ms.insert(all.select_ms.end(), l.select_ms.begin(),
                         l.select_ms.end());
    all.update_ms.insert(all.update_ms.end(), l.update_ms.begin(),
                         l.update_ms.end());
    all.errors += l.errors;
    if (all.first_error.empty()) all.first_error = l.first_error;
  }
  const double pairs = static_cast<double>(all.update_ms.size());
  const double raw = 8.0 * (d + kPostHocDim) + 64;
  std::printf(
      "%s, %d replica(s), d = %d, %d users, %d clients, fsync %s, %.1f s: "
      "%.0f pairs, %.0f pairs/s, %lld errors\n",
      postgres ? "PostgreSQL" : "SQLite", replicas, d, users, clients,
      postgres || absl::GetFlag(FLAGS_fsync) ? "on" : "off", seconds, pairs,
      pairs / seconds, static_cast<long long>(all.errors));
  if (all.errors > 0) std::printf("first error: %s\n", all.first_error.c_str());
  std::printf("%-8s %8s %8s %8s %8s\n", "ms", "p50", "p90", "p99", "max");
  for (auto* v : {&all.select_ms, &all.update_ms}) {
    std::printf("%-8s %8.3f %8.3f %8.3f %8.3f\n",
                v == &all.select_ms ? "Select" : "Update", Percentile(*v, 0.5),
                Percentile(*v, 0.9), Percentile(*v, 0.99),
                v->empty() ? 0.0 : *std::max_element(v->begin(), v->end()));
  }
  if (pairs > 0 && written >= 0) {
    std::printf(
        "written to storage: %.1f KB per pair; the event's raw size %.1f KB: "
        "%.2fx\n",
        written / pairs / 1024.0, raw / 1024.0, written / pairs / raw);
  }
  if (postgres && pairs > 0) {
    std::printf(
        "PostgreSQL WAL: %.1f KB per pair (%.2f full-page images), %.2f "
        "WAL syncs per pair\n",
        (wal("wal_bytes") - wal_bytes_before) / pairs / 1024.0,
        (wal("wal_fpi") - wal_fpi_before) / pairs,
        (wal("wal_sync") - wal_syncs_before) / pairs);
  }
  for (auto& replica : servers) {
    replica->SignalAndWait(SIGTERM, absl::Seconds(20)).IgnoreError();
  }
  std::filesystem::remove_all(dir);
  return all.errors > 0 ? 1 : 0;
}

}  // namespace
}  // namespace bitewise

int main(int argc, char** argv) {
  absl::ParseCommandLine(argc, argv);
  return bitewise::Run();
}
