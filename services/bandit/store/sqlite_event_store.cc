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
#include "services/bandit/store/sqlite_schema.h"
#include "services/bandit/store/store_rows.h"
#include "services/common/status_macros.h"

namespace bitewise::bandit {
namespace {

using sqlite::CheckIntegrity;
using sqlite::Exec;
using sqlite::InitializeDatabase;
using sqlite::LockStoreFile;
using sqlite::SqliteCloser;
using sqlite::SqliteError;
using sqlite::Statement;
using sqlite::Transaction;
using store_rows::ApproxBytes;
using store_rows::DecodePrior;
using store_rows::EncodeDoubles;
using store_rows::EncodePrior;
using store_rows::EventNotFound;
using store_rows::FromMicros;
using store_rows::ParsePageToken;
using store_rows::ToMicros;
using store_rows::UserNotFound;

constexpr char kUserColumns[] = R"sql(
SELECT u.user_id, u.learner, u.strategy, u.alpha, u.lambda_c, u.lambda_p,
       u.epsilon, u.importance_weighting, u.context_dim, u.posthoc_dim,
       u.seed, u.created_at_us, u.model_version,
       (SELECT COUNT(*) FROM events e
        WHERE e.user_id = u.user_id AND e.completed = 0),
       u.prior
FROM users u
)sql";

// LEFT JOIN: an event whose context row is missing reads with none, and
// its selection checksum then fails (DATA_LOSS) rather than the event
// silently vanishing from the log.
// A context kept in the contexts file is read from there
// (bitewise_context, registered at Open).
constexpr char kEventColumns[] = R"sql(
SELECT event_id, user_id, meal_id, item_label,
       CASE WHEN context_offset IS NULL THEN context
            ELSE bitewise_context(context_offset, context_bytes) END,
       action, propensity, selected_at_us, completed, loss, posthoc, weight,
       model_version, updated_at_us, selection_checksum, outcome_checksum
FROM events LEFT JOIN event_contexts USING (event_id)
)sql";

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

// The action names of one user or pool, stored one row per action in
// `table` (user_actions, pool_actions) under `key_column`.
absl::Status WriteActionNames(sqlite3* db, const char* table,
                              const char* key_column, absl::string_view key,
                              const std::vector<std::string>& names,
                              absl::string_view op) {
  for (size_t i = 0; i < names.size(); ++i) {
    ASSIGN_OR_RETURN(
        Statement row,
        Statement::Prepare(db,
                           absl::StrCat("INSERT INTO ", table, " (", key_column,
                                        ", action, name) VALUES (?1, ?2, ?3)"),
                           op));
    row.BindText(1, key);
    row.BindInt64(2, static_cast<int64_t>(i));
    row.BindText(3, names[i]);
    RETURN_IF_ERROR(row.Run());
  }
  return absl::OkStatus();
}

// Reads them back in action order; DATA_LOSS unless the actions are
// 0, 1, ... with at least one.
absl::StatusOr<std::vector<std::string>> ReadActionNames(
    sqlite3* db, const char* table, const char* key_column,
    absl::string_view key, absl::string_view what, absl::string_view op) {
  ASSIGN_OR_RETURN(Statement st,
                   Statement::Prepare(db,
                                      absl::StrCat("SELECT action, name FROM ",
                                                   table, " WHERE ", key_column,
                                                   " = ?1 ORDER BY action"),
                                      op));
  st.BindText(1, key);
  store_rows::ActionNamesReader names(what, table);
  while (true) {
    ASSIGN_OR_RETURN(const bool row, st.Step());
    if (!row) break;
    RETURN_IF_ERROR(names.Add(st.Int64(0), st.Text(1)));
  }
  return names.Take();
}

// Reads a row selected with kUserColumns (and its action names).
absl::StatusOr<UserRecord> ReadUser(sqlite3* db, Statement& st) {
  return store_rows::ReadUserRow(
      st, [db](const std::string& user_id, const std::string& what) {
        return ReadActionNames(db, "user_actions", "user_id", user_id, what,
                               "reading action names");
      });
}

// Reads a row selected with kEventColumns.
absl::StatusOr<EventRecord> ReadEvent(Statement& st) {
  return store_rows::ReadEventRow(st);
}

// Sets synchronous = FULL for its lifetime (from NORMAL), so the
// transaction it spans is fsynced at its commit. SQLite allows the change
// only outside a transaction: construct it before the transaction begins.
class DurableCommit {
 public:
  DurableCommit(sqlite3* db, bool needed) : db_(needed ? db : nullptr) {
    if (db_ != nullptr) {
      status_ = Exec(db_, "PRAGMA synchronous = FULL", "a durable commit");
    }
  }
  ~DurableCommit() {
    if (db_ != nullptr && status_.ok()) {
      const absl::Status restored =
          Exec(db_, "PRAGMA synchronous = NORMAL", "a durable commit");
      if (!restored.ok()) {
        std::fprintf(stderr, "bitewise-bandit: %s\n",
                     restored.ToString().c_str());
      }
    }
  }
  DurableCommit(const DurableCommit&) = delete;
  DurableCommit& operator=(const DurableCommit&) = delete;

  // Not OK if FULL could not be set: the caller must not go on.
  const absl::Status& status() const { return status_; }

 private:
  sqlite3* const db_;
  absl::Status status_;
};

