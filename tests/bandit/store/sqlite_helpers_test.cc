// The SQLite helpers (sqlite_helpers.h) on real databases: result codes as
// statuses, storage faults naming the file, statements, the statement
// cache, and transactions that roll back unless committed.
#include "services/bandit/store/sqlite_helpers.h"

#include <sqlite3.h>
#include <stdlib.h>

#include <filesystem>
#include <memory>
#include <string>

#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "services/bandit/store/write_faults.h"
#include "tests/common/status_matchers.h"

namespace bitewise::bandit::sqlite {
namespace {

using ::bitewise::testing::IsOk;
using ::bitewise::testing::StatusIs;
using ::testing::AllOf;
using ::testing::HasSubstr;

using Db = std::unique_ptr<sqlite3, SqliteCloser>;

TEST(CodeForSqliteTest, EachResultCodeHasTheCodeItsRemedyNeeds) {
  struct Case {
    int rc;
    absl::StatusCode code;
  };
  const Case cases[] = {
      {SQLITE_BUSY, absl::StatusCode::kUnavailable},
      {SQLITE_BUSY_SNAPSHOT, absl::StatusCode::kUnavailable},
      {SQLITE_LOCKED, absl::StatusCode::kUnavailable},
      {SQLITE_CONSTRAINT, absl::StatusCode::kFailedPrecondition},
      {SQLITE_CONSTRAINT_FOREIGNKEY, absl::StatusCode::kFailedPrecondition},
      {SQLITE_CORRUPT, absl::StatusCode::kDataLoss},
      {SQLITE_NOTADB, absl::StatusCode::kDataLoss},
      {SQLITE_FULL, absl::StatusCode::kResourceExhausted},
      {SQLITE_NOMEM, absl::StatusCode::kResourceExhausted},
      {SQLITE_CANTOPEN, absl::StatusCode::kFailedPrecondition},
      {SQLITE_READONLY, absl::StatusCode::kFailedPrecondition},
      {SQLITE_PERM, absl::StatusCode::kFailedPrecondition},
      {SQLITE_AUTH, absl::StatusCode::kFailedPrecondition},
      {SQLITE_TOOBIG, absl::StatusCode::kInvalidArgument},
      {SQLITE_RANGE, absl::StatusCode::kInvalidArgument},
      {SQLITE_MISMATCH, absl::StatusCode::kInvalidArgument},
      {SQLITE_ERROR, absl::StatusCode::kInternal},
      {SQLITE_MISUSE, absl::StatusCode::kInternal},
      {SQLITE_IOERR_WRITE, absl::StatusCode::kInternal},
  };
  for (const Case& c : cases) {
    EXPECT_EQ(CodeForSqlite(c.rc), c.code) << sqlite3_errstr(c.rc);
  }
}

class SqliteHelpersTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string base = ::testing::TempDir();
    if (base.empty() || base.back() != '/') base += '/';
    std::string pattern = base + "sqlite_helpers_XXXXXX";
    ASSERT_NE(mkdtemp(pattern.data()), nullptr) << pattern;
    dir_ = pattern;
    path_ = dir_ + "/test.db";
    db_ = MustOpen(SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE);
    ASSERT_THAT(Exec(db_.get(),
                     "CREATE TABLE t (id INTEGER PRIMARY KEY, v BLOB) STRICT",
                     "create"),
                IsOk());
  }
  void TearDown() override {
    db_.reset();
    std::filesystem::remove_all(dir_);
  }

  Db MustOpen(int flags) {
    sqlite3* db = nullptr;
    EXPECT_EQ(sqlite3_open_v2(path_.c_str(), &db, flags, nullptr), SQLITE_OK);
    // As the store opens its connections (sqlite_event_store.cc).
    sqlite3_extended_result_codes(db, 1);
    return Db(db);
  }

  int64_t Count(sqlite3* db) {
    absl::StatusOr<int64_t> n = ReadInt(db, "SELECT COUNT(*) FROM t", "count");
    EXPECT_THAT(n, IsOk());
    return n.ok() ? *n : -1;
  }

  std::string dir_;
  std::string path_;
  Db db_;
};

TEST_F(SqliteHelpersTest, ErrorsCarryTheOperationAndTheConnectionsMessage) {
  ASSERT_THAT(Exec(db_.get(), "INSERT INTO t VALUES (1, x'00')", "first"),
              IsOk());
  EXPECT_THAT(
      Exec(db_.get(), "INSERT INTO t VALUES (1, x'01')", "adding row 1"),
      StatusIs(absl::StatusCode::kFailedPrecondition,
               AllOf(HasSubstr("adding row 1: "),
                     HasSubstr("UNIQUE constraint failed: t.id"),
                     HasSubstr("(sqlite code 1555)"))));
  EXPECT_THAT(Exec(db_.get(), "SELEC 1", "typo"),
              StatusIs(absl::StatusCode::kInternal,
                       AllOf(HasSubstr("typo: "), HasSubstr("syntax error"))));
  // A code that is not the connection's last: SQLite's text for the code.
  EXPECT_THAT(SqliteError(db_.get(), SQLITE_CORRUPT, "reading"),
              StatusIs(absl::StatusCode::kDataLoss,
                       AllOf(HasSubstr("reading: "),
                             HasSubstr(sqlite3_errstr(SQLITE_CORRUPT)),
                             HasSubstr("(sqlite code 11)"))));
  EXPECT_EQ(Count(db_.get()), 1);
}

