// TestPostgres: a real PostgreSQL server (Debian's postgresql-15) started by
// a test in a temporary directory, the way the PostgreSQL store's tests and
// benchmarks get a database without any setup outside the test. It runs
// initdb and the server as an unprivileged account when the test runs as
// root (the server refuses root), listens only on a Unix socket in its own
// directory, keeps fsync on (the store refuses a server without it) and
// dies with the test process. Each test takes a fresh database from it.
//
// The server's binaries are found in $BITEWISE_PG_BINDIR, else in
// `pg_config --bindir`, else in /usr/lib/postgresql/<newest>/bin.
#ifndef BITEWISE_TESTS_COMMON_POSTGRES_SERVER_H_
#define BITEWISE_TESTS_COMMON_POSTGRES_SERVER_H_

#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "tests/common/child_process.h"

namespace bitewise::testing {

class TestPostgres {
 public:
  // initdb in a new temporary directory, then Start().
  static absl::StatusOr<std::unique_ptr<TestPostgres>> Create();
  ~TestPostgres();
  TestPostgres(const TestPostgres&) = delete;
  TestPostgres& operator=(const TestPostgres&) = delete;

  // Starts the server on the existing data directory and waits until it
  // accepts connections.
  absl::Status Start();
  // Start with server settings over the usual ones, e.g. {"fsync=off"}.
  absl::Status Start(const std::vector<std::string>& settings);
  // A fast shutdown (SIGINT), waiting for it to end.
  absl::Status Stop();
  bool running() const { return server_.running(); }
  // NAME=value variables for the server's environment from its next
  // Start (e.g. the write-fault injector).
  void set_server_env(std::vector<std::string> env) {
    server_.set_env(std::move(env));
  }

  // Creates a new, empty database and returns its connection string
  // (postgresql:///NAME?host=DIR&port=PORT&user=bitewise).
  absl::StatusOr<std::string> CreateDatabase(const std::string& name);
  std::string ConnInfo(const std::string& database) const;

  // Runs SQL on `database` as the superuser (tests' tampering and
  // inspection) and returns the first column of the first row, if any.
  absl::StatusOr<std::string> Query(const std::string& database,
                                    const std::string& sql);

  // The server and every process it started, stopped (SIGSTOP) as a hung
  // host or a debugger would leave them: their sockets stay open and the
  // kernel still takes bytes, but nothing answers. They go on (SIGCONT)
  // when the object goes.
  class Frozen {
   public:
    explicit Frozen(std::vector<int> pids) : pids_(std::move(pids)) {}
    Frozen(const Frozen&) = delete;
    Frozen& operator=(const Frozen&) = delete;
    ~Frozen();

   private:
    std::vector<int> pids_;
  };
  absl::StatusOr<std::unique_ptr<Frozen>> Freeze();

  const std::string& dir() const { return dir_; }
  std::string log() const { return server_.log(); }

 private:
  TestPostgres() = default;
  std::string bindir_;
  std::string dir_;
  int port_ = 0;
  std::optional<ChildProcess::RunAs> run_as_;
  ChildProcess server_;
};

// One server for the whole test binary, created at first use and removed
// at exit. Aborts the test (ADD_FAILURE) and returns null if it cannot
// start.
TestPostgres* SharedTestPostgres();

}  // namespace bitewise::testing

#endif  // BITEWISE_TESTS_COMMON_POSTGRES_SERVER_H_
