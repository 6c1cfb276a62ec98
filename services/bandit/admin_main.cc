// bitewise-admin: moves users between BanditService stores (SQLite files
// and PostgreSQL databases), with the services on them stopped.
//
//   bitewise-admin copy --from=sqlite:old.db --to=sqlite:new.db
//   bitewise-admin copy --from=lab.db --to=postgresql://bitewise@db/facility
//   bitewise-admin copy --from=old.db --to=alice.db --user=alice   # export
//   bitewise-admin copy --from=alice.db --to=new.db --user=alice   # import
//   bitewise-admin verify --from=old.db --to=new.db [--user=alice]
//
// copy creates --to if it does not exist, and with every user copies the
// audit log too; verify compares every user (or one) field for field, the
// models rebuilt from both logs and (for every user) the audit log, prints
// what differs and exits 1 if anything does. Exit 2: bad usage, the same
// store twice, or a store that cannot be opened or compared; copy exits 1
// when a write or read fails part way (the user being copied is removed
// from --to again), and 128 + the signal when interrupted (130 for
// SIGINT, 143 for SIGTERM: the user being copied is removed, those before
// it stay whole; a second signal ends it at once). A mistyped flag
// exits 1 (Abseil's flag parser), before anything is opened.
#include <atomic>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "absl/flags/flag.h"
#include "absl/flags/parse.h"
#include "absl/flags/usage.h"
#include "absl/status/statusor.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/strip.h"
#include "services/bandit/store/open_store.h"
#include "services/bandit/store/store_copy.h"

ABSL_FLAG(std::string, from, "",
          "The store to read: sqlite:PATH, PATH or postgresql://...");
ABSL_FLAG(std::string, to, "",
          "The store to write (copy) or compare with (verify).");
ABSL_FLAG(std::string, user, "", "Only this user (empty: every user).");
ABSL_FLAG(double, model_tolerance, 1e-12,
          "verify: largest relative difference of the rebuilt models.");

namespace bitewise::bandit {
namespace {

absl::StatusOr<std::unique_ptr<EventStore>> OpenStore(const std::string& spec,
                                                      bool create) {
  if (spec.empty()) {
    return absl::InvalidArgumentError("--from and --to are required");
  }
  OpenStoreOptions options;
  options.create_if_missing = create;
  options.postgres_connections = 1;
  return OpenEventStore(spec, options);
}

// The signal that interrupted a copy (0: none). A second one is not
// caught: it ends the tool at once (a copy blocked on a hung server).
std::atomic<int> interrupted{0};

void OnSignal(int signal_number) {
  interrupted = signal_number;
  std::signal(signal_number, SIG_DFL);
}

// The file a sqlite spec names, resolved, or "" (PostgreSQL, or no file).
std::string SqliteFile(const std::string& spec) {
  if (IsPostgresSpec(spec)) return "";
  std::error_code error;
  const std::filesystem::path path = std::filesystem::canonical(
      std::string(absl::StripPrefix(spec, "sqlite:")), error);
  return error ? "" : path.string();
}

int Run(const std::vector<char*>& args) {
  if (args.size() != 2 ||
      (std::string(args[1]) != "copy" && std::string(args[1]) != "verify")) {
    std::fprintf(stderr,
                 "usage: bitewise-admin copy|verify --from=STORE "
                 "--to=STORE [--user=ID]\n");
    return 2;
  }
  const bool copy = std::string(args[1]) == "copy";
  const std::string from_spec = absl::GetFlag(FLAGS_from);
  const std::string to_spec = absl::GetFlag(FLAGS_to);
  if (!from_spec.empty() && (from_spec == to_spec ||
                             (!SqliteFile(from_spec).empty() &&
                              SqliteFile(from_spec) == SqliteFile(to_spec)))) {
    std::fprintf(stderr, "--from and --to are the same store (%s)\n",
                 DescribeStoreSpec(from_spec).c_str());
    return 2;
  }
  // Stores read must exist (the store's own message would suggest the
  // service's --create and --db).
  for (const auto& [flag, spec] :
       {std::pair<const char*, std::string>{"--from", from_spec},
        {"--to", copy ? std::string() : to_spec}}) {
    if (!spec.empty() && !IsPostgresSpec(spec) &&
        !LooksLikeLibpqKeyValue(spec) && SqliteFile(spec).empty()) {
      std::fprintf(stderr, "%s: no store at \"%s\" (nothing to %s)\n", flag,
                   spec.c_str(), copy ? "copy" : "compare");
      return 2;
    }
  }
  absl::StatusOr<std::unique_ptr<EventStore>> from =
      OpenStore(from_spec, /*create=*/false);
  if (!from.ok()) {
    std::fprintf(stderr, "--from: %s\n", from.status().ToString().c_str());
    return 2;
  }
  absl::StatusOr<std::unique_ptr<EventStore>> to =
      OpenStore(to_spec, /*create=*/copy);
  if (!to.ok()) {
    std::fprintf(stderr, "--to: %s\n", to.status().ToString().c_str());
    return 2;
  }
  const std::string user = absl::GetFlag(FLAGS_user);
  if (copy) {
    // A copy cut short by Ctrl-C or a stop leaves no half-copied user.
    std::signal(SIGINT, OnSignal);
    std::signal(SIGTERM, OnSignal);
    absl::StatusOr<CopyReport> copied =
        CopyUsers(**from, **to, user, [] { return interrupted.load() != 0; });
    if (!copied.ok()) {
      std::fprintf(stderr, "copy: %s\n", copied.status().ToString().c_str());
      return absl::IsCancelled(copied.status()) ? 128 + interrupted.load() : 1;
    }
    std::printf("copied %lld users, %lld events, %lld audit entries\n",
                static_cast<long long>(copied->users),
                static_cast<long long>(copied->events),
                static_cast<long long>(copied->audit_entries));
    return 0;
  }
  absl::StatusOr<VerifyReport> verified =
      VerifyCopy(**from, **to, user, absl::GetFlag(FLAGS_model_tolerance));
  if (!verified.ok()) {
    std::fprintf(stderr, "verify: %s\n", verified.status().ToString().c_str());
    return 2;
  }
  for (const std::string& difference : verified->differences) {
    std::printf("%s\n", difference.c_str());
  }
  std::printf(
      "%s: %lld users, %lld events, %lld audit entries compared; models "
      "within %.3g (relative)\n",
      verified->differences.empty() ? "equal" : "DIFFERENT",
      static_cast<long long>(verified->users),
      static_cast<long long>(verified->events),
      static_cast<long long>(verified->audit_entries),
      verified->worst_model_difference);
  return verified->differences.empty() ? 0 : 1;
}

}  // namespace
}  // namespace bitewise::bandit

int main(int argc, char** argv) {
  absl::SetProgramUsageMessage(
      "bitewise-admin copy|verify --from=STORE --to=STORE [--user=ID]");
  return bitewise::bandit::Run(absl::ParseCommandLine(argc, argv));
}
