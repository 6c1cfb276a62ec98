// SqliteStoreOptions: how the SQLite store opens its file (the options
// both SqliteEventStore and the schema code read, apart from either).
#ifndef BITEWISE_SERVICES_BANDIT_STORE_SQLITE_STORE_OPTIONS_H_
#define BITEWISE_SERVICES_BANDIT_STORE_SQLITE_STORE_OPTIONS_H_

#include <cstdint>
#include <string>

#include "absl/time/time.h"

namespace bitewise::bandit {

struct SqliteStoreOptions {
  // The database file. Created, with the schema, if it does not exist; an
  // existing file must be a bitewise store of a schema version this build
  // knows. ":memory:" gives a private, non-durable store (tests only).
  std::string path;
  // true: synchronous=FULL, every commit is fsynced, so an acknowledged write
  // survives power loss as well as a crash of the process. false:
  // synchronous=NORMAL, which in WAL mode still survives kill -9 of the
  // process but may lose the last commits on power loss or an OS crash.
  bool synchronous_full = true;
  // How long an operation waits for a lock held by another process on the
  // same file before failing with UNAVAILABLE.
  absl::Duration busy_timeout = absl::Seconds(5);
  // Whether a path that does not exist (or an empty file) becomes a new
  // store, created with owner-only permissions. The service sets it only
  // with --create; otherwise Open is FAILED_PRECONDITION naming the path.
  bool create_if_missing = true;
  // Contexts of at least this many bytes (d >= 512 with the default) are
  // kept in the contexts file "<path>.contexts" (context_file.h), written
  // once, rather than in the database, where the write-ahead log writes
  // them twice; smaller ones stay in the database, which saves the file's
  // own sync in their commits. A ":memory:" store keeps every context.
  int64_t context_file_min_bytes = 4096;
  // true: Open runs SQLite's integrity check over the whole file and erases
  // the contexts file's unreferenced blocks before it returns. Both read
  // the whole store, so their time grows with it. false: Open reads only
  // the schema and the newest context's location, and RunDeferredChecks
  // does both later; the service runs them in the background once it is
  // SERVING, its writes waiting for them (FaultWatchStore).
  bool check_at_open = true;
};

}  // namespace bitewise::bandit

#endif  // BITEWISE_SERVICES_BANDIT_STORE_SQLITE_STORE_OPTIONS_H_
