// OpenEventStore: the one place a store location (--db, --from, --to)
// becomes an EventStore, so the service and bitewise-admin accept the same
// forms:
//   postgresql://... or postgres://...  the PostgreSQL store (libpq URI)
//   sqlite:PATH or PATH                 the SQLite store (a file)
#ifndef BITEWISE_SERVICES_BANDIT_STORE_OPEN_STORE_H_
#define BITEWISE_SERVICES_BANDIT_STORE_OPEN_STORE_H_

#include <memory>
#include <string>

#include "absl/status/statusor.h"
#include "absl/time/time.h"
#include "services/bandit/store/event_store.h"

namespace bitewise::bandit {

struct OpenStoreOptions {
  // Make a new store where there is none (a missing or empty SQLite file,
  // a PostgreSQL database without the bitewise tables).
  bool create_if_missing = false;
  // SQLite: fsync every commit (synchronous=FULL).
  bool sqlite_fsync = true;
  // PostgreSQL: connections kept open.
  int postgres_connections = 8;
  // PostgreSQL: how long a statement waits for the server's next bytes
  // (PostgresStoreOptions::response_timeout).
  absl::Duration postgres_response_timeout = absl::Seconds(30);
  // SQLite: open without reading the whole file, and run its integrity
  // check (and the contexts file's clean-up) in the background, writes
  // waiting for it (FaultWatchStore::StartDeferredChecks), so the time to
  // open does not grow with the file. The service sets it; tools check at
  // open.
  bool defer_full_check = false;
};

// Whether `spec` names a PostgreSQL store.
bool IsPostgresSpec(const std::string& spec);

// Whether `spec` looks like libpq's key=value form ("host=db dbname=x"),
// which OpenEventStore refuses without echoing it (it may hold a password).
bool LooksLikeLibpqKeyValue(const std::string& spec);

// The store at `spec`, opened (Open's errors of the store it names), and
// watched for write faults (FaultWatchStore: health reports a storage that
// refuses writes until a probe write succeeds).
// INVALID_ARGUMENT for an empty spec.
absl::StatusOr<std::unique_ptr<EventStore>> OpenEventStore(
    const std::string& spec, const OpenStoreOptions& options);

// `spec` as it may be logged: a PostgreSQL URI without its password (and
// its client key's passphrase); nothing of a key=value string.
std::string DescribeStoreSpec(const std::string& spec);

}  // namespace bitewise::bandit

#endif  // BITEWISE_SERVICES_BANDIT_STORE_OPEN_STORE_H_
