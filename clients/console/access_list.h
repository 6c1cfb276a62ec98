// AccessList: who may use bitewise-console off loopback, and in which role.
// The access file has one credential per line,
//
//   NAME ROLE pbkdf2-sha256$ITERATIONS$SALT_HEX$HASH_HEX
//
// with ROLE caregiver (the table view and STOP) or researcher (the
// read-only views and STOP); '#' starts a comment. `bitewise-console
// --hash_password` prints the third field for a password read from standard
// input. Browsers send the name and password by HTTP Basic authentication,
// which the console only accepts over TLS off loopback.
//
// Thread-safe: Check may be called from many request threads; a verified
// password is remembered (as its SHA-256) so that PBKDF2 runs once per
// credential, not once per request. PBKDF2 runs for one password at a time,
// with at most kMaxWaitingChecks more waiting; beyond that Check refuses at
// once. So wrong passwords sent in bulk hold at most one core and a few
// request threads, and a person whose password is already verified (STOP
// above all) is answered without waiting behind them.
#ifndef BITEWISE_CLIENTS_CONSOLE_ACCESS_LIST_H_
#define BITEWISE_CLIENTS_CONSOLE_ACCESS_LIST_H_

#include <cstdint>
#include <map>
#include <set>
#include <string>

#include "absl/base/thread_annotations.h"
#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/synchronization/mutex.h"

namespace bitewise::console {

enum class Role { kLocal, kCaregiver, kResearcher };

const char* RoleName(Role role);

// "pbkdf2-sha256$ITERATIONS$SALT_HEX$HASH_HEX" of `password` with a fresh
// 16-byte random salt. INTERNAL if the system's random source fails.
absl::StatusOr<std::string> HashPassword(const std::string& password,
                                         int iterations = 200000);

class AccessList {
 public:
  // Errors name the file and line: FAILED_PRECONDITION when it cannot be
  // read; INVALID_ARGUMENT for a malformed line, an unknown role, a
  // repeated name, or a file with no credentials.
  static absl::StatusOr<AccessList> Load(const std::string& path);

  AccessList(const AccessList& other);

  // Checks of new passwords that may wait while one runs.
  static constexpr int kMaxWaitingChecks = 16;

  // The role of `name` if `password` is its password; UNAUTHENTICATED
  // (saying only that the name or password is wrong, after as much work
  // for a name that is not listed as for one that is) otherwise;
  // RESOURCE_EXHAUSTED when the password is not yet verified and one check
  // runs with kMaxWaitingChecks already waiting.
  absl::StatusOr<Role> Check(const std::string& name,
                             const std::string& password) const;

  int size() const { return static_cast<int>(entries_.size()); }
  // PBKDF2 derivations run so far (a name not listed costs one too).
  int64_t derivations() const {
    absl::MutexLock lock(&mu_);
    return derivations_;
  }

 private:
  struct Entry {
    Role role;
    int iterations;
    std::string salt;  // bytes
    std::string hash;  // bytes
  };
  AccessList() = default;
  bool NoCheckRunning() const ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_) {
    return checks_running_ == 0;
  }

  std::map<std::string, Entry> entries_;
  // What a name not in the file is checked against (and always fails):
  // the same work as a listed name's, so the time of a wrong answer does
  // not tell which names exist.
  Entry decoy_{Role::kCaregiver, 0, std::string(16, '\0'), std::string()};
  mutable absl::Mutex mu_;
  // SHA-256 of "name\0password" for passwords already verified.
  mutable std::set<std::string> verified_ ABSL_GUARDED_BY(mu_);
  // PBKDF2 checks running (0 or 1) and waiting to run.
  mutable int checks_running_ ABSL_GUARDED_BY(mu_) = 0;
  mutable int checks_waiting_ ABSL_GUARDED_BY(mu_) = 0;
  mutable int64_t derivations_ ABSL_GUARDED_BY(mu_) = 0;
};

}  // namespace bitewise::console

#endif  // BITEWISE_CLIENTS_CONSOLE_ACCESS_LIST_H_
