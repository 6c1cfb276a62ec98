// What only the SQLite store has: its file, its lock, its migrations, its
// contexts file.
#include "services/bandit/store/write_faults.h"
#include "tests/bandit/store/store_test_fixture.h"

namespace bitewise::bandit::store_test {
namespace {

TEST_F(SqliteEventStoreTest, FileIsWalWithSchemaVersion) {
  RawDb raw(path_);
  EXPECT_EQ(raw.Text("PRAGMA journal_mode"), "wal");
  EXPECT_EQ(raw.Text("PRAGMA user_version"), "7");
  EXPECT_NE(raw.Text("PRAGMA application_id"), "0");
}

TEST_F(SqliteEventStoreTest, MissingOrEmptyFileIsANewStoreOnlyWhenAskedFor) {
  SqliteStoreOptions options;
  options.path = dir_ + "/typo.db";
  options.create_if_missing = false;
  auto missing = SqliteEventStore::Open(options);
  EXPECT_EQ(missing.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(missing.status().message(),
              HasSubstr(options.path + "\" does not exist; pass --create"));
  EXPECT_FALSE(std::filesystem::exists(options.path));  // nothing made
  std::ofstream(options.path).close();                  // a 0-byte file
  auto empty = SqliteEventStore::Open(options);
  EXPECT_THAT(empty.status().message(), HasSubstr("is an empty file"));
  // Asked for: created, readable by its owner only.
  options.create_if_missing = true;
  std::filesystem::remove(options.path);
  auto created = SqliteEventStore::Open(options);
  ASSERT_TRUE(created.ok()) << created.status();
  struct stat st {};
  ASSERT_EQ(stat(options.path.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0600u);
  created->reset();
  // An existing store opens without it.
  options.create_if_missing = false;
  EXPECT_TRUE(SqliteEventStore::Open(options).ok());
}

TEST_F(SqliteEventStoreTest, NotADatabaseIsFailedPrecondition) {
  const std::string path = dir_ + "/notes.txt";
  const std::string content(4096, 'x');
  {
    std::ofstream out(path, std::ios::binary);
    out << content;
  }
  SqliteStoreOptions options;
  options.path = path;
  auto store = SqliteEventStore::Open(options);
  EXPECT_EQ(store.status().code(), absl::StatusCode::kFailedPrecondition)
      << store.status();
  EXPECT_THAT(store.status().message(), HasSubstr(path));
  std::ifstream in(path, std::ios::binary);
  EXPECT_EQ(std::string(std::istreambuf_iterator<char>(in), {}), content);
}

TEST_F(SqliteEventStoreTest, NewerSchemaVersionIsFailedPrecondition) {
  store_.reset();
  RawDb(path_).Exec("PRAGMA user_version = 8");
  SqliteStoreOptions options;
  options.path = path_;
  auto store = SqliteEventStore::Open(options);
  EXPECT_EQ(store.status().code(), absl::StatusCode::kFailedPrecondition)
      << store.status();
  EXPECT_THAT(store.status().message(), HasSubstr(path_));
  EXPECT_THAT(store.status().message(), HasSubstr("version 8"));
}

// A second process on the same file would serve models that miss the first
// one's updates: it is refused, naming the holder; the file is free again
// once the first store closes (or its process dies: the lock is the
// kernel's).
TEST_F(SqliteEventStoreTest, ASecondStoreOnTheSameFileIsRefused) {
  SqliteStoreOptions options;
  options.path = path_;
  auto second = SqliteEventStore::Open(options);
  EXPECT_EQ(second.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(second.status().message(),
              HasSubstr("already open in another process (pid " +
                        std::to_string(getpid())));
  EXPECT_THAT(second.status().message(), HasSubstr(path_));
  store_.reset();
  auto third = SqliteEventStore::Open(options);
  EXPECT_TRUE(third.ok()) << third.status();
}

// A second name for the file (a symbolic link) is the same store: its
// lock and its contexts file are named from the real file. Before, a
// service on the link took a lock and a contexts file of its own, and the
// two wrote contexts over each other (DATA_LOSS at the next read).
TEST_F(SqliteEventStoreTest, ALinkToAnOpenStoreIsRefusedToo) {
  const std::string link = path_ + "-link.db";
  std::filesystem::create_symlink(path_, link);
  SqliteStoreOptions options;
  options.path = link;
  auto second = SqliteEventStore::Open(options);
  EXPECT_EQ(second.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(second.status().message(),
              HasSubstr("already open in another process"));
  EXPECT_THAT(second.status().message(),
              HasSubstr(std::filesystem::canonical(path_).string() + ".lock"));
  store_.reset();
  auto through_link = SqliteEventStore::Open(options);
  ASSERT_TRUE(through_link.ok()) << through_link.status();
  EXPECT_FALSE(std::filesystem::exists(link + ".lock"));
  EXPECT_FALSE(std::filesystem::exists(link + ".contexts"));
  through_link->reset();
  // A store an earlier build served through the link kept its contexts as
  // "<link>.contexts": that file is used where it is.
  const std::string real = std::filesystem::canonical(path_).string();
  std::filesystem::rename(real + ".contexts", link + ".contexts");
  auto upgraded = SqliteEventStore::Open(options);
  ASSERT_TRUE(upgraded.ok()) << upgraded.status();
  EXPECT_FALSE(std::filesystem::exists(real + ".contexts"));
  EXPECT_TRUE(std::filesystem::exists(link + ".contexts"));
  upgraded->reset();
  // Both names there (a header-only file made by an open through the real
  // name): which holds the contexts is not guessed.
  { std::ofstream(real + ".contexts") << "x"; }
  auto ambiguous = SqliteEventStore::Open(options);
  EXPECT_EQ(ambiguous.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(ambiguous.status().message(),
              HasSubstr("exist: keep the one this database's contexts are in"));
  std::filesystem::remove(real + ".contexts");
  std::filesystem::remove(link + ".contexts");
  std::filesystem::remove(link);
}

// A database file removed (or replaced) under a running service: writes
// would be acknowledged and lost at the next start, so none is accepted.
TEST_F(SqliteEventStoreTest, WritesAreRefusedOnceTheFileIsRemoved) {
  ASSERT_TRUE(store_->CreateUser(MakeUser("ann")).ok());
  EXPECT_TRUE(store_->CheckHealth().ok());
  std::filesystem::remove(path_);
  const absl::Status health = store_->CheckHealth();
  EXPECT_EQ(health.code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(health.message(), HasSubstr(path_ + " was removed or replaced"));
  auto appended = store_->AppendPending(MakeEvent("ann", "m1"));
  EXPECT_EQ(appended.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_EQ(store_->CreateUser(MakeUser("bob")).code(),
            absl::StatusCode::kFailedPrecondition);
}

// The first bytes of `event`'s context as the contexts file holds them.
std::string ContextPrefix(const EventRecord& event) {
  std::string bytes(64, '\0');
  std::memcpy(bytes.data(), event.context.data(), bytes.size());
  return bytes;
}

// A file whose pages were damaged is not served as if it were whole.
TEST_F(SqliteEventStoreTest, ADamagedFileIsDataLossNotAnEmptyStore) {
  ASSERT_TRUE(store_->CreateUser(MakeUser("ann")).ok());
  for (int i = 0; i < 200; ++i) {
    ASSERT_TRUE(store_->AppendPending(MakeEvent("ann", "m1", i)).ok());
  }
  store_.reset();
  {
    RawDb raw(path_);
    raw.Exec("PRAGMA wal_checkpoint(TRUNCATE)");
  }
  // Overwrite the middle of the event table's pages with garbage.
  const auto size = std::filesystem::file_size(path_);
  ASSERT_GT(size, 16384u);
  {
    std::fstream file(path_, std::ios::in | std::ios::out | std::ios::binary);
    for (std::streamoff at = 8192; at < 8192 + 3 * 4096; at += 4096) {
      file.seekp(at + 8);
      const std::string garbage(64, '\x5a');
      file.write(garbage.data(), garbage.size());
    }
  }
  SqliteStoreOptions options;
  options.path = path_;
  auto store = SqliteEventStore::Open(options);
  EXPECT_EQ(store.status().code(), absl::StatusCode::kDataLoss)
      << store.status();
  EXPECT_THAT(store.status().message(), HasSubstr(path_));

  // The service's way (the check deferred to a thread once it serves): the
  // open succeeds without reading the file, the check finds the same
  // damage, health reports it and no write goes in, now or after a probe.
  OpenStoreOptions deferred;
  deferred.defer_full_check = true;
  auto watched = OpenEventStore(path_, deferred);
  ASSERT_TRUE(watched.ok()) << watched.status();
  const absl::Status checked = (*watched)->RunDeferredChecks();  // waits
  EXPECT_EQ(checked.code(), absl::StatusCode::kDataLoss) << checked;
  EXPECT_THAT(checked.message(),
              HasSubstr(path_ + " failed SQLite's integrity check"));
  const absl::Status health = (*watched)->CheckHealth();
  EXPECT_EQ(health, checked);
  const auto refused = (*watched)->AppendPending(MakeEvent("ann", "m2"));
  EXPECT_EQ(refused.status(), checked);
  EXPECT_EQ((*watched)->CreateUser(MakeUser("bob")), checked);
  absl::SleepFor(absl::Milliseconds(250));  // past a probe period
  EXPECT_EQ((*watched)->CheckHealth(), checked);
  EXPECT_EQ((*watched)->CreateUser(MakeUser("bob")), checked);
  EXPECT_GE((*watched)->write_stats().write_faults, 3);
}

// Deferred or not, the checks keep the same promises: a contexts file
// missing while rows point into it is refused at open; bytes no row points
// at are erased (by RunDeferredChecks, not by the open); and writes made
// after it go after everything the rows point at.
TEST_F(SqliteEventStoreTest, DeferredChecksKeepTheOpensPromises) {
  const std::string file = path_ + ".contexts";
  ASSERT_TRUE(store_->CreateUser(MakeUser("ann")).ok());
  const int64_t kept = MustAppend(LargeEvent("ann", 0.5));
  const int64_t small = MustAppend(MakeEvent("ann", "m"));  // after it
  EXPECT_EQ(store_->AppendPending(LargeEvent("ghost", 3.75)).status().code(),
            absl::StatusCode::kNotFound);
  store_ = nullptr;
  const std::string ghost = ContextPrefix(LargeEvent("ghost", 3.75));
  SqliteStoreOptions options;
  options.path = path_;
  options.check_at_open = false;
  {
    const std::string whole = FileBytes(file);
    std::filesystem::remove(file);
    auto missing = SqliteEventStore::Open(options);
    EXPECT_EQ(missing.status().code(), absl::StatusCode::kDataLoss);
    EXPECT_THAT(missing.status().message(), HasSubstr(file));
    std::ofstream(file, std::ios::binary) << whole;
  }
  auto store = SqliteEventStore::Open(options);
  ASSERT_TRUE(store.ok()) << store.status();
  EXPECT_NE(FileBytes(file).find(ghost), std::string::npos);  // not yet
  EXPECT_EQ((*store)->GetEvent(kept)->context, LargeEvent("ann", 0.5).context);
  ASSERT_TRUE((*store)->RunDeferredChecks().ok());
  EXPECT_EQ(FileBytes(file).find(ghost), std::string::npos);
  ASSERT_TRUE((*store)->RunDeferredChecks().ok());  // once is enough
  const auto next = (*store)->AppendPending(LargeEvent("ann", 2.0));
  ASSERT_TRUE(next.ok()) << next.status();
  EXPECT_EQ((*store)->GetEvent(*next)->context, LargeEvent("ann", 2.0).context);
  EXPECT_EQ((*store)->GetEvent(kept)->context, LargeEvent("ann", 0.5).context);
  EXPECT_TRUE((*store)->GetEvent(small).ok());
  auto check = (*store)->CheckStore();
  ASSERT_TRUE(check.ok()) << check.status();
  EXPECT_THAT(check->findings, IsEmpty());
}

// Turns the current store at `path` back into what a version 6 build wrote:
// no phi_radius per user (the release file of release_files_test is another
// version 6 store, written by that build).
void RewriteAsVersion6(const std::string& path) {
  RawDb raw(path);
  raw.Exec("ALTER TABLE users DROP COLUMN phi_radius");
  raw.Exec("PRAGMA user_version = 6");
}

// Turns the current store at `path` back into what a version 5 build wrote:
// no contexts file (every context, all small here, in event_contexts).
void RewriteAsVersion5(const std::string& path) {
  RewriteAsVersion6(path);
  RawDb raw(path);
  EXPECT_EQ(raw.Text("SELECT COUNT(*) FROM events WHERE context_offset IS "
                     "NOT NULL"),
            "0");
  raw.Exec("ALTER TABLE events DROP COLUMN context_offset");
  raw.Exec("ALTER TABLE events DROP COLUMN context_bytes");
  raw.Exec("PRAGMA user_version = 5");
}

// Turns the current store at `path` back into what a version 4 build wrote:
// each event's context in its own row.
void RewriteAsVersion4(const std::string& path) {
  RewriteAsVersion5(path);
  RawDb raw(path);
  raw.Exec("ALTER TABLE events ADD COLUMN context BLOB");
  raw.Exec(
      "UPDATE events SET context = (SELECT context FROM event_contexts c "
      "WHERE c.event_id = events.event_id)");
  raw.Exec("DROP TABLE event_contexts");
  raw.Exec("PRAGMA user_version = 4");
}

// Turns the current store at `path` back into what a version 2 build wrote:
// action names as a JSON column of users and pools, no child tables.
void RewriteAsVersion2(const std::string& path,
                       const std::string& user_names_json,
                       const std::string& pool_names_json) {
  RewriteAsVersion4(path);
  RawDb raw(path);
  raw.Exec(
      "ALTER TABLE users ADD COLUMN action_names TEXT NOT NULL DEFAULT ''");
  raw.Exec("UPDATE users SET action_names = '" + user_names_json + "'");
  raw.Exec(
      "ALTER TABLE population_pools ADD COLUMN action_names TEXT NOT NULL "
      "DEFAULT ''");
  raw.Exec("UPDATE population_pools SET action_names = '" + pool_names_json +
           "'");
  raw.Exec("DROP TABLE user_actions");
  raw.Exec("DROP TABLE pool_actions");
  raw.Exec("ALTER TABLE events DROP COLUMN selection_checksum");
  raw.Exec("ALTER TABLE events DROP COLUMN outcome_checksum");
  raw.Exec("DROP TABLE audit");
  raw.Exec("DROP TABLE model_checkpoint_chunks");
  raw.Exec("DROP TABLE model_checkpoints");
  raw.Exec("PRAGMA user_version = 2");
}

// Version 4 kept each context in its event's row; version 5 moves them to
// event_contexts, and every event reads back as it was, checksums included.
TEST_F(SqliteEventStoreTest, VersionFourContextsMoveToTheirOwnTable) {
  ASSERT_TRUE(store_->CreateUser(MakeUser("four")).ok());
  const int64_t done = MustAppend(MakeEvent("four", "m1", 0.25));
  MustComplete(done, 0.0);
  const int64_t pending = MustAppend(MakeEvent("four", "m2", -1.5));
  const EventRecord before_done = MustGetEvent(done);
  const EventRecord before_pending = MustGetEvent(pending);
  store_.reset();
  RewriteAsVersion4(path_);
  EXPECT_EQ(RawDb(path_).Text("SELECT COUNT(*) FROM events WHERE context IS "
                              "NOT NULL"),
            "2");
  store_ = OpenStore();
  ASSERT_NE(store_, nullptr);
  EXPECT_EQ(RawDb(path_).Text("PRAGMA user_version"), "7");
  EXPECT_EQ(RawDb(path_).Text("SELECT COUNT(*) FROM event_contexts"), "2");
  const EventRecord after_done = MustGetEvent(done);
  const EventRecord after_pending = MustGetEvent(pending);
  EXPECT_EQ(after_done.context, before_done.context);
  EXPECT_EQ(after_done.loss, before_done.loss);
  EXPECT_EQ(after_done.model_version, 1);
  EXPECT_EQ(after_pending.context, before_pending.context);
  EXPECT_FALSE(after_pending.completed);
  absl::StatusOr<StoreCheckReport> check = store_->CheckStore();
  ASSERT_TRUE(check.ok()) << check.status();
  EXPECT_TRUE(check->findings.empty());
  // A lost context row is damage, found by the checksum, not an event
  // that silently drops out of the log.
  RawDb(path_).Exec(
      absl::StrCat("DELETE FROM event_contexts WHERE event_id = ", pending));
  EXPECT_EQ(store_->GetEvent(pending).status().code(),
            absl::StatusCode::kDataLoss);
  check = store_->CheckStore();
  ASSERT_TRUE(check.ok()) << check.status();
  EXPECT_FALSE(check->findings.empty());
  // Deleting the user takes the contexts along.
  ASSERT_TRUE(store_->DeleteUser("four").ok());
  EXPECT_EQ(RawDb(path_).Text("SELECT COUNT(*) FROM event_contexts"), "0");
}

TEST_F(SqliteEventStoreTest, VersionOneFilesAreMigratedKeepingEverything) {
  ASSERT_TRUE(store_->CreateUser(MakeUser("old")).ok());
  auto id = store_->AppendPending(MakeEvent("old", "m1"));
  ASSERT_TRUE(id.ok());
  store_.reset();
  RewriteAsVersion2(path_, R"(["VS0","VS90","TV0","TV90","TA0","TA90"])", "[]");
  {
    RawDb raw(path_);  // and back to what a version 1 build wrote
    raw.Exec("DROP TABLE population_pools");
    raw.Exec("ALTER TABLE users DROP COLUMN prior");
    raw.Exec("PRAGMA user_version = 1");
  }
  SqliteStoreOptions options;
  options.path = path_;
  auto store = SqliteEventStore::Open(options);
  ASSERT_TRUE(store.ok()) << store.status();
  EXPECT_EQ(RawDb(path_).Text("PRAGMA user_version"), "7");
  auto user = (*store)->GetUser("old");
  ASSERT_TRUE(user.ok()) << user.status();
  EXPECT_EQ(user->pending_events, 1);
  EXPECT_EQ(user->config.action_names, SmallConfig().action_names);
  // The migration gave the event its checksum: it reads back, and completes.
  ASSERT_TRUE((*store)->GetEvent(*id).ok());
  ASSERT_TRUE((*store)
                  ->CompleteEvent(*id, 1.0, {0.5, -0.5}, 1.0,
                                  absl::FromUnixSeconds(1700000100))
                  .ok());
  EXPECT_TRUE((*store)->CompletedEvents("old").ok());
  EXPECT_FALSE(user->config.prior.enabled());
  EXPECT_EQ((*store)->LatestPool(SmallConfig()).status().code(),
            absl::StatusCode::kNotFound);
}

// Version 2 kept action names as JSON; version 3 moves them, byte for byte
// (quotes, backslashes, control characters, NUL, non-ASCII), into
// user_actions and pool_actions and drops the columns.
TEST_F(SqliteEventStoreTest, VersionTwoActionNamesMoveIntoChildTables) {
  BanditConfig config = SmallConfig();
  config.action_names = {"a\"b",     "c\\d",      std::string("\0x", 2),
                         "\xc3\xa9", "tab\there", "/"};
  UserRecord user = MakeUser("v2");
  user.config = config;
  ASSERT_TRUE(store_->CreateUser(user).ok());
  PoolRecord pool;
  pool.users = 4;
  pool.learner = config.learner;
  pool.context_dim = config.context_dim;
  pool.posthoc_dim = config.posthoc_dim;
  pool.action_names = config.action_names;
  pool.prior = SmallPrior(0, 0.0);
  ASSERT_TRUE(store_->AddPool(pool).ok());
  store_.reset();
  const std::string json =
      R"(["a\"b","c\\d","\u0000x","\u00e9","tab\there","\/"])";
  RewriteAsVersion2(path_, json, json);

  SqliteStoreOptions options;
  options.path = path_;
  auto store = SqliteEventStore::Open(options);
  ASSERT_TRUE(store.ok()) << store.status();
  auto migrated = (*store)->GetUser("v2");
  ASSERT_TRUE(migrated.ok()) << migrated.status();
  EXPECT_EQ(migrated->config.action_names, config.action_names);
  auto found = (*store)->LatestPool(config);
  ASSERT_TRUE(found.ok()) << found.status();
  EXPECT_EQ(found->action_names, config.action_names);
  RawDb raw(path_);
  EXPECT_EQ(raw.Text("SELECT COUNT(*) FROM pragma_table_info('users') "
                     "WHERE name = 'action_names'"),
            "0");
  EXPECT_EQ(raw.Text("SELECT COUNT(*) FROM user_actions"), "6");
  EXPECT_EQ(raw.Text("SELECT COUNT(*) FROM pool_actions"), "6");
}

TEST_F(SqliteEventStoreTest, MalformedVersionTwoNamesAreDataLossAndUntouched) {
  ASSERT_TRUE(store_->CreateUser(MakeUser("broken")).ok());
  store_.reset();
  RewriteAsVersion2(path_, R"(["VS0","VS90)", "[]");
  SqliteStoreOptions options;
  options.path = path_;
  auto store = SqliteEventStore::Open(options);
  EXPECT_EQ(store.status().code(), absl::StatusCode::kDataLoss)
      << store.status();
  EXPECT_THAT(store.status().message(), HasSubstr("broken"));
  EXPECT_EQ(RawDb(path_).Text("PRAGMA user_version"), "2");  // rolled back
}

TEST_F(SqliteEventStoreTest, ForeignDatabaseIsFailedPreconditionAndUntouched) {
  const std::string path = dir_ + "/other.db";
  RawDb(path).Exec("CREATE TABLE notes (text TEXT)");
  SqliteStoreOptions options;
  options.path = path;
  auto store = SqliteEventStore::Open(options);
  EXPECT_EQ(store.status().code(), absl::StatusCode::kFailedPrecondition)
      << store.status();
  EXPECT_THAT(store.status().message(), HasSubstr(path));
  RawDb raw(path);
  EXPECT_EQ(raw.Text("PRAGMA journal_mode"), "delete");
  EXPECT_EQ(raw.Text("SELECT COUNT(*) FROM sqlite_schema"), "1");
}

TEST_F(SqliteEventStoreTest, OpenRejectsEmptyPathAndAcceptsMemory) {
  EXPECT_EQ(SqliteEventStore::Open(SqliteStoreOptions()).status().code(),
            absl::StatusCode::kInvalidArgument);
  SqliteStoreOptions memory;
  memory.path = ":memory:";
  auto store = SqliteEventStore::Open(memory);
  ASSERT_TRUE(store.ok()) << store.status();
  EXPECT_TRUE((*store)->CreateUser(MakeUser("alice")).ok());
}

TEST_F(SqliteEventStoreTest, LargeContextsLiveInTheContextsFile) {
  // New files have 1 KB pages; large contexts go to "<db>.contexts", each
  // at a 4 KB boundary, and read back bit for bit, also after a restart.
  EXPECT_EQ(RawDb(path_).Text("PRAGMA page_size"), "1024");
  const std::string file = path_ + ".contexts";
  ASSERT_TRUE(store_->CreateUser(MakeUser("ann")).ok());
  const int64_t small = MustAppend(MakeEvent("ann", "m"));
  const int64_t first = MustAppend(LargeEvent("ann", 0.5));
  const int64_t second = MustAppend(LargeEvent("ann", 1.5));
  MustComplete(first);
  {
    RawDb raw(path_);
    EXPECT_EQ(raw.Text("SELECT COUNT(*) FROM event_contexts"), "1");
    EXPECT_EQ(raw.Text(absl::StrCat(
                  "SELECT context_offset IS NULL FROM events WHERE event_id = ",
                  small)),
              "1");
    EXPECT_EQ(raw.Text(absl::StrCat("SELECT (context_offset % 4096) || ' ' || "
                                    "context_bytes FROM events WHERE "
                                    "event_id = ",
                                    second)),
              "0 4800");
  }
  EXPECT_EQ(FileBytes(file).substr(0, 16), "bitewise ctx v1\n");
  EXPECT_EQ(
      std::filesystem::status(file).permissions() & std::filesystem::perms::all,
      std::filesystem::perms::owner_read | std::filesystem::perms::owner_write);
  store_ = nullptr;
  store_ = OpenStore();
  ASSERT_NE(store_, nullptr);
  const EventRecord read = MustGetEvent(second);
  ASSERT_EQ(read.context.size(), 600u);
  EXPECT_EQ(read.context[0], 1.5);
  EXPECT_TRUE(std::signbit(read.context[1]));
  EXPECT_EQ(MustGetEvent(first).context, LargeEvent("ann", 0.5).context);
  auto log = store_->CompletedEvents("ann");
  ASSERT_TRUE(log.ok());
  ASSERT_EQ(log->size(), 1u);
  EXPECT_EQ((*log)[0].context, LargeEvent("ann", 0.5).context);
  // A new context goes after everything before the restart.
  const int64_t third = MustAppend(LargeEvent("ann", 2.5));
  EXPECT_EQ(MustGetEvent(second).context, LargeEvent("ann", 1.5).context);
  EXPECT_EQ(MustGetEvent(third).context, LargeEvent("ann", 2.5).context);
  auto check = store_->CheckStore();
  ASSERT_TRUE(check.ok()) << check.status();
  EXPECT_THAT(check->findings, IsEmpty());
}

TEST_F(SqliteEventStoreTest, AMissingOrForeignContextsFileIsRefused) {
  const std::string file = path_ + ".contexts";
  ASSERT_TRUE(store_->CreateUser(MakeUser("ann")).ok());
  MustAppend(LargeEvent("ann", 0.5));
  store_ = nullptr;
  const std::string kept = FileBytes(file);
  // Missing while the database points into it: refused, naming it.
  std::filesystem::remove(file);
  auto missing = TryOpenStore();
  EXPECT_EQ(missing.status().code(), absl::StatusCode::kDataLoss);
  EXPECT_THAT(missing.status().message(), HasSubstr(file));
  EXPECT_THAT(missing.status().message(), HasSubstr("missing"));
  EXPECT_FALSE(std::filesystem::exists(file));  // not made up anew
  // Not ours: refused, untouched.
  std::ofstream(file, std::ios::binary) << "some other file's bytes";
  auto foreign = TryOpenStore();
  EXPECT_EQ(foreign.status().code(), absl::StatusCode::kDataLoss);
  EXPECT_THAT(foreign.status().message(),
              HasSubstr("is not a bitewise contexts file"));
  EXPECT_EQ(FileBytes(file), "some other file's bytes");
  // Put back: served again.
  std::ofstream(file, std::ios::binary | std::ios::trunc) << kept;
  store_ = OpenStore();
  ASSERT_NE(store_, nullptr);
  EXPECT_EQ(MustGetUser("ann").pending_events, 1);
  // A new store's file is made under a temporary name: one left by a crash
  // during that is replaced, and never taken for the file.
  store_ = nullptr;
  const std::string fresh = dir_ + "/fresh.db";
  std::ofstream(fresh + ".contexts.new", std::ios::binary) << "half";
  SqliteStoreOptions options;
  options.path = fresh;
  auto made = SqliteEventStore::Open(options);
  ASSERT_TRUE(made.ok()) << made.status();
  EXPECT_EQ(FileBytes(fresh + ".contexts"), "bitewise ctx v1\n");
  EXPECT_FALSE(std::filesystem::exists(fresh + ".contexts.new"));
}

TEST_F(SqliteEventStoreTest, ADamagedContextIsDataLossNamingTheEvent) {
  const std::string file = path_ + ".contexts";
  ASSERT_TRUE(store_->CreateUser(MakeUser("ann")).ok());
  const int64_t kept = MustAppend(LargeEvent("ann", 0.5));
  const int64_t cut = MustAppend(LargeEvent("ann", 1.5));
  // The file loses its end (a torn copy): the last context reads short.
  std::filesystem::resize_file(file, std::filesystem::file_size(file) - 100);
  auto event = store_->GetEvent(cut);
  EXPECT_EQ(event.status().code(), absl::StatusCode::kDataLoss);
  EXPECT_THAT(event.status().message(), HasSubstr(absl::StrCat("event ", cut)));
  EXPECT_EQ(MustGetEvent(kept).context, LargeEvent("ann", 0.5).context);
  auto check = store_->CheckStore();
  ASSERT_TRUE(check.ok()) << check.status();
  ASSERT_EQ(check->findings.size(), 1u);
  EXPECT_THAT(check->findings[0], HasSubstr(absl::StrCat("event ", cut)));
  // New contexts never land where the lost one was.
  const int64_t next = MustAppend(LargeEvent("ann", 2.5));
  EXPECT_EQ(MustGetEvent(next).context, LargeEvent("ann", 2.5).context);
  EXPECT_EQ(store_->GetEvent(cut).status().code(), absl::StatusCode::kDataLoss);
  // A row claiming a petabyte reads what the file holds, and is DATA_LOSS.
  RawDb(path_).Exec(absl::StrCat(
      "UPDATE events SET context_bytes = 1000000000000000 WHERE event_id = ",
      kept));
  EXPECT_EQ(store_->GetEvent(kept).status().code(),
            absl::StatusCode::kDataLoss);
}

TEST_F(SqliteEventStoreTest, UnreferencedContextsAreErasedAtOpen) {
  // A write that did not commit (here: for a user that does not exist)
  // leaves its context in the file, unreferenced, until the next open.
  const std::string file = path_ + ".contexts";
  ASSERT_TRUE(store_->CreateUser(MakeUser("ann")).ok());
  const int64_t kept = MustAppend(LargeEvent("ann", 0.5));
  EXPECT_EQ(store_->AppendPending(LargeEvent("ghost", 3.75)).status().code(),
            absl::StatusCode::kNotFound);
  const int64_t after = MustAppend(LargeEvent("ann", 1.25));
  EXPECT_NE(FileBytes(file).find(ContextPrefix(LargeEvent("ghost", 3.75))),
            std::string::npos);
  store_ = nullptr;
  store_ = OpenStore();
  ASSERT_NE(store_, nullptr);
  EXPECT_EQ(FileBytes(file).find(ContextPrefix(LargeEvent("ghost", 3.75))),
            std::string::npos);
  EXPECT_EQ(MustGetEvent(kept).context, LargeEvent("ann", 0.5).context);
  EXPECT_EQ(MustGetEvent(after).context, LargeEvent("ann", 1.25).context);
  const int64_t next = MustAppend(LargeEvent("ann", 2.0));
  EXPECT_EQ(MustGetEvent(next).context, LargeEvent("ann", 2.0).context);
}

TEST_F(SqliteEventStoreTest, DeletedUsersContextsAreErasedFromTheFile) {
  const std::string file = path_ + ".contexts";
  ASSERT_TRUE(store_->CreateUser(MakeUser("ann")).ok());
  ASSERT_TRUE(store_->CreateUser(MakeUser("bob")).ok());
  const int64_t anns = MustAppend(LargeEvent("ann", 0.5));
  const int64_t bobs = MustAppend(LargeEvent("bob", 7.25));
  const int64_t anns_second = MustAppend(LargeEvent("ann", 0.75));
  auto where = [&](int64_t id) {
    const int64_t offset = std::stoll(RawDb(path_).Text(absl::StrCat(
        "SELECT context_offset FROM events WHERE event_id = ", id)));
    return FileBytes(file).substr(static_cast<size_t>(offset), 4800);
  };
  const std::string anns_bytes = where(anns);
  const std::string anns_second_bytes = where(anns_second);
  ASSERT_NE(anns_bytes, std::string(4800, '\0'));
  const std::string bobs_bytes = where(bobs);
  // The file's bytes, to find ann's afterwards.
  ASSERT_TRUE(store_->ResetUser("ann").ok());
  const std::string after_reset = FileBytes(file);
  EXPECT_EQ(after_reset.find(anns_bytes), std::string::npos);
  EXPECT_EQ(after_reset.find(anns_second_bytes), std::string::npos);
  EXPECT_NE(after_reset.find(bobs_bytes), std::string::npos);
  EXPECT_EQ(MustGetEvent(bobs).context, LargeEvent("bob", 7.25).context);
  ASSERT_TRUE(store_->DeleteUser("bob").ok());
  EXPECT_EQ(FileBytes(file).find(bobs_bytes), std::string::npos);
}

TEST_F(SqliteEventStoreTest, AReplacedContextsFileFailsHealth) {
  const std::string file = path_ + ".contexts";
  ASSERT_TRUE(store_->CreateUser(MakeUser("ann")).ok());
  MustAppend(LargeEvent("ann", 0.5));
  EXPECT_TRUE(store_->CheckHealth().ok());
  const std::string kept = FileBytes(file);
  std::filesystem::remove(file);
  std::ofstream(file, std::ios::binary) << kept;
  const absl::Status health = store_->CheckHealth();
  EXPECT_EQ(health.code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(health.message(), HasSubstr(file));
  // Writes are refused rather than acknowledged into the old file.
  EXPECT_EQ(store_->AppendPending(LargeEvent("ann", 1.0)).status().code(),
            absl::StatusCode::kFailedPrecondition);
}

// A write lock held by another program past the busy timeout (a sqlite3
// shell with a transaction open) is a storage fault: health says so, named
// (it stayed SERVING while every write failed), and clears once it goes.
TEST_F(SqliteEventStoreTest, LockHeldElsewhereIsUnavailable) {
  ASSERT_TRUE(store_->CreateUser(MakeUser("alice")).ok());
  const int64_t id = MustAppend(MakeEvent("alice", "m"));
  store_.reset();
  SqliteStoreOptions options;
  options.path = path_;
  options.busy_timeout = absl::Seconds(2);
  auto store = SqliteEventStore::Open(options);
  ASSERT_TRUE(store.ok()) << store.status();
  FaultWatchStore watched(std::move(store).value(), absl::Milliseconds(20));

  RawDb raw(path_);
  raw.Exec("BEGIN IMMEDIATE");
  auto completed =
      watched.CompleteEvent(id, 1.0, {}, 1.0, absl::FromUnixMicros(1));
  EXPECT_EQ(completed.status().code(), absl::StatusCode::kUnavailable)
      << completed.status();
  EXPECT_TRUE(IsStorageFault(completed.status()));
  EXPECT_THAT(completed.status().message(),
              HasSubstr("cannot write " + path_ +
                        ": the database is locked by another connection"));
  // The probe behind health does not wait for the lock (it would hold the
  // store's mutex, and every read, for the busy timeout): a bound on a wait,
  // well under the 2 s, not a measure of speed.
  absl::SleepFor(absl::Milliseconds(30));  // past the probe period
  const absl::Time asked = absl::Now();
  const absl::Status health = watched.CheckHealth();
  EXPECT_LT(absl::Now() - asked, absl::Seconds(1));
  EXPECT_EQ(health.code(), absl::StatusCode::kUnavailable);
  EXPECT_THAT(health.message(), HasSubstr("locked by another connection"));
  // Readers are not blocked by a writer in WAL mode.
  auto event = watched.GetEvent(id);
  ASSERT_TRUE(event.ok()) << event.status();
  EXPECT_FALSE(event->completed);
  raw.Exec("ROLLBACK");
  absl::SleepFor(absl::Milliseconds(30));
  EXPECT_TRUE(watched.CheckHealth().ok()) << watched.CheckHealth();
  auto done = watched.CompleteEvent(id, 1.0, {}, 1.0, absl::FromUnixMicros(1));
  ASSERT_TRUE(done.ok()) << done.status();
  EXPECT_EQ(done->model_version, 1);
}

}  // namespace
}  // namespace bitewise::bandit::store_test
