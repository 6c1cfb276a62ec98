#include "tests/common/child_process.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <grp.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"

namespace bitewise::testing {

absl::StatusOr<int> PickFreePort() {
  const int fd = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return absl::InternalError(std::strerror(errno));
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  addr.sin_port = 0;
  socklen_t len = sizeof(addr);
  if (bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)) != 0 ||
      getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len) != 0) {
    const std::string error = std::strerror(errno);
    close(fd);
    return absl::InternalError(absl::StrCat("picking a port: ", error));
  }
  close(fd);
  return static_cast<int>(ntohs(addr.sin_port));
}

std::string ReadFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream contents;
  contents << in.rdbuf();
  return contents.str();
}

std::string DescribeWaitStatus(int status) {
  if (WIFEXITED(status)) return absl::StrCat("exit ", WEXITSTATUS(status));
  if (WIFSIGNALED(status)) {
    return absl::StrCat("killed by signal ", WTERMSIG(status));
  }
  return absl::StrCat("wait status ", status);
}

absl::Status ChildProcess::Start(const std::vector<std::string>& args,
                                 const std::string& log_path,
                                 std::optional<RunAs> run_as) {
  if (pid_ > 0) return absl::FailedPreconditionError("already running");
  if (args.empty()) return absl::InvalidArgumentError("argv: empty");
  log_path_ = log_path;
  // Everything the child needs is prepared here: between fork and execv only
  // async-signal-safe calls are allowed (the test may have gRPC threads).
  std::vector<std::string> copy = args;
  std::vector<char*> argv;
  for (std::string& arg : copy) argv.push_back(arg.data());
  argv.push_back(nullptr);
  const int log_fd =
      open(log_path_.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
  if (log_fd < 0) {
    return absl::InternalError(
        absl::StrCat("open ", log_path_, ": ", std::strerror(errno)));
  }
  // O_RDWR: a FIFO opens at once, whether or not its writer is there yet.
  const int null_fd = open(stdin_path_.c_str(), O_RDWR | O_CLOEXEC);
  if (null_fd < 0) {
    close(log_fd);
    return absl::InternalError(
        absl::StrCat("open ", stdin_path_, ": ", std::strerror(errno)));
  }
  // The test's environment with the extra variables (later ones win).
  std::vector<std::string> env_copy;
  for (char** e = environ; *e != nullptr; ++e) {
    const std::string entry = *e;
    const std::string name = entry.substr(0, entry.find('='));
    bool replaced = false;
    for (const std::string& extra : extra_env_) {
      replaced = replaced || extra.substr(0, extra.find('=')) == name;
    }
    if (!replaced) env_copy.push_back(entry);
  }
  for (const std::string& extra : extra_env_) env_copy.push_back(extra);
  std::vector<char*> envp;
  for (std::string& entry : env_copy) envp.push_back(entry.data());
  envp.push_back(nullptr);
  const pid_t parent = getpid();
  const pid_t pid = fork();
  if (pid == 0) {
    // Credentials first: changing them clears the parent-death signal.
    if (run_as.has_value() &&
        (setgroups(0, nullptr) != 0 || setgid(run_as->gid) != 0 ||
         setuid(run_as->uid) != 0)) {
      static const char kMessage[] = "ChildProcess: cannot change user\n";
      (void)!write(STDERR_FILENO, kMessage, sizeof(kMessage) - 1);
      _exit(126);
    }
    // The other account may not be allowed into the test's working
    // directory (PostgreSQL's server changes back into it at start).
    if (run_as.has_value() && chdir("/") != 0) _exit(126);
    prctl(PR_SET_PDEATHSIG, SIGKILL);
    if (getppid() != parent) _exit(127);
    dup2(null_fd, STDIN_FILENO);
    dup2(log_fd, STDOUT_FILENO);
    dup2(log_fd, STDERR_FILENO);
    sigset_t none;
    sigemptyset(&none);
    sigprocmask(SIG_SETMASK, &none, nullptr);
    execve(argv[0], argv.data(), envp.data());
    static const char kMessage[] = "ChildProcess: execv failed\n";
    (void)!write(STDERR_FILENO, kMessage, sizeof(kMessage) - 1);
    _exit(127);
  }
  const int fork_errno = errno;
  close(log_fd);
  close(null_fd);
  if (pid < 0) {
    return absl::InternalError(
        absl::StrCat("fork: ", std::strerror(fork_errno)));
  }
  pid_ = pid;
  return absl::OkStatus();
}

absl::Status ChildProcess::WaitForLog(const std::string& text,
                                      absl::Duration timeout) {
  const absl::Time deadline = absl::Now() + timeout;
  while (true) {
    if (absl::StrContains(log(), text)) return absl::OkStatus();
    if (pid_ <= 0) {
      return absl::FailedPreconditionError(
          absl::StrCat("the process is not running; log:\n", log()));
    }
    int status = 0;
    if (waitpid(pid_, &status, WNOHANG) == pid_) {
      pid_ = -1;
      exit_status_ = status;
      if (absl::StrContains(log(), text)) return absl::OkStatus();
      return absl::FailedPreconditionError(
          absl::StrCat("the process ended (", DescribeWaitStatus(status),
                       ") before printing \"", text, "\"; log:\n", log()));
    }
    if (absl::Now() > deadline) {
      return absl::DeadlineExceededError(
          absl::StrCat("no \"", text, "\" within ",
                       absl::FormatDuration(timeout), "; log:\n", log()));
    }
    absl::SleepFor(absl::Milliseconds(5));
  }
}

absl::StatusOr<int> ChildProcess::Wait(absl::Duration timeout) {
  if (pid_ <= 0) return absl::FailedPreconditionError("not running");
  const absl::Time deadline = absl::Now() + timeout;
  while (true) {
    int status = 0;
    const pid_t reaped = waitpid(pid_, &status, WNOHANG);
    if (reaped == pid_) {
      pid_ = -1;
      exit_status_ = status;
      return status;
    }
    if (reaped < 0) {
      return absl::InternalError(
          absl::StrCat("waitpid: ", std::strerror(errno)));
    }
    if (absl::Now() > deadline) {
      return absl::DeadlineExceededError(
          absl::StrCat("still running after ", absl::FormatDuration(timeout)));
    }
    absl::SleepFor(absl::Milliseconds(5));
  }
}

absl::StatusOr<int> ChildProcess::SignalAndWait(int signal,
                                                absl::Duration timeout) {
  if (pid_ <= 0) return absl::FailedPreconditionError("not running");
  if (kill(pid_, signal) != 0) {
    return absl::InternalError(absl::StrCat("kill: ", std::strerror(errno)));
  }
  return Wait(timeout);
}

void ChildProcess::Kill() {
  if (pid_ <= 0) return;
  kill(pid_, SIGKILL);
  int status = 0;
  while (waitpid(pid_, &status, 0) < 0 && errno == EINTR) {
  }
  exit_status_ = status;
  pid_ = -1;
}

}  // namespace bitewise::testing
