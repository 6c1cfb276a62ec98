// The bandit store's file: its schema and migrations, and the checks made
// when it is opened (internal to services/bandit/store).
//
// Schema versions: 1 events and users; 2 adds the users' population priors
// and the pools; 3 moves action names from JSON columns into the child
// tables user_actions and pool_actions, gives every event its checksums
// (event_checksum.h) and adds the audit log; 4 adds model checkpoints; 5
// moves the contexts into event_contexts; 6 lets a large context live in the
// contexts file beside the database (context_file.h). Older files are
// migrated in one transaction when opened; a newer file is refused
// untouched. New files have 1 KB pages.
#ifndef BITEWISE_SERVICES_BANDIT_STORE_SQLITE_SCHEMA_H_
#define BITEWISE_SERVICES_BANDIT_STORE_SQLITE_SCHEMA_H_

#include <sqlite3.h>

#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "services/bandit/store/sqlite_store_options.h"

namespace bitewise::bandit::sqlite {

inline constexpr int kSchemaVersion = 7;

// Checks that the file is a bitewise store (or empty), switches to WAL with
// foreign keys and the options' synchronous mode, then creates the schema or
// migrates an older one. FAILED_PRECONDITION naming the path for a foreign
// file, an unknown version, or a SQLite build without foreign keys;
// DATA_LOSS for unreadable version-2 action names.
absl::Status InitializeDatabase(sqlite3* db, const SqliteStoreOptions& options);

// Takes an exclusive advisory lock on "<path>.lock" (released by the kernel
// when the process ends, however it ends) and writes our pid into it.
// ":memory:" needs none (-1). FAILED_PRECONDITION naming the holder when
// another process has the store open; UNAVAILABLE if the lock file cannot be
// made.
//
// `real_path` is the file `path` names with every symbolic link resolved
// (StoreFilesBase): the lock and the contexts file are named from it, so a
// second name for the same file (a link) finds the same lock.
absl::StatusOr<int> LockStoreFile(const std::string& path,
                                  const std::string& real_path);

// The database file's name with its links resolved (the file need not exist
// yet: its directory's are); `path` itself for ":memory:", or when the
// name cannot be resolved (the open then fails naming `path`).
std::string StoreFilesBase(const std::string& path);

// PRAGMA integrity_check: DATA_LOSS naming the path and SQLite's first
// findings when the file's structure is damaged.
absl::Status CheckIntegrity(sqlite3* db, const std::string& path);

// SQLite's full integrity check: its findings (at most `max_findings`),
// none when the file is whole.
absl::StatusOr<std::vector<std::string>> IntegrityFindings(sqlite3* db,
                                                           int max_findings);

}  // namespace bitewise::bandit::sqlite

#endif  // BITEWISE_SERVICES_BANDIT_STORE_SQLITE_SCHEMA_H_
