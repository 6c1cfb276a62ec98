// bitewise-admin: moves users between BanditService stores (SQLite files
// and PostgreSQL databases), with the services on them stopped.
//
//   bitewise-admin copy --from=sqlite:old.db --to=sqlite:new.db
//   bitewise-admin copy --from=lab.db --to=postgresql://bitewise@db/facility
//   bitewise-admin copy --from=old.db --to=alice.db --user=alice   # export
//   bitewise-admin copy --from=alice.db --to=new.db --user=alice   # import
//   bitewise-admin verify --from=old.db --to=new.db [--user=alice]
//
// copy creates --to if it does not exist; verify compares every user (or
// one) field for field and the models rebuilt from both logs, prints what
// differs and exits 1 if anything does. Exit 2: bad usage or a store that
// cannot be opened or read.
#include <cstdio>
#include <memory>
#include <string>
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

int Run(const std::vector<char*>& args) {
  if (args.size() != 2 ||
      (std::string(args[1]) != "copy" && std::string(args[1]) != "verify")) {
    std::fprintf(stderr,
                 "usage: bitewise-admin copy|verify --from=STORE "
                 "--to=STORE [--user=ID]\n");
    return 2;
  }
  const bool copy = std::string(args[1]) == "copy";
  absl::StatusOr<std::unique_ptr<EventStore>> from =
      OpenStore(absl::GetFlag(FLAGS_from), /*create=*/false);
  if (!from.ok()) {
    std::fprintf(stderr, "--from: %s\n", from.status().ToString().c_str());
    return 2;
  }
  absl::StatusOr<std::unique_ptr<EventStore>> to =
      OpenStore(absl::GetFlag(FLAGS_to), /*create=*/copy);
  if (!to.ok()) {
    std::fprintf(stderr, "--to: %s\n", to.status().ToString().c_str());
    return 2;
  }
  const std::string user = absl::GetFlag(FLAGS_user);
  if (copy) {
    absl::StatusOr<CopyReport> copied = CopyUsers(**from, **to, user);
    if (!copied.ok()) {
      std::fprintf(stderr, "copy: %s\n", copied.status().ToString().c_str());
      return 1;
    }
    std::printf("copied %lld users, %lld events\n",
                static_cast<long long>(copied->users),
                static_cast<long long>(copied->events));
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
      "%s: %lld users, %lld events compared; models within %.3g (relative)\n",
      verified->differences.empty() ? "equal" : "DIFFERENT",
      static_cast<long long>(verified->users),
      static_cast<long long>(verified->events),
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
