// SqliteEventStore: opening the file, health and the write probe, and the
// group commit of the hot path. The roles: sqlite_event_log.cc,
// sqlite_checkpoints.cc, sqlite_pools_audit.cc.
#include "services/bandit/store/sqlite_event_store.h"

#include <fcntl.h>
#include <sqlite3.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <utility>

#include "absl/strings/ascii.h"
#include "absl/strings/escaping.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "absl/strings/string_view.h"
#include "absl/time/clock.h"
#include "services/bandit/store/context_file.h"
#include "services/bandit/store/event_checksum.h"
#include "services/bandit/store/sqlite_helpers.h"
#include "services/bandit/store/sqlite_rows.h"
#include "services/bandit/store/sqlite_schema.h"
#include "services/bandit/store/store_rows.h"
#include "services/common/status_macros.h"

namespace bitewise::bandit {
namespace {

using sqlite::CheckIntegrity;
using sqlite::InitializeDatabase;
using sqlite::LockStoreFile;

// bitewise_context(offset, length): the bytes there in the store's contexts
// file (sqlite3_user_data); NULL without one. A short read returns what
// there is, and the event's checksum then names it.
void ReadContextFunction(sqlite3_context* call, int argc,
                         sqlite3_value** argv) {
  const auto* contexts =
      static_cast<const ContextFile*>(sqlite3_user_data(call));
  if (contexts == nullptr || argc != 2) {
    sqlite3_result_null(call);
    return;
  }
  const std::string bytes = contexts->Read(sqlite3_value_int64(argv[0]),
                                           sqlite3_value_int64(argv[1]));
  sqlite3_result_blob64(call, bytes.data(), bytes.size(), SQLITE_TRANSIENT);
}

// Where the rows point in the contexts file: every (offset, length), and
// the end of the furthest. Reads every event's location (the whole log).
struct ContextRanges {
  std::vector<std::pair<int64_t, int64_t>> live;
  int64_t referenced_end = 0;
};

absl::StatusOr<ContextRanges> ReadContextRanges(sqlite3* db,
                                                const std::string& op) {
  ContextRanges ranges;
  ASSIGN_OR_RETURN(Statement st,
                   Statement::Prepare(db,
                                      "SELECT context_offset, context_bytes "
                                      "FROM events WHERE context_offset IS "
                                      "NOT NULL",
                                      op));
  while (true) {
    ASSIGN_OR_RETURN(const bool row, st.Step());
    if (!row) break;
    ranges.live.emplace_back(st.Int64(0), st.Int64(1));
    ranges.referenced_end =
        std::max(ranges.referenced_end, st.Int64(0) + st.Int64(1));
  }
  return ranges;
}

// The end of the newest event's context in the contexts file (0 when no
// row points there): contexts are appended in the order their events are
// numbered (both under the store's lock), so it is the furthest, found
// from the end of the log without reading the rest.
absl::StatusOr<int64_t> NewestContextEnd(sqlite3* db, const std::string& op) {
  ASSIGN_OR_RETURN(Statement st,
                   Statement::Prepare(db,
                                      "SELECT context_offset + context_bytes "
                                      "FROM events WHERE context_offset IS "
                                      "NOT NULL ORDER BY event_id DESC LIMIT 1",
                                      op));
  ASSIGN_OR_RETURN(const bool row, st.Step());
  return row ? st.Int64(0) : 0;
}

void EraseUnreferenced(ContextFile& contexts, ContextRanges ranges) {
  if (const absl::Status erased = contexts.EraseAllBut(std::move(ranges.live));
      !erased.ok()) {
    std::fprintf(stderr,
                 "bitewise-bandit: unreferenced contexts were not erased from "
                 "the contexts file (they stay until the next start): %s\n",
                 erased.ToString().c_str());
  }
}

// The database's contexts file (named from the real database file,
// `files_base`), opened knowing how far its rows point (so a
// missing file is told from one never used). With `check`, what no row
// points at is erased now (reading every event's location); otherwise by
// RunDeferredChecks.
absl::StatusOr<std::unique_ptr<ContextFile>> OpenContextFile(
    sqlite3* db, const std::string& path, const std::string& files_base,
    bool check) {
  const std::string op = absl::StrCat("opening ", path);
  std::string contexts_path = files_base + ".contexts";
  // Before 2026-12-07 the name came from --db as given: a link's store kept
  // "<link>.contexts". It is used where it is and the real name's is not
  // (the lock, named from the real file, keeps one process on the store);
  // with both there, which holds the contexts is not guessed.
  std::error_code error;
  const std::string old_path = path + ".contexts";
  if (files_base != path && std::filesystem::exists(old_path, error) &&
      !std::filesystem::equivalent(old_path, contexts_path, error)) {
    if (std::filesystem::exists(contexts_path, error)) {
      return absl::FailedPreconditionError(absl::StrCat(
          path, " is a link to ", files_base, ", and both ", old_path, " and ",
          contexts_path,
          " exist: keep the one this database's contexts are in (the larger, "
          "as a rule; CheckStore tells) under the second name, and move the "
          "other away"));
    }
    contexts_path = old_path;
  }
  if (!check) {
    ASSIGN_OR_RETURN(const int64_t end, NewestContextEnd(db, op));
    return ContextFile::Open(contexts_path, end);
  }
  ASSIGN_OR_RETURN(ContextRanges ranges, ReadContextRanges(db, op));
  ASSIGN_OR_RETURN(std::unique_ptr<ContextFile> contexts,
                   ContextFile::Open(contexts_path, ranges.referenced_end));
  EraseUnreferenced(*contexts, std::move(ranges));
  return contexts;
}

}  // namespace

absl::StatusOr<std::unique_ptr<SqliteEventStore>> SqliteEventStore::Open(
    const SqliteStoreOptions& options) {
  if (options.path.empty()) {
    return absl::InvalidArgumentError("SqliteStoreOptions.path is empty");
  }
  // A missing or empty file is a new store only when asked for: a mistyped
  // --db must not silently start everyone from scratch.
  bool creating = false;
  if (options.path != ":memory:") {
    struct stat existing {};
    const bool exists = stat(options.path.c_str(), &existing) == 0;
    creating = !exists || existing.st_size == 0;
    if (creating && !options.create_if_missing) {
      return absl::FailedPreconditionError(absl::StrCat(
          "database \"", options.path, "\" ",
          exists ? "is an empty file" : "does not exist",
          "; pass --create to make a new store there (or correct --db)"));
    }
  }
  sqlite3* raw = nullptr;
  // NOMUTEX: the store's own mutex already serialises use of the connection.
  // A new file gets owner-only permissions: it holds health data.
  const mode_t previous_umask = creating ? umask(0077) : 0;
  const int rc = sqlite3_open_v2(
      options.path.c_str(), &raw,
      SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_NOMUTEX,
      nullptr);
  if (creating) umask(previous_umask);
  // SQLite allocates a handle even when opening fails; it must be closed.
  std::unique_ptr<sqlite3, SqliteCloser> db(raw);
  if (rc != SQLITE_OK) {
    return SqliteError(db.get(), rc, absl::StrCat("opening ", options.path));
  }
  sqlite3_extended_result_codes(db.get(), 1);
  const int64_t timeout_ms =
      std::clamp<int64_t>(absl::ToInt64Milliseconds(options.busy_timeout), 0,
                          std::numeric_limits<int>::max());
  sqlite3_busy_timeout(db.get(), static_cast<int>(timeout_ms));
  // One process per file: a second one would serve models that miss the
  // first one's updates.
  // Named from the real file, so that a link to it is the same store.
  const std::string files_base = sqlite::StoreFilesBase(options.path);
  ASSIGN_OR_RETURN(const int lock_fd, LockStoreFile(options.path, files_base));
  // A private store is as small as a test makes it: checked now.
  const bool check_now = options.check_at_open || options.path == ":memory:";
  absl::Status ready = InitializeDatabase(db.get(), options);
  if (ready.ok() && check_now) ready = CheckIntegrity(db.get(), options.path);
  std::unique_ptr<ContextFile> contexts;
  if (ready.ok() && options.path != ":memory:") {
    absl::StatusOr<std::unique_ptr<ContextFile>> opened =
        OpenContextFile(db.get(), options.path, files_base, check_now);
    ready = opened.status();
    if (ready.ok()) contexts = *std::move(opened);
  }
  if (ready.ok()) {
    const int rc = sqlite3_create_function_v2(
        db.get(), "bitewise_context", 2, SQLITE_UTF8, contexts.get(),
        &ReadContextFunction, nullptr, nullptr, nullptr);
    if (rc != SQLITE_OK) {
      ready = SqliteError(db.get(), rc, absl::StrCat("opening ", options.path));
    }
  }
  struct stat file {};
  if (ready.ok() && options.path != ":memory:" &&
      stat(options.path.c_str(), &file) != 0) {
    ready = absl::UnavailableError(
        absl::StrCat("cannot stat ", options.path, ": ", std::strerror(errno)));
  }
  if (!ready.ok()) {
    if (lock_fd >= 0) close(lock_fd);
    return ready;
  }
  std::unique_ptr<SqliteEventStore> store(new SqliteEventStore(
      db.release(), lock_fd, options.path, static_cast<uint64_t>(file.st_dev),
      static_cast<uint64_t>(file.st_ino), std::move(contexts),
      options.context_file_min_bytes, options.synchronous_full, !check_now));
  store->busy_timeout_ms_ = static_cast<int>(timeout_ms);
  return store;
}

SqliteEventStore::SqliteEventStore(sqlite3* db, int lock_fd, std::string path,
                                   uint64_t device, uint64_t inode,
                                   std::unique_ptr<ContextFile> contexts,
                                   int64_t context_file_min_bytes,
                                   bool synchronous_full, bool checks_deferred)
    : checks_deferred_(checks_deferred),
      db_(db),
      statements_(std::make_unique<sqlite::StatementCache>(db)),
      contexts_(std::move(contexts)),
      context_file_min_bytes_(context_file_min_bytes),
      synchronous_full_(synchronous_full),
      lock_fd_(lock_fd),
      path_(std::move(path)),
      device_(device),
      inode_(inode) {}

absl::Status SqliteEventStore::CheckHealth() {
  if (path_ == ":memory:") return absl::OkStatus();
  struct stat file {};
  if (stat(path_.c_str(), &file) != 0 ||
      static_cast<uint64_t>(file.st_dev) != device_ ||
      static_cast<uint64_t>(file.st_ino) != inode_) {
    return absl::FailedPreconditionError(absl::StrCat(
        "the database file ", path_,
        " was removed or replaced while the service had it open; writes "
        "would be lost at the next start. Restore it and restart the "
        "service"));
  }
  if (contexts_ != nullptr &&
      (stat(contexts_->path().c_str(), &file) != 0 ||
       static_cast<uint64_t>(file.st_dev) != contexts_->device() ||
       static_cast<uint64_t>(file.st_ino) != contexts_->inode())) {
    return absl::FailedPreconditionError(absl::StrCat(
        "the contexts file ", contexts_->path(),
        " was removed or replaced while the service had it open; the "
        "contexts written since would be lost at the next start. Restore "
        "it and restart the service"));
  }
  return absl::OkStatus();
}

absl::Status SqliteEventStore::ProbeWrite() {
  RETURN_IF_ERROR(CheckHealth());
  absl::MutexLock lock(&mu_);
  if (contexts_ != nullptr) RETURN_IF_ERROR(contexts_->Probe());
  // A lock another program holds is not waited for here: the probe runs
  // under mu_, which every read takes too.
  sqlite3_busy_timeout(db_, 0);
  absl::StatusOr<Transaction> begun =
      Transaction::Begin(db_, Transaction::Kind::kWrite, "write probe");
  sqlite3_busy_timeout(db_, busy_timeout_ms_);
  ASSIGN_OR_RETURN(Transaction txn, std::move(begun));
  RETURN_IF_ERROR(Exec(
      db_,
      absl::StrCat("PRAGMA user_version = ", sqlite::kSchemaVersion).c_str(),
      "write probe"));
  return txn.Commit();
}

absl::Status SqliteEventStore::RunDeferredChecks() {
  if (!checks_deferred_.exchange(false)) return absl::OkStatus();
  // The integrity check reads one snapshot on a connection of its own, so
  // the service's calls go on meanwhile (WAL: readers never wait).
  {
    sqlite3* raw = nullptr;
    const int rc =
        sqlite3_open_v2(path_.c_str(), &raw,
                        SQLITE_OPEN_READONLY | SQLITE_OPEN_NOMUTEX, nullptr);
    std::unique_ptr<sqlite3, SqliteCloser> reader(raw);
    if (rc != SQLITE_OK) {
      return SqliteError(reader.get(), rc,
                         absl::StrCat("checking the integrity of ", path_));
    }
    RETURN_IF_ERROR(CheckIntegrity(reader.get(), path_));
  }
  if (contexts_ == nullptr) return absl::OkStatus();
  absl::MutexLock lock(&mu_);
  ASSIGN_OR_RETURN(
      ContextRanges ranges,
      ReadContextRanges(db_, absl::StrCat("checking the contexts of ", path_)));
  contexts_->ExtendTo(ranges.referenced_end);
  EraseUnreferenced(*contexts_, std::move(ranges));
  return absl::OkStatus();
}

SqliteEventStore::~SqliteEventStore() {
  // The cached statements first, so the connection really closes (its last
  // checkpoint done) before the lock file is released.
  statements_.reset();
  sqlite3_close_v2(db_);
  if (lock_fd_ >= 0) close(lock_fd_);  // releases the lock
}

struct SqliteEventStore::QueuedWrite {
  absl::FunctionRef<absl::Status()> apply;
  absl::Status status;
  bool done = false;
};

namespace {

struct GroupWait {
  const bool* done;
  const bool* committing;
};

bool MayProceed(GroupWait* wait) { return *wait->done || !*wait->committing; }

}  // namespace

absl::Status SqliteEventStore::RunInGroup(
    absl::FunctionRef<absl::Status()> apply) {
  QueuedWrite write{apply, absl::OkStatus(), false};
  std::vector<QueuedWrite*> group;
  {
    absl::MutexLock lock(&queue_mu_);
    queue_.push_back(&write);
    // While another caller commits, it may take this write along; once it
    // is done, this one leads the next group with whatever has queued.
    GroupWait wait{&write.done, &committing_};
    queue_mu_.Await(absl::Condition(&MayProceed, &wait));
    if (write.done) return write.status;
    committing_ = true;
    group.swap(queue_);
  }
  CommitGroup(group);
  {
    absl::MutexLock lock(&queue_mu_);
    for (QueuedWrite* queued : group) queued->done = true;
    committing_ = false;
  }
  return write.status;
}

void SqliteEventStore::CommitGroup(const std::vector<QueuedWrite*>& group) {
  const absl::Time start = absl::Now();
  auto fail_all = [&](const absl::Status& status) {
    for (QueuedWrite* queued : group) queued->status = status;
  };
  {
    absl::MutexLock lock(&mu_);
    absl::StatusOr<Transaction> txn =
        Transaction::Begin(db_, Transaction::Kind::kWrite, "group commit");
    if (!txn.ok()) {
      fail_all(txn.status());
    } else {
      absl::Status failed;  // a step that failed the whole group
      for (QueuedWrite* queued : group) {
        failed = Exec(db_, "SAVEPOINT w", "group commit");
        if (!failed.ok()) break;
        queued->status = queued->apply();
        if (!queued->status.ok()) {
          if (sqlite3_get_autocommit(db_) != 0) {
            // SQLite rolled the whole transaction back itself (a full
            // disk, an I/O error): the group fails with this write's
            // error, which says what happened.
            failed = queued->status;
            break;
          }
          failed = Exec(db_, "ROLLBACK TO w", "group commit");
          if (!failed.ok()) break;
        }
        failed = Exec(db_, "RELEASE w", "group commit");
        if (!failed.ok()) break;
      }
      // The contexts the rows point at are on disk before the rows.
      if (failed.ok() && contexts_ != nullptr && contexts_->dirty()) {
        failed = contexts_->Sync();
      }
      if (!failed.ok()) {
        fail_all(failed);
      } else {
        const absl::Status committed = txn->Commit();
        // Nothing of the group is on disk: every write fails.
        for (QueuedWrite* queued : group) {
          if (!committed.ok() && queued->status.ok()) {
            queued->status = committed;
          }
        }
      }
    }
  }
  const double seconds = absl::ToDoubleSeconds(absl::Now() - start);
  if (commit_observer_) {
    commit_observer_(seconds, static_cast<int64_t>(group.size()));
  }
  absl::MutexLock stats(&stats_mu_);
  ++write_stats_.commits;
  write_stats_.committed_writes += static_cast<int64_t>(group.size());
  write_stats_.commit_seconds += seconds;
}

StoreWriteStats SqliteEventStore::write_stats() const {
  absl::MutexLock lock(&stats_mu_);
  return write_stats_;
}

}  // namespace bitewise::bandit