// The database's contexts file, opened knowing which ranges its rows point
// at (so a missing file is told from one never used, and what no row
// points at is erased).
absl::StatusOr<std::unique_ptr<ContextFile>> OpenContextFile(
    sqlite3* db, const std::string& path) {
  const std::string op = absl::StrCat("opening ", path);
  std::vector<std::pair<int64_t, int64_t>> live;
  int64_t referenced_end = 0;
  {
    ASSIGN_OR_RETURN(Statement st,
                     Statement::Prepare(db,
                                        "SELECT context_offset, context_bytes "
                                        "FROM events WHERE context_offset IS "
                                        "NOT NULL",
                                        op));
    while (true) {
      ASSIGN_OR_RETURN(const bool row, st.Step());
      if (!row) break;
      live.emplace_back(st.Int64(0), st.Int64(1));
      referenced_end = std::max(referenced_end, st.Int64(0) + st.Int64(1));
    }
  }
  ASSIGN_OR_RETURN(std::unique_ptr<ContextFile> contexts,
                   ContextFile::Open(path + ".contexts", referenced_end));
  if (const absl::Status erased = contexts->EraseAllBut(std::move(live));
      !erased.ok()) {
    std::fprintf(stderr,
                 "bitewise-bandit: unreferenced contexts were not erased from "
                 "the contexts file (they stay until the next start): %s\n",
                 erased.ToString().c_str());
  }
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
  ASSIGN_OR_RETURN(const int lock_fd, LockStoreFile(options.path));
  absl::Status ready = InitializeDatabase(db.get(), options);
  if (ready.ok()) ready = CheckIntegrity(db.get(), options.path);
  std::unique_ptr<ContextFile> contexts;
  if (ready.ok() && options.path != ":memory:") {
    absl::StatusOr<std::unique_ptr<ContextFile>> opened =
        OpenContextFile(db.get(), options.path);
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
  return std::unique_ptr<SqliteEventStore>(new SqliteEventStore(
      db.release(), lock_fd, options.path, static_cast<uint64_t>(file.st_dev),
      static_cast<uint64_t>(file.st_ino), std::move(contexts),
      options.context_file_min_bytes, options.synchronous_full));
}

SqliteEventStore::SqliteEventStore(sqlite3* db, int lock_fd, std::string path,
                                   uint64_t device, uint64_t inode,
                                   std::unique_ptr<ContextFile> contexts,
                                   int64_t context_file_min_bytes,
                                   bool synchronous_full)
    : db_(db),
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
  ASSIGN_OR_RETURN(Transaction txn, Transaction::Begin(
                                        db_, Transaction::Kind::kWrite,
                                        "write probe"));
  RETURN_IF_ERROR(Exec(
      db_,
      absl::StrCat("PRAGMA user_version = ", sqlite::kSchemaVersion).c_str(),
      "write probe"));
  return txn.Commit();
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

absl::Status SqliteEventStore::CreateUser(const UserRecord& user) {
  RETURN_IF_ERROR(CheckHealth());
  if (user.user_id.empty()) {
    return absl::InvalidArgumentError("user_id must not be empty");
  }
  RETURN_IF_ERROR(ValidateConfig(user.config));
  const BanditConfig& c = user.config;
  absl::MutexLock lock(&mu_);
  ASSIGN_OR_RETURN(
      Transaction txn,
      Transaction::Begin(db_, Transaction::Kind::kWrite, "CreateUser"));
  // model_version and pending_events describe stored events, of which a new
  // user has none; the caller's values are ignored.
  ASSIGN_OR_RETURN(
      Statement st,
      Statement::Prepare(
          db_,
          "INSERT INTO users (user_id, learner, strategy, alpha, lambda_c, "
          "lambda_p, epsilon, importance_weighting, context_dim, posthoc_dim, "
          "seed, created_at_us, model_version, prior) "
          "VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, 0, "
          "?13) ON CONFLICT (user_id) DO NOTHING RETURNING user_id",
          "CreateUser"));
  st.BindText(1, user.user_id);
  st.BindInt64(2, static_cast<int64_t>(c.learner));
  st.BindInt64(3, static_cast<int64_t>(c.strategy));
  st.BindDouble(4, c.alpha);
  st.BindDouble(5, c.lambda_c);
  st.BindDouble(6, c.lambda_p);
  st.BindDouble(7, c.epsilon);
  st.BindInt64(8, c.importance_weighting ? 1 : 0);
  st.BindInt64(9, c.context_dim);
  st.BindInt64(10, c.posthoc_dim);
  st.BindInt64(11, static_cast<int64_t>(c.seed));
  st.BindInt64(12, ToMicros(user.created_at));
  const std::string prior =
      c.prior.enabled() ? EncodePrior(c.prior) : std::string();
  if (c.prior.enabled()) st.BindBlob(13, prior);  // else NULL
  ASSIGN_OR_RETURN(const bool inserted, st.Step());
  RETURN_IF_ERROR(st.Run());
  if (!inserted) {
    return absl::AlreadyExistsError(
        absl::StrCat("user \"", user.user_id, "\" already exists"));
  }
  RETURN_IF_ERROR(WriteActionNames(db_, "user_actions", "user_id", user.user_id,
                                   c.action_names, "CreateUser"));
  return txn.Commit();
}

absl::StatusOr<UserRecord> SqliteEventStore::GetUserLocked(
    const std::string& user_id) {
  ASSIGN_OR_RETURN(
      Statement st,
      Statement::Prepare(
          db_, absl::StrCat(kUserColumns, "WHERE u.user_id = ?1"), "GetUser"));
  st.BindText(1, user_id);
  ASSIGN_OR_RETURN(const bool row, st.Step());
  if (!row) return UserNotFound(user_id);
  return ReadUser(db_, st);
}

absl::StatusOr<UserRecord> SqliteEventStore::GetUser(
    const std::string& user_id) {
  absl::MutexLock lock(&mu_);
  return GetUserLocked(user_id);
}

absl::StatusOr<PageResult<UserRecord>> SqliteEventStore::ListUsers(
    const Page& page) {
  store_rows::PageBuilder<UserRecord> out(
      page, 'u', [](const UserRecord& user) { return user.user_id; });
  std::string after;
  if (!page.page_token.empty()) {
    ASSIGN_OR_RETURN(after, ParsePageToken(page.page_token, 'u'));
  }
  absl::MutexLock lock(&mu_);
  ASSIGN_OR_RETURN(
      Statement st,
      Statement::Prepare(
          db_,
          absl::StrCat(kUserColumns,
                       page.page_token.empty() ? "" : "WHERE u.user_id > ?2 ",
                       "ORDER BY u.user_id LIMIT ?1"),
          "ListUsers"));
  // One extra row says whether another page exists.
  st.BindInt64(1, out.page_size() + 1);
  if (!page.page_token.empty()) st.BindText(2, after);
  while (true) {
    ASSIGN_OR_RETURN(const bool row, st.Step());
    if (!row || !out.Room()) break;
    ASSIGN_OR_RETURN(UserRecord user, ReadUser(db_, st));
    const int64_t bytes = ApproxBytes(user);
    if (!out.Add(std::move(user), bytes)) break;
  }
  return out.Take();
}

absl::Status SqliteEventStore::DeleteUser(const std::string& user_id) {
  RETURN_IF_ERROR(CheckHealth());
  absl::MutexLock lock(&mu_);
  // The deletion is on disk before the contexts are erased, whatever the
  // store's synchronous mode: otherwise a power loss could bring the
  // events back without them.
  const DurableCommit durable(db_, !synchronous_full_);
  RETURN_IF_ERROR(durable.status());
  ASSIGN_OR_RETURN(
      Transaction txn,
      Transaction::Begin(db_, Transaction::Kind::kWrite, "DeleteUser"));
  ASSIGN_OR_RETURN(const auto ranges, ContextRangesLocked(user_id));
  {
    // The user's events go with it through ON DELETE CASCADE.
    ASSIGN_OR_RETURN(Statement st,
                     Statement::Prepare(db_,
                                        "DELETE FROM users WHERE user_id = ?1 "
                                        "RETURNING user_id",
                                        "DeleteUser"));
    st.BindText(1, user_id);
    ASSIGN_OR_RETURN(const bool deleted, st.Step());
    RETURN_IF_ERROR(st.Run());
    if (!deleted) return UserNotFound(user_id);
  }
  RETURN_IF_ERROR(txn.Commit());
  EraseContexts(ranges);
  return absl::OkStatus();
}

absl::StatusOr<std::vector<std::pair<int64_t, int64_t>>>
SqliteEventStore::ContextRangesLocked(const std::string& user_id) {
  std::vector<std::pair<int64_t, int64_t>> ranges;
  if (contexts_ == nullptr) return ranges;
  ASSIGN_OR_RETURN(Statement st,
                   Statement::Prepare(db_,
                                      "SELECT context_offset, context_bytes "
                                      "FROM events WHERE user_id = ?1 AND "
                                      "context_offset IS NOT NULL",
                                      "reading where contexts are"));
  st.BindText(1, user_id);
  while (true) {
    ASSIGN_OR_RETURN(const bool row, st.Step());
    if (!row) break;
    ranges.emplace_back(st.Int64(0), st.Int64(1));
  }
  return ranges;
}

void SqliteEventStore::EraseContexts(
    const std::vector<std::pair<int64_t, int64_t>>& ranges) {
  if (contexts_ == nullptr) return;
  if (const absl::Status erased = contexts_->Erase(ranges); !erased.ok()) {
    std::fprintf(stderr,
                 "bitewise-bandit: deleted events' contexts were not erased "
                 "from the contexts file (they stay, unreferenced): %s\n",
                 erased.ToString().c_str());
  }
}

absl::Status SqliteEventStore::ResetUser(const std::string& user_id) {
  RETURN_IF_ERROR(CheckHealth());
  absl::MutexLock lock(&mu_);
  // The deletion is on disk before the contexts are erased, whatever the
  // store's synchronous mode: otherwise a power loss could bring the
  // events back without them.
  const DurableCommit durable(db_, !synchronous_full_);
  RETURN_IF_ERROR(durable.status());
  ASSIGN_OR_RETURN(
      Transaction txn,
      Transaction::Begin(db_, Transaction::Kind::kWrite, "ResetUser"));
  {
    ASSIGN_OR_RETURN(Statement st,
                     Statement::Prepare(db_,
                                        "UPDATE users SET model_version = 0 "
                                        "WHERE user_id = ?1 RETURNING user_id",
                                        "ResetUser"));
    st.BindText(1, user_id);
    ASSIGN_OR_RETURN(const bool found, st.Step());
    RETURN_IF_ERROR(st.Run());
    if (!found) return UserNotFound(user_id);
  }
  ASSIGN_OR_RETURN(const auto ranges, ContextRangesLocked(user_id));
  {
    ASSIGN_OR_RETURN(
        Statement st,
        Statement::Prepare(db_, "DELETE FROM events WHERE user_id = ?1",
                           "ResetUser"));
    st.BindText(1, user_id);
    RETURN_IF_ERROR(st.Run());
  }
  RETURN_IF_ERROR(DeleteCheckpointLocked(user_id));
  RETURN_IF_ERROR(txn.Commit());
  EraseContexts(ranges);
  return absl::OkStatus();
}

absl::StatusOr<int64_t> SqliteEventStore::AppendPending(
    const EventRecord& event) {
  RETURN_IF_ERROR(CheckHealth());
  if (std::isnan(event.propensity)) {
    return absl::InvalidArgumentError("propensity must not be NaN");
  }
  const std::string context = EncodeDoubles(event.context);
  const int64_t checksum = SelectionChecksum(
      event.user_id, event.meal_id, event.item_label, context, event.action,
      event.propensity, ToMicros(event.selected_at));
  const absl::Time start = absl::Now();
  int64_t event_id = 0;
  const bool in_file =
      contexts_ != nullptr &&
      static_cast<int64_t>(context.size()) >= context_file_min_bytes_;
  RETURN_IF_ERROR(RunInGroup([&]() ABSL_NO_THREAD_SAFETY_ANALYSIS {
    // The row is inserted only if the user exists, and no row back means
    // it does not; then its context (both in this write's savepoint).
    {
      ASSIGN_OR_RETURN(
          Statement st,
          statements_->Get(
              "INSERT INTO events (user_id, meal_id, item_label, action, "
              "propensity, selected_at_us, completed, selection_checksum, "
              "context_offset, context_bytes) "
              "SELECT ?1, ?2, ?3, ?4, ?5, ?6, 0, ?7, ?8, ?9 "
              "WHERE EXISTS (SELECT 1 FROM users WHERE user_id = ?1) "
              "RETURNING event_id",
              "AppendPending"));
      st.BindText(1, event.user_id);
      st.BindText(2, event.meal_id);
      st.BindText(3, event.item_label);
      st.BindInt64(4, event.action);
      st.BindDouble(5, event.propensity);
      st.BindInt64(6, ToMicros(event.selected_at));
      st.BindInt64(7, checksum);
      if (in_file) {
        // Written now, synced before the group's commit; bytes of a write
        // that does not commit stay unreferenced.
        ASSIGN_OR_RETURN(const int64_t offset, contexts_->Append(context));
        st.BindInt64(8, offset);
        st.BindInt64(9, static_cast<int64_t>(context.size()));
      } else {
        st.BindNull(8);
        st.BindNull(9);
      }
      ASSIGN_OR_RETURN(const bool inserted, st.Step());
      event_id = inserted ? st.Int64(0) : 0;
      RETURN_IF_ERROR(st.Run());
    }
    const bool inserted = event_id != 0;
    if (inserted && !in_file) {
      ASSIGN_OR_RETURN(
          Statement st,
          statements_->Get("INSERT INTO event_contexts (event_id, context) "
                           "VALUES (?1, ?2)",
                           "AppendPending"));
      st.BindInt64(1, event_id);
      st.BindBlob(2, context);
      RETURN_IF_ERROR(st.Run());
    }
    if (!inserted) return UserNotFound(event.user_id);
    return absl::OkStatus();
  }));
  {
    absl::MutexLock stats(&stats_mu_);
    ++write_stats_.appends;
    write_stats_.append_seconds += absl::ToDoubleSeconds(absl::Now() - start);
  }
  return event_id;
}

absl::StatusOr<EventRecord> SqliteEventStore::CompleteEvent(
    int64_t event_id, double loss, const std::vector<double>& posthoc,
    double weight, absl::Time updated_at) {
  RETURN_IF_ERROR(CheckHealth());
  RETURN_IF_ERROR(store_rows::CheckOutcome(loss, weight));
  const std::string posthoc_bytes = EncodeDoubles(posthoc);
  const absl::Time start = absl::Now();
  EventRecord event;
  RETURN_IF_ERROR(RunInGroup([&]() ABSL_NO_THREAD_SAFETY_ANALYSIS {
    {
      // The one read of the event: what the model needs, and whether it
      // is still pending (in this transaction, so never applied twice).
      ASSIGN_OR_RETURN(
          Statement st,
          statements_->Get(absl::StrCat(kEventColumns, "WHERE event_id = ?1"),
                           "CompleteEvent"));
      st.BindInt64(1, event_id);
      ASSIGN_OR_RETURN(const bool found, st.Step());
      if (!found) return EventNotFound(event_id);
      ASSIGN_OR_RETURN(event, ReadEvent(st));
    }
    if (event.completed) return store_rows::AlreadyCompleted(event_id);
    {
      ASSIGN_OR_RETURN(
          Statement st,
          statements_->Get("UPDATE users SET model_version = model_version + 1 "
                           "WHERE user_id = ?1 RETURNING model_version",
                           "CompleteEvent"));
      st.BindText(1, event.user_id);
      ASSIGN_OR_RETURN(const bool found, st.Step());
      // The foreign key makes this unreachable short of a damaged file.
      if (!found) {
        return absl::DataLossError(absl::StrCat("event ", event_id,
                                                " belongs to missing user \"",
                                                event.user_id, "\""));
      }
      event.model_version = st.Int64(0);
      RETURN_IF_ERROR(st.Run());
    }
    ASSIGN_OR_RETURN(
        Statement st,
        statements_->Get(
            "UPDATE events SET completed = 1, loss = ?2, posthoc = ?3, "
            "weight = ?4, model_version = ?5, updated_at_us = ?6, "
            "outcome_checksum = ?7 WHERE event_id = ?1",
            "CompleteEvent"));
    st.BindInt64(1, event_id);
    st.BindDouble(2, loss);
    st.BindBlob(3, posthoc_bytes);
    st.BindDouble(4, weight);
    st.BindInt64(5, event.model_version);
    st.BindInt64(6, ToMicros(updated_at));
    st.BindInt64(7, OutcomeChecksum(loss, posthoc_bytes, weight,
                                    event.model_version, ToMicros(updated_at)));
    return st.Run();
  }));
  {
    absl::MutexLock stats(&stats_mu_);
    ++write_stats_.completions;
    write_stats_.completion_seconds +=
        absl::ToDoubleSeconds(absl::Now() - start);
  }
  event.completed = true;
  event.loss = loss;
  event.posthoc = posthoc;
  event.weight = weight;
  // Reported as stored, i.e. truncated to microseconds.
  event.updated_at = FromMicros(ToMicros(updated_at));
  return event;
}

absl::StatusOr<EventRecord> SqliteEventStore::GetEvent(int64_t event_id) {
  absl::MutexLock lock(&mu_);
  ASSIGN_OR_RETURN(
      Statement st,
      Statement::Prepare(
          db_, absl::StrCat(kEventColumns, "WHERE event_id = ?1"), "GetEvent"));
  st.BindInt64(1, event_id);
  ASSIGN_OR_RETURN(const bool found, st.Step());
  if (!found) return EventNotFound(event_id);
  return ReadEvent(st);
}

absl::StatusOr<int64_t> SqliteEventStore::AddPool(const PoolRecord& pool) {
  RETURN_IF_ERROR(CheckHealth());
  absl::MutexLock lock(&mu_);
  ASSIGN_OR_RETURN(
      Transaction txn,
      Transaction::Begin(db_, Transaction::Kind::kWrite, "AddPool"));
  ASSIGN_OR_RETURN(
      Statement st,
      Statement::Prepare(
          db_,
          "INSERT INTO population_pools (created_at_us, users, learner, "
          "context_dim, posthoc_dim, prior) "
          "VALUES (?1, ?2, ?3, ?4, ?5, ?6) RETURNING pool_version",
          "AddPool"));
  PopulationPrior stored = pool.prior;
  stored.pool_version = 0;
  stored.rounds = 0.0;
  const std::string prior = EncodePrior(stored);
  st.BindInt64(1, ToMicros(pool.created_at));
  st.BindInt64(2, pool.users);
  st.BindInt64(3, static_cast<int64_t>(pool.learner));
  st.BindInt64(4, pool.context_dim);
  st.BindInt64(5, pool.posthoc_dim);
  st.BindBlob(6, prior);
  ASSIGN_OR_RETURN(const bool row, st.Step());
  if (!row) return absl::InternalError("AddPool: no pool_version returned");
  const int64_t version = st.Int64(0);
  RETURN_IF_ERROR(st.Run());
  // Bound as text like any key; the column's INTEGER affinity converts it.
  RETURN_IF_ERROR(WriteActionNames(db_, "pool_actions", "pool_version",
                                   absl::StrCat(version), pool.action_names,
                                   "AddPool"));
  RETURN_IF_ERROR(txn.Commit());
  return version;
}

absl::StatusOr<PoolRecord> SqliteEventStore::LatestPool(
    const BanditConfig& config) {
  absl::MutexLock lock(&mu_);
  ASSIGN_OR_RETURN(
      Transaction txn,
      Transaction::Begin(db_, Transaction::Kind::kRead, "LatestPool"));
  // The newest pool of this learner and these dimensions whose actions are
  // the user's, name for name.
  ASSIGN_OR_RETURN(
      Statement st,
      Statement::Prepare(
          db_,
          "SELECT pool_version, created_at_us, users, prior "
          "FROM population_pools WHERE learner = ?1 AND context_dim = ?2 AND "
          "posthoc_dim = ?3 ORDER BY pool_version DESC",
          "LatestPool"));
  const int posthoc_dim =
      config.learner == Learner::kPostHoc ? config.posthoc_dim : 0;
  st.BindInt64(1, static_cast<int64_t>(config.learner));
  st.BindInt64(2, config.context_dim);
  st.BindInt64(3, posthoc_dim);
  while (true) {
    ASSIGN_OR_RETURN(const bool row, st.Step());
    if (!row) break;
    PoolRecord pool;
    pool.pool_version = st.Int64(0);
    const std::string what = absl::StrCat("pool ", pool.pool_version);
    ASSIGN_OR_RETURN(
        pool.action_names,
        ReadActionNames(db_, "pool_actions", "pool_version",
                        absl::StrCat(pool.pool_version), what, "LatestPool"));
    if (pool.action_names != config.action_names) continue;
    pool.created_at = FromMicros(st.Int64(1));
    pool.users = st.Int64(2);
    pool.learner = config.learner;
    pool.context_dim = config.context_dim;
    pool.posthoc_dim = posthoc_dim;
    ASSIGN_OR_RETURN(pool.prior, DecodePrior(st.Blob(3), what));
    pool.prior.pool_version = pool.pool_version;
    return pool;
  }
  return store_rows::NoPoolFor(config, posthoc_dim);
}

absl::Status SqliteEventStore::CheckUserExistsLocked(
    const std::string& user_id) {
  ASSIGN_OR_RETURN(
      Statement st,
      Statement::Prepare(db_, "SELECT 1 FROM users WHERE user_id = ?1",
                         "CheckUserExists"));
  st.BindText(1, user_id);
  ASSIGN_OR_RETURN(const bool found, st.Step());
  if (!found) return UserNotFound(user_id);
  return absl::OkStatus();
}

absl::StatusOr<PageResult<EventRecord>> SqliteEventStore::ListEvents(
    const std::string& user_id, const std::string& meal_id, const Page& page) {
  store_rows::PageBuilder<EventRecord> out(
      page, 'e',
      [](const EventRecord& event) { return absl::StrCat(event.event_id); });
  int64_t after = 0;  // event ids start at 1
  if (!page.page_token.empty()) {
    ASSIGN_OR_RETURN(after, store_rows::ParseIdPageToken(page.page_token, 'e'));
  }
  absl::MutexLock lock(&mu_);
  // A read transaction: the existence check and the rows come from one
  // snapshot even if another process writes in between.
  ASSIGN_OR_RETURN(
      Transaction txn,
      Transaction::Begin(db_, Transaction::Kind::kRead, "ListEvents"));
  RETURN_IF_ERROR(CheckUserExistsLocked(user_id));
  {
    // Separate statements so each filter gets its index.
    ASSIGN_OR_RETURN(
        Statement st,
        Statement::Prepare(
            db_,
            absl::StrCat(kEventColumns, "WHERE user_id = ?1 ",
                         meal_id.empty() ? "" : "AND meal_id = ?4 ",
                         "AND event_id > ?2 ORDER BY event_id LIMIT ?3"),
            "ListEvents"));
    st.BindText(1, user_id);
    st.BindInt64(2, after);
    st.BindInt64(3, out.page_size() + 1);
    if (!meal_id.empty()) st.BindText(4, meal_id);
    while (true) {
      ASSIGN_OR_RETURN(const bool row, st.Step());
      if (!row || !out.Room()) break;
      ASSIGN_OR_RETURN(EventRecord event, ReadEvent(st));
      const int64_t bytes = ApproxBytes(event);
      if (!out.Add(std::move(event), bytes)) break;
    }
  }
  RETURN_IF_ERROR(txn.Commit());
  return out.Take();
}

absl::StatusOr<std::vector<EventRecord>> SqliteEventStore::CompletedEvents(
    const std::string& user_id) {
  return CompletedEventsFrom(user_id, 1);
}

absl::StatusOr<std::vector<EventRecord>> SqliteEventStore::CompletedEventsFrom(
    const std::string& user_id, int64_t from_version) {
  absl::MutexLock lock(&mu_);
  ASSIGN_OR_RETURN(
      Transaction txn,
      Transaction::Begin(db_, Transaction::Kind::kRead, "CompletedEvents"));
  RETURN_IF_ERROR(CheckUserExistsLocked(user_id));
  std::vector<EventRecord> events;
  {
    ASSIGN_OR_RETURN(
        Statement st,
        Statement::Prepare(db_,
                           absl::StrCat(kEventColumns,
                                        "WHERE user_id = ?1 AND completed = 1 "
                                        "AND model_version >= ?2 "
                                        "ORDER BY model_version"),
                           "CompletedEvents"));
    st.BindText(1, user_id);
    st.BindInt64(2, from_version);
    while (true) {
      ASSIGN_OR_RETURN(const bool row, st.Step());
      if (!row) break;
      ASSIGN_OR_RETURN(EventRecord event, ReadEvent(st));
      events.push_back(std::move(event));
    }
  }
  RETURN_IF_ERROR(txn.Commit());
  return events;
}

absl::Status SqliteEventStore::PutCheckpoint(
    const std::string& user_id, const ModelCheckpoint& checkpoint) {
  RETURN_IF_ERROR(CheckHealth());
  constexpr char kOp[] = "PutCheckpoint";
  if (checkpoint.model_version <= 0 || checkpoint.state.empty()) {
    return absl::InvalidArgumentError(
        "checkpoint: needs model_version > 0 and a state");
  }
  const absl::string_view state = checkpoint.state;
  const int64_t chunks = static_cast<int64_t>(
      (state.size() + kCheckpointChunkBytes - 1) / kCheckpointChunkBytes);
  // The chunks first, one transaction each: other calls run in between.
  for (int64_t seq = 0; seq < chunks; ++seq) {
    absl::MutexLock lock(&mu_);
    ASSIGN_OR_RETURN(Transaction txn,
                     Transaction::Begin(db_, Transaction::Kind::kWrite, kOp));
    RETURN_IF_ERROR(CheckUserExistsLocked(user_id));
    ASSIGN_OR_RETURN(
        Statement st,
        Statement::Prepare(db_,
                           "INSERT OR REPLACE INTO model_checkpoint_chunks "
                           "(user_id, model_version, seq, data) "
                           "VALUES (?1, ?2, ?3, ?4)",
                           kOp));
    st.BindText(1, user_id);
    st.BindInt64(2, checkpoint.model_version);
    st.BindInt64(3, seq);
    st.BindBlob(
        4, state.substr(seq * kCheckpointChunkBytes, kCheckpointChunkBytes));
    RETURN_IF_ERROR(st.Run());
    RETURN_IF_ERROR(txn.Commit());
  }
  // Then the header, if the log still has this event at this version, and
  // the older checkpoint's chunks go.
  absl::MutexLock lock(&mu_);
  ASSIGN_OR_RETURN(Transaction txn,
                   Transaction::Begin(db_, Transaction::Kind::kWrite, kOp));
  RETURN_IF_ERROR(CheckUserExistsLocked(user_id));
  bool current = false;
  {
    ASSIGN_OR_RETURN(
        Statement st,
        Statement::Prepare(db_,
                           "SELECT 1 FROM events WHERE user_id = ?1 AND "
                           "completed = 1 AND model_version = ?2 AND "
                           "event_id = ?3",
                           kOp));
    st.BindText(1, user_id);
    st.BindInt64(2, checkpoint.model_version);
    st.BindInt64(3, checkpoint.last_event_id);
    ASSIGN_OR_RETURN(current, st.Step());
    RETURN_IF_ERROR(st.Run());
  }
  if (current) {
    ASSIGN_OR_RETURN(
        Statement st,
        Statement::Prepare(
            db_,
            "INSERT OR REPLACE INTO model_checkpoints (user_id, "
            "model_version, last_event_id, state_bytes, chunks, checksum, "
            "created_at_us) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7)",
            kOp));
    st.BindText(1, user_id);
    st.BindInt64(2, checkpoint.model_version);
    st.BindInt64(3, checkpoint.last_event_id);
    st.BindInt64(4, static_cast<int64_t>(state.size()));
    st.BindInt64(5, chunks);
    st.BindInt64(6, BlobChecksum(state));
    st.BindInt64(7, ToMicros(checkpoint.created_at));
    RETURN_IF_ERROR(st.Run());
  }
  {
    ASSIGN_OR_RETURN(
        Statement st,
        Statement::Prepare(db_,
                           // Kept: the current header's chunks.
                           "DELETE FROM model_checkpoint_chunks WHERE "
                           "user_id = ?1 AND model_version NOT IN (SELECT "
                           "model_version FROM model_checkpoints WHERE "
                           "user_id = ?1)",
                           kOp));
    st.BindText(1, user_id);
    RETURN_IF_ERROR(st.Run());
  }
  RETURN_IF_ERROR(txn.Commit());
  if (!current) {
    return store_rows::CheckpointNotKept(user_id, checkpoint);
  }
  return absl::OkStatus();
}

absl::StatusOr<ModelCheckpoint> SqliteEventStore::GetCheckpoint(
    const std::string& user_id) {
  absl::MutexLock lock(&mu_);
  ASSIGN_OR_RETURN(
      Transaction txn,
      Transaction::Begin(db_, Transaction::Kind::kRead, "GetCheckpoint"));
  RETURN_IF_ERROR(CheckUserExistsLocked(user_id));
  ASSIGN_OR_RETURN(ModelCheckpoint out, ReadCheckpointLocked(user_id));
  RETURN_IF_ERROR(txn.Commit());
  return out;
}

absl::StatusOr<ModelCheckpoint> SqliteEventStore::ReadCheckpointLocked(
    const std::string& user_id) {
  constexpr char kOp[] = "GetCheckpoint";
  ModelCheckpoint out;
  int64_t bytes = 0, chunks = 0, checksum = 0;
  {
    ASSIGN_OR_RETURN(
        Statement st,
        Statement::Prepare(db_,
                           "SELECT model_version, last_event_id, state_bytes, "
                           "chunks, checksum, created_at_us FROM "
                           "model_checkpoints WHERE user_id = ?1",
                           kOp));
    st.BindText(1, user_id);
    ASSIGN_OR_RETURN(const bool row, st.Step());
    if (!row) {
      return absl::NotFoundError(
          absl::StrCat("user ", user_id, " has no model checkpoint"));
    }
    out.model_version = st.Int64(0);
    out.last_event_id = st.Int64(1);
    bytes = st.Int64(2);
    chunks = st.Int64(3);
    checksum = st.Int64(4);
    out.created_at = FromMicros(st.Int64(5));
    RETURN_IF_ERROR(st.Run());
  }
  {
    ASSIGN_OR_RETURN(
        Statement st,
        Statement::Prepare(db_,
                           "SELECT seq, data FROM model_checkpoint_chunks "
                           "WHERE user_id = ?1 AND model_version = ?2 "
                           "ORDER BY seq",
                           kOp));
    st.BindText(1, user_id);
    st.BindInt64(2, out.model_version);
    if (bytes > 0) out.state.reserve(static_cast<size_t>(bytes));
    int64_t expected_seq = 0;
    while (true) {
      ASSIGN_OR_RETURN(const bool row, st.Step());
      if (!row) break;
      if (st.Int64(0) != expected_seq++) break;
      const absl::string_view data = st.Blob(1);
      out.state.append(data.data(), data.size());
    }
    if (expected_seq != chunks ||
        static_cast<int64_t>(out.state.size()) != bytes ||
        BlobChecksum(out.state) != checksum) {
      return store_rows::CheckpointDamaged(user_id, out.model_version,
                                           out.state.size(), bytes,
                                           expected_seq, chunks);
    }
  }
  return out;
}

absl::Status SqliteEventStore::DeleteCheckpoint(const std::string& user_id) {
  RETURN_IF_ERROR(CheckHealth());
  absl::MutexLock lock(&mu_);
  ASSIGN_OR_RETURN(
      Transaction txn,
      Transaction::Begin(db_, Transaction::Kind::kWrite, "DeleteCheckpoint"));
  RETURN_IF_ERROR(CheckUserExistsLocked(user_id));
  RETURN_IF_ERROR(DeleteCheckpointLocked(user_id));
  return txn.Commit();
}

absl::Status SqliteEventStore::DeleteCheckpointLocked(
    const std::string& user_id) {
  for (const char* sql :
       {"DELETE FROM model_checkpoints WHERE user_id = ?1",
        "DELETE FROM model_checkpoint_chunks WHERE user_id = ?1"}) {
    ASSIGN_OR_RETURN(Statement st,
                     Statement::Prepare(db_, sql, "DeleteCheckpoint"));
    st.BindText(1, user_id);
    RETURN_IF_ERROR(st.Run());
  }
  return absl::OkStatus();
}

StoreWriteStats SqliteEventStore::write_stats() const {
  absl::MutexLock lock(&stats_mu_);
  return write_stats_;
}

absl::StatusOr<int64_t> SqliteEventStore::AppendAudit(const AuditEntry& entry) {
  RETURN_IF_ERROR(CheckHealth());
  absl::MutexLock lock(&mu_);
  ASSIGN_OR_RETURN(
      Statement st,
      Statement::Prepare(db_,
                         "INSERT INTO audit (at_us, method, target, identity, "
                         "role, peer, result) VALUES (?1, ?2, ?3, ?4, ?5, ?6, "
                         "?7) RETURNING audit_id",
                         "AppendAudit"));
  st.BindInt64(1, ToMicros(entry.time));
  st.BindText(2, entry.method);
  st.BindText(3, entry.target);
  st.BindText(4, entry.identity);
  st.BindText(5, entry.role);
  st.BindText(6, entry.peer);
  st.BindText(7, entry.result);
  ASSIGN_OR_RETURN(const bool row, st.Step());
  if (!row) return absl::InternalError("AppendAudit: no audit_id returned");
  const int64_t id = st.Int64(0);
  RETURN_IF_ERROR(st.Run());
  return id;
}

absl::StatusOr<PageResult<AuditEntry>> SqliteEventStore::ListAudit(
    const Page& page) {
  store_rows::PageBuilder<AuditEntry> out(
      page, 'a',
      [](const AuditEntry& entry) { return absl::StrCat(entry.audit_id); });
  int64_t after = 0;
  if (!page.page_token.empty()) {
    ASSIGN_OR_RETURN(after, store_rows::ParseIdPageToken(page.page_token, 'a'));
  }
  absl::MutexLock lock(&mu_);
  ASSIGN_OR_RETURN(
      Statement st,
      Statement::Prepare(db_,
                         "SELECT audit_id, at_us, method, target, identity, "
                         "role, peer, result FROM audit WHERE audit_id > ?1 "
                         "ORDER BY audit_id LIMIT ?2",
                         "ListAudit"));
  st.BindInt64(1, after);
  st.BindInt64(2, out.page_size() + 1);
  while (true) {
    ASSIGN_OR_RETURN(const bool row, st.Step());
    if (!row || !out.Room()) break;
    out.Add(store_rows::ReadAuditRow(st), /*bytes=*/0);
  }
  return out.Take();
}

absl::StatusOr<StoreCheckReport> SqliteEventStore::CheckStore() {
  constexpr int kMaxFindings = 100;
  absl::MutexLock lock(&mu_);
  ASSIGN_OR_RETURN(std::vector<std::string> findings,
                   sqlite::IntegrityFindings(db_, kMaxFindings));
  store_rows::CheckReportBuilder report(std::move(findings));
  ASSIGN_OR_RETURN(
      Transaction txn,
      Transaction::Begin(db_, Transaction::Kind::kRead, "CheckStore"));
  {
    ASSIGN_OR_RETURN(
        Statement users,
        Statement::Prepare(db_, absl::StrCat(kUserColumns, "ORDER BY user_id"),
                           "CheckStore"));
    while (true) {
      ASSIGN_OR_RETURN(const bool row, users.Step());
      if (!row) break;
      RETURN_IF_ERROR(report.User(ReadUser(db_, users)));
    }
  }
  {
    ASSIGN_OR_RETURN(Statement events,
                     Statement::Prepare(
                         db_, absl::StrCat(kEventColumns, "ORDER BY event_id"),
                         "CheckStore"));
    while (true) {
      ASSIGN_OR_RETURN(const bool row, events.Step());
      if (!row) break;
      RETURN_IF_ERROR(report.Event(ReadEvent(events).status()));
    }
  }
  {
    // Checkpoints are derived (a damaged one is ignored and the model
    // rebuilt from the log), but a damaged one is still worth knowing of.
    std::vector<std::string> with_checkpoint;
    ASSIGN_OR_RETURN(
        Statement st,
        Statement::Prepare(
            db_, "SELECT user_id FROM model_checkpoints ORDER BY user_id",
            "CheckStore"));
    while (true) {
      ASSIGN_OR_RETURN(const bool row, st.Step());
      if (!row) break;
      with_checkpoint.push_back(st.Text(0));
    }
    for (const std::string& user_id : with_checkpoint) {
      RETURN_IF_ERROR(
          report.Checkpoint(ReadCheckpointLocked(user_id).status()));
    }
  }
  RETURN_IF_ERROR(txn.Commit());
  return report.Take();
}

}  // namespace bitewise::bandit