TEST_F(SqliteHelpersTest, RefusedWritesAreStorageFaultsNamingTheFile) {
  const absl::Status full = SqliteError(db_.get(), SQLITE_FULL, "appending");
  EXPECT_TRUE(IsStorageFault(full));
  EXPECT_THAT(full,
              StatusIs(absl::StatusCode::kResourceExhausted,
                       AllOf(HasSubstr("appending: cannot write "),
                             HasSubstr(path_), HasSubstr("the disk is full"))));
  const absl::Status io = SqliteError(nullptr, SQLITE_IOERR_FSYNC, "syncing");
  EXPECT_TRUE(IsStorageFault(io));
  EXPECT_THAT(io, StatusIs(absl::StatusCode::kUnavailable,
                           AllOf(HasSubstr("cannot write the database"),
                                 HasSubstr("an I/O error"))));
  // A lock held past the busy timeout by another connection: the storage
  // takes no writes while it lasts.
  const absl::Status busy = SqliteError(db_.get(), SQLITE_BUSY, "x");
  EXPECT_TRUE(IsStorageFault(busy));
  EXPECT_THAT(busy, StatusIs(absl::StatusCode::kUnavailable,
                             AllOf(HasSubstr("x: cannot write "),
                                   HasSubstr("locked by another connection"))));
  // Anything else is no storage fault.
  EXPECT_FALSE(IsStorageFault(SqliteError(db_.get(), SQLITE_CONSTRAINT, "x")));

  // A real refusal: a write on a read-only connection.
  Db readonly = MustOpen(SQLITE_OPEN_READONLY);
  const absl::Status refused =
      Exec(readonly.get(), "INSERT INTO t VALUES (2, x'02')", "adding row 2");
  EXPECT_TRUE(IsStorageFault(refused)) << refused;
  EXPECT_THAT(refused,
              StatusIs(absl::StatusCode::kUnavailable,
                       AllOf(HasSubstr("adding row 2: cannot write "),
                             HasSubstr(path_), HasSubstr("read-only"))));
  EXPECT_EQ(Count(db_.get()), 0);
}

TEST_F(SqliteHelpersTest, BindErrorsSurfaceAtStepAndRunNothing) {
  absl::StatusOr<Statement> st =
      Statement::Prepare(db_.get(), "INSERT INTO t VALUES (?1, ?2)", "insert");
  ASSERT_THAT(st, IsOk());
  st->BindInt64(1, 5);
  st->BindBlob(3, "no such parameter");
  st->BindBlob(2, "later binds do not hide the first error");
  EXPECT_THAT(st->Step(), StatusIs(absl::StatusCode::kInvalidArgument,
                                   AllOf(HasSubstr("insert: "),
                                         HasSubstr("(sqlite code 25)"))));
  EXPECT_EQ(Count(db_.get()), 0);
  EXPECT_THAT(Statement::Prepare(db_.get(), "SELECT * FROM nowhere", "list"),
              StatusIs(absl::StatusCode::kInternal,
                       AllOf(HasSubstr("list: "), HasSubstr("nowhere"))));
}

TEST_F(SqliteHelpersTest, ValuesRoundTripAndAnEmptyBlobIsNotNull) {
  {
    absl::StatusOr<Statement> st = Statement::Prepare(
        db_.get(), "INSERT INTO t VALUES (?1, ?2)", "insert");
    ASSERT_THAT(st, IsOk());
    st->BindInt64(1, 1);
    st->BindBlob(2, "");
    ASSERT_THAT(st->Run(), IsOk());
  }
  {
    absl::StatusOr<Statement> st = Statement::Prepare(
        db_.get(), "INSERT INTO t VALUES (?1, ?2)", "insert");
    ASSERT_THAT(st, IsOk());
    st->BindInt64(1, 2);
    st->BindNull(2);
    ASSERT_THAT(st->Run(), IsOk());
  }
  EXPECT_EQ(*ReadInt(db_.get(), "SELECT COUNT(*) FROM t WHERE v IS NULL", "n"),
            1);
  EXPECT_EQ(*ReadInt(db_.get(), "SELECT id FROM t WHERE v = x''", "n"), 1);

  absl::StatusOr<Statement> st =
      Statement::Prepare(db_.get(), "SELECT ?1, ?2, ?3, ?4, ?5", "select");
  ASSERT_THAT(st, IsOk());
  const std::string text("a\0b\xc3\xbc", 5);
  const std::string blob("\0\xff\x01", 3);
  st->BindInt64(1, INT64_MIN);
  st->BindDouble(2, -0.1);
  st->BindText(3, text);
  st->BindBlob(4, blob);
  st->BindNull(5);
  absl::StatusOr<bool> row = st->Step();
  ASSERT_THAT(row, IsOk());
  ASSERT_TRUE(*row);
  EXPECT_EQ(st->Int64(0), INT64_MIN);
  EXPECT_EQ(st->Double(1), -0.1);
  EXPECT_EQ(st->Text(2), text);
  EXPECT_EQ(std::string(st->Blob(3)), blob);
  EXPECT_TRUE(st->IsNull(4));
  EXPECT_FALSE(st->IsNull(3));
  EXPECT_EQ(st->Text(4), "");
  EXPECT_EQ(*st->Step(), false);
}

