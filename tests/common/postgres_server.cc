#include "tests/common/postgres_server.h"

#include <libpq-fe.h>
#include <pwd.h>
#include <signal.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>

#include "absl/strings/ascii.h"
#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "gtest/gtest.h"

namespace bitewise::testing {
namespace {

bool IsExecutable(const std::string& path) {
  return access(path.c_str(), X_OK) == 0;
}

absl::StatusOr<std::string> FindBindir() {
  if (const char* env = std::getenv("BITEWISE_PG_BINDIR"); env != nullptr) {
    if (IsExecutable(absl::StrCat(env, "/postgres"))) return std::string(env);
    return absl::FailedPreconditionError(
        absl::StrCat("BITEWISE_PG_BINDIR=", env, " has no postgres binary"));
  }
  if (FILE* pipe = popen("pg_config --bindir 2>/dev/null", "r")) {
    char buffer[512] = {0};
    const bool read = fgets(buffer, sizeof(buffer), pipe) != nullptr;
    pclose(pipe);
    const std::string dir(absl::StripAsciiWhitespace(read ? buffer : ""));
    if (!dir.empty() && IsExecutable(dir + "/postgres")) return dir;
  }
  std::string best;
  std::error_code error;
  for (const auto& entry :
       std::filesystem::directory_iterator("/usr/lib/postgresql", error)) {
    const std::string bin = entry.path().string() + "/bin";
    if (IsExecutable(bin + "/postgres") && bin > best) best = bin;
  }
  if (!best.empty()) return best;
  return absl::FailedPreconditionError(
      "no PostgreSQL server binaries found (install postgresql-15, or set "
      "BITEWISE_PG_BINDIR)");
}

}  // namespace

absl::StatusOr<std::unique_ptr<TestPostgres>> TestPostgres::Create() {
  std::unique_ptr<TestPostgres> pg(new TestPostgres());
  absl::StatusOr<std::string> bindir = FindBindir();
  if (!bindir.ok()) return bindir.status();
  pg->bindir_ = *bindir;
  std::string pattern = "/tmp/bitewise-pg-XXXXXX";
  if (mkdtemp(pattern.data()) == nullptr) {
    return absl::InternalError(absl::StrCat("mkdtemp: ", std::strerror(errno)));
  }
  pg->dir_ = pattern;
  if (geteuid() == 0) {
    const passwd* account = getpwnam("postgres");
    if (account == nullptr) account = getpwnam("nobody");
    if (account == nullptr) {
      return absl::FailedPreconditionError(
          "running as root and there is no postgres or nobody account to "
          "run the server as");
    }
    pg->run_as_ = ChildProcess::RunAs{account->pw_uid, account->pw_gid};
    if (chown(pg->dir_.c_str(), account->pw_uid, account->pw_gid) != 0) {
      return absl::InternalError(
          absl::StrCat("chown ", pg->dir_, ": ", std::strerror(errno)));
    }
  }
  // The port only names the socket file in our own directory.
  pg->port_ = 5432;
  ChildProcess initdb;
  absl::Status started = initdb.Start(
      {pg->bindir_ + "/initdb", "-D", pg->dir_ + "/data", "-U", "bitewise",
       "-A", "trust", "-E", "UTF8", "--no-locale", "--no-sync"},
      pg->dir_ + "/initdb.log", pg->run_as_);
  if (!started.ok()) return started;
  absl::StatusOr<int> status = initdb.Wait(absl::Seconds(120));
  if (!status.ok()) return status.status();
  if (*status != 0) {
    return absl::InternalError(absl::StrCat(
        "initdb: ", DescribeWaitStatus(*status), "\n", initdb.log()));
  }
  absl::Status running = pg->Start();
  if (!running.ok()) return running;
  return pg;
}

TestPostgres::~TestPostgres() {
  if (server_.running()) Stop().IgnoreError();
  std::error_code ignored;
  std::filesystem::remove_all(dir_, ignored);
}

absl::Status TestPostgres::Start() { return Start({}); }

absl::Status TestPostgres::Start(const std::vector<std::string>& settings) {
  std::vector<std::string> args = {bindir_ + "/postgres",
                                   "-D",
                                   dir_ + "/data",
                                   "-k",
                                   dir_,
                                   "-p",
                                   absl::StrCat(port_),
                                   "-c",
                                   "listen_addresses=",
                                   "-c",
                                   "fsync=on",
                                   "-c",
                                   "shared_buffers=32MB",
                                   "-c",
                                   "max_connections=60",
                                   "-c",
                                   "dynamic_shared_memory_type=mmap",
                                   "-c",
                                   "max_wal_size=256MB"};
  for (const std::string& setting : settings) {
    args.push_back("-c");  // a later -c wins
    args.push_back(setting);
  }
  absl::Status started = server_.Start(args, dir_ + "/server.log", run_as_);
  if (!started.ok()) return started;
  const std::string conninfo = ConnInfo("postgres");
  const absl::Time deadline = absl::Now() + absl::Seconds(60);
  while (PQping(conninfo.c_str()) != PQPING_OK) {
    if (absl::Now() > deadline) {
      return absl::DeadlineExceededError(
          absl::StrCat("PostgreSQL did not start:\n", server_.log()));
    }
    absl::StatusOr<int> exited = server_.Wait(absl::Milliseconds(50));
    if (exited.ok()) {
      return absl::InternalError(
          absl::StrCat("PostgreSQL exited: ", DescribeWaitStatus(*exited), "\n",
                       server_.log()));
    }
  }
  return absl::OkStatus();
}

TestPostgres::Frozen::~Frozen() {
  for (const int pid : pids_) kill(pid, SIGCONT);
}

absl::StatusOr<std::unique_ptr<TestPostgres::Frozen>> TestPostgres::Freeze() {
  if (!server_.running()) {
    return absl::FailedPreconditionError("the test server is not running");
  }
  const int postmaster = server_.pid();
  // The postmaster first, so that it starts no process meanwhile.
  if (kill(postmaster, SIGSTOP) != 0) {
    return absl::InternalError(
        absl::StrCat("cannot stop the server: ", std::strerror(errno)));
  }
  std::vector<int> pids = {postmaster};
  std::error_code error;
  for (const auto& entry :
       std::filesystem::directory_iterator("/proc", error)) {
    const std::string name = entry.path().filename().string();
    if (name.empty() || !absl::ascii_isdigit(name[0])) continue;
    FILE* file = std::fopen((entry.path() / "stat").c_str(), "r");
    if (file == nullptr) continue;
    char buffer[1024] = {0};
    const size_t n = std::fread(buffer, 1, sizeof(buffer) - 1, file);
    std::fclose(file);
    // pid (comm) state ppid ...: comm may hold spaces and parentheses.
    const std::string stat(buffer, n);
    const size_t close = stat.rfind(')');
    if (close == std::string::npos) continue;
    int ppid = 0;
    char state = 0;
    if (std::sscanf(stat.c_str() + close + 1, " %c %d", &state, &ppid) != 2) {
      continue;
    }
    if (ppid != postmaster) continue;
    const int pid = std::atoi(name.c_str());
    if (kill(pid, SIGSTOP) == 0) pids.push_back(pid);
  }
  auto frozen = std::make_unique<Frozen>(std::move(pids));
  if (error) {
    return absl::InternalError(  // thawed as `frozen` goes
        absl::StrCat("cannot list /proc: ", error.message()));
  }
  return frozen;
}

absl::Status TestPostgres::Stop() {
  absl::StatusOr<int> status = server_.SignalAndWait(SIGINT, absl::Seconds(60));
  return status.status();
}

std::string TestPostgres::ConnInfo(const std::string& database) const {
  return absl::StrCat("postgresql:///", database, "?host=", dir_,
                      "&port=", port_, "&user=bitewise");
}

absl::StatusOr<std::string> TestPostgres::Query(const std::string& database,
                                                const std::string& sql) {
  PGconn* conn = PQconnectdb(ConnInfo(database).c_str());
  if (PQstatus(conn) != CONNECTION_OK) {
    const std::string message = PQerrorMessage(conn);
    PQfinish(conn);
    return absl::UnavailableError(message);
  }
  PGresult* result = PQexec(conn, sql.c_str());
  const ExecStatusType status = PQresultStatus(result);
  std::string out;
  absl::Status error;
  if (status != PGRES_COMMAND_OK && status != PGRES_TUPLES_OK) {
    error = absl::InternalError(absl::StrCat(sql, ": ", PQerrorMessage(conn)));
  } else if (status == PGRES_TUPLES_OK && PQntuples(result) > 0) {
    out = PQgetvalue(result, 0, 0);
  }
  PQclear(result);
  PQfinish(conn);
  if (!error.ok()) return error;
  return out;
}

absl::StatusOr<std::string> TestPostgres::CreateDatabase(
    const std::string& name) {
  absl::StatusOr<std::string> created =
      Query("postgres", absl::StrCat("CREATE DATABASE ", name));
  if (!created.ok()) return created.status();
  return ConnInfo(name);
}

TestPostgres* SharedTestPostgres() {
  static TestPostgres* const server = [] {
    absl::StatusOr<std::unique_ptr<TestPostgres>> created =
        TestPostgres::Create();
    if (!created.ok()) {
      ADD_FAILURE() << "cannot start a test PostgreSQL server: "
                    << created.status();
      return static_cast<TestPostgres*>(nullptr);
    }
    TestPostgres* raw = created->release();
    // Stopped and removed at exit (the server also dies with the process).
    std::atexit([] { delete SharedTestPostgres(); });
    return raw;
  }();
  return server;
}

}  // namespace bitewise::testing
