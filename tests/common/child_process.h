// ChildProcess: runs a real bitewise binary from a test, the way an
// operator would, with its output in a log file. Used by the tests that
// start service binaries (crash, drain, bad model files, end to end). The
// child dies with the test process even if the test crashes.
#ifndef BITEWISE_TESTS_COMMON_CHILD_PROCESS_H_
#define BITEWISE_TESTS_COMMON_CHILD_PROCESS_H_

#include <sys/types.h>

#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/time/time.h"

namespace bitewise::testing {

// A port that was free a moment ago (bound to 127.0.0.1:0 and released).
// A server may still lose a race for it; callers retry on a new port.
absl::StatusOr<int> PickFreePort();

// The whole file, or "" if it cannot be read.
std::string ReadFile(const std::string& path);

// "exit 3", "killed by signal 9", ...
std::string DescribeWaitStatus(int status);

class ChildProcess {
 public:
  ChildProcess() = default;
  ~ChildProcess() { Kill(); }
  ChildProcess(const ChildProcess&) = delete;
  ChildProcess& operator=(const ChildProcess&) = delete;

  // An unprivileged account to run the child as (when the test runs as
  // root: PostgreSQL's server refuses to run as root).
  struct RunAs {
    uid_t uid;
    gid_t gid;
  };

  // For the next Start: stdin from this file instead of /dev/null (e.g. a
  // FIFO the test writes answers to), and these NAME=value variables added
  // to the test's environment.
  void set_stdin(std::string path) { stdin_path_ = std::move(path); }
  void set_env(std::vector<std::string> extra) {
    extra_env_ = std::move(extra);
  }

  // Starts `argv` (argv[0] is the binary's path) with stdin from /dev/null
  // and stdout+stderr appended to `log_path`, as `run_as` if given.
  absl::Status Start(const std::vector<std::string>& argv,
                     const std::string& log_path,
                     std::optional<RunAs> run_as = std::nullopt);

  // Waits until the log contains `text`. FAILED_PRECONDITION with the log
  // if the child exits first (its wait status is then in exit_status()),
  // DEADLINE_EXCEEDED with the log on timeout.
  absl::Status WaitForLog(const std::string& text, absl::Duration timeout);

  // Waits up to `timeout` for the child to exit; returns its wait status.
  absl::StatusOr<int> Wait(absl::Duration timeout);
  // Sends `signal`, then Wait(timeout).
  absl::StatusOr<int> SignalAndWait(int signal, absl::Duration timeout);
  // SIGKILL and reap, if running. Safe to call at any time.
  void Kill();

  bool running() const { return pid_ > 0; }
  pid_t pid() const { return pid_; }
  int exit_status() const { return exit_status_; }
  const std::string& log_path() const { return log_path_; }
  std::string log() const { return ReadFile(log_path_); }

 private:
  pid_t pid_ = -1;
  int exit_status_ = 0;
  std::string log_path_;
  std::string stdin_path_ = "/dev/null";
  std::vector<std::string> extra_env_;
};

}  // namespace bitewise::testing

#endif  // BITEWISE_TESTS_COMMON_CHILD_PROCESS_H_