TEST_F(SqliteHelpersTest, ReadIntWithoutARowIsAnErrorNamingTheOperation) {
  EXPECT_EQ(*ReadInt(db_.get(), "PRAGMA user_version", "version"), 0);
  EXPECT_THAT(
      ReadInt(db_.get(), "SELECT id FROM t", "first id"),
      StatusIs(absl::StatusCode::kInternal, HasSubstr("first id: no result")));
}

TEST_F(SqliteHelpersTest, CachedStatementsAreResetAndNeverSharedWhileInUse) {
  StatementCache cache(db_.get());
  const std::string sql = "SELECT ?1";
  {
    absl::StatusOr<Statement> first = cache.Get(sql, "echo");
    ASSERT_THAT(first, IsOk());
    first->BindInt64(1, 7);
    ASSERT_TRUE(*first->Step());
    // The same text while the first is still in use: a statement of its own.
    absl::StatusOr<Statement> second = cache.Get(sql, "echo");
    ASSERT_THAT(second, IsOk());
    second->BindInt64(1, 8);
    ASSERT_TRUE(*second->Step());
    EXPECT_EQ(first->Int64(0), 7);
    EXPECT_EQ(second->Int64(0), 8);
  }
  // Back from the cache: reset, its parameters cleared.
  absl::StatusOr<Statement> again = cache.Get(sql, "echo");
  ASSERT_THAT(again, IsOk());
  ASSERT_TRUE(*again->Step());
  EXPECT_TRUE(again->IsNull(0));
  EXPECT_THAT(cache.Get("SELECT FROM", "broken"),
              StatusIs(absl::StatusCode::kInternal, HasSubstr("broken: ")));
}

TEST_F(SqliteHelpersTest, TransactionsRollBackUnlessCommitted) {
  {
    absl::StatusOr<Transaction> tx =
        Transaction::Begin(db_.get(), Transaction::Kind::kWrite, "write");
    ASSERT_THAT(tx, IsOk());
    ASSERT_THAT(Exec(db_.get(), "INSERT INTO t VALUES (1, x'01')", "insert"),
                IsOk());
    EXPECT_EQ(Count(db_.get()), 1);
  }  // an early return: not committed
  EXPECT_EQ(Count(db_.get()), 0);
  EXPECT_NE(sqlite3_get_autocommit(db_.get()), 0);
  {
    absl::StatusOr<Transaction> tx =
        Transaction::Begin(db_.get(), Transaction::Kind::kWrite, "write");
    ASSERT_THAT(tx, IsOk());
    ASSERT_THAT(Exec(db_.get(), "INSERT INTO t VALUES (2, x'02')", "insert"),
                IsOk());
    ASSERT_THAT(tx->Commit(), IsOk());
  }
  Db other = MustOpen(SQLITE_OPEN_READWRITE);
  EXPECT_EQ(Count(other.get()), 1);
}

TEST_F(SqliteHelpersTest, AWriteTransactionTakesTheLockUpFront) {
  absl::StatusOr<Transaction> held =
      Transaction::Begin(db_.get(), Transaction::Kind::kWrite, "holder");
  ASSERT_THAT(held, IsOk());
  Db other = MustOpen(SQLITE_OPEN_READWRITE);
  // A second writer is refused at BEGIN, before it does anything.
  EXPECT_THAT(Transaction::Begin(other.get(), Transaction::Kind::kWrite,
                                 "second writer"),
              StatusIs(absl::StatusCode::kUnavailable,
                       AllOf(HasSubstr("second writer: "),
                             HasSubstr("database is locked"))));
  // A reader is not.
  {
    absl::StatusOr<Transaction> reader =
        Transaction::Begin(other.get(), Transaction::Kind::kRead, "reader");
    ASSERT_THAT(reader, IsOk());
    EXPECT_EQ(Count(other.get()), 0);
  }
  ASSERT_THAT(held->Commit(), IsOk());
  EXPECT_THAT(Transaction::Begin(other.get(), Transaction::Kind::kWrite,
                                 "second writer"),
              IsOk());
}

}  // namespace
}  // namespace bitewise::bandit::sqlite
