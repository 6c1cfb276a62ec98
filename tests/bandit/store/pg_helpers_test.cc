// The PostgreSQL helpers (pg_helpers.h) against a real server the test
// starts: values sent and read in binary bit for bit, SQLSTATEs as status
// codes naming the database and the operation, transactions, a server that
// stops answering, and a pool whose lost connections are restored.
#include "services/bandit/store/pg_helpers.h"

#include <cstdint>
#include <cstring>
#include <limits>
#include <memory>
#include <string>
#include <thread>

#include "absl/strings/str_cat.h"
#include "absl/synchronization/notification.h"
#include "absl/time/clock.h"
#include "absl/time/time.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "services/bandit/store/write_faults.h"
#include "tests/common/postgres_server.h"
#include "tests/common/status_matchers.h"

namespace bitewise::bandit::pg {
namespace {

using ::bitewise::testing::IsOk;
using ::bitewise::testing::StatusIs;
using ::testing::AllOf;
using ::testing::HasSubstr;
using ::testing::Not;

uint64_t BitsOf(double value) {
  uint64_t bits;
  std::memcpy(&bits, &value, sizeof(bits));
  return bits;
}

class PgHelpersTest : public ::testing::Test {
 protected:
  void SetUp() override {
    server_ = ::bitewise::testing::SharedTestPostgres();
    ASSERT_NE(server_, nullptr);
    static int databases = 0;
    database_ = absl::StrCat("pg_helpers_test_", ++databases);
    absl::StatusOr<std::string> conninfo = server_->CreateDatabase(database_);
    ASSERT_THAT(conninfo, IsOk());
    conninfo_ = *conninfo;
    conn_ = MustConnect();
    ASSERT_NE(conn_, nullptr);
    ASSERT_THAT(conn_->ExecScript("CREATE TABLE t (id int8 PRIMARY KEY, "
                                  "v float8 CHECK (v >= 0))",
                                  "create"),
                IsOk());
  }

  void TearDown() override {
    conn_.reset();
    server_->Query("postgres", absl::StrCat("DROP DATABASE ", database_))
        .IgnoreError();
  }

  std::unique_ptr<Connection> MustConnect() {
    absl::StatusOr<std::unique_ptr<Connection>> conn =
        Connection::Open(conninfo_);
    EXPECT_THAT(conn, IsOk());
    return conn.ok() ? std::move(conn).value() : nullptr;
  }

  // The first column of the only row of `sql` on `conn`, as an integer.
  int64_t Int(Connection& conn, const std::string& sql) {
    absl::StatusOr<Rows> rows = conn.Exec(sql, "int");
    EXPECT_THAT(rows, IsOk());
    if (!rows.ok() || !rows->Next()) return -1;
    return rows->Int64(0);
  }

  // Ends `conn`'s server process, as a server restart or an administrator
  // would, and waits until `conn` has seen its end of the socket close (so
  // what follows does not race the server's exit).
  void Terminate(Connection& conn) {
    const int64_t pid = Int(conn, "SELECT pg_backend_pid()");
    absl::StatusOr<std::string> done = server_->Query(
        "postgres", absl::StrCat("SELECT pg_terminate_backend(", pid, ")"));
    ASSERT_THAT(done, IsOk());
    ASSERT_EQ(*done, "t");
    const absl::Time deadline = absl::Now() + absl::Seconds(30);
    while (!conn.broken() && absl::Now() < deadline) {
      absl::SleepFor(absl::Milliseconds(10));
      conn.Probe();
    }
    ASSERT_TRUE(conn.broken()) << "backend " << pid << " did not go";
  }

  ::bitewise::testing::TestPostgres* server_ = nullptr;
  std::string database_;
  std::string conninfo_;
  std::unique_ptr<Connection> conn_;
};

TEST_F(PgHelpersTest, ValuesCrossInBinaryBitForBit) {
  const double nan_payload = [] {
    const uint64_t bits = 0x7ff8000000000123;
    double value;
    std::memcpy(&value, &bits, sizeof(value));
    return value;
  }();
  const std::string text("\xc3\xbc tab\t\x01", 8);
  const std::string bytes("\0\xff\x00z", 4);
  Params params;
  params.Int64(std::numeric_limits<int64_t>::min())
      .Double(-0.0)
      .Double(nan_payload)
      .Double(std::numeric_limits<double>::denorm_min())
      .Bool(true)
      .Text(text)
      .Bytes(bytes)
      .Bytes("")
      .NullBytes();
  ASSERT_EQ(params.size(), 9);
  absl::StatusOr<Rows> rows =
      conn_->Exec("SELECT $1, $2, $3, $4, $5, $6, $7, $8, $9", params, "echo");
  ASSERT_THAT(rows, IsOk());
  ASSERT_EQ(rows->size(), 1);
  ASSERT_TRUE(rows->Next());
  EXPECT_EQ(rows->Int64(0), std::numeric_limits<int64_t>::min());
  EXPECT_EQ(BitsOf(rows->Double(1)), BitsOf(-0.0));
  EXPECT_EQ(BitsOf(rows->Double(2)), BitsOf(nan_payload));
  EXPECT_EQ(BitsOf(rows->Double(3)),
            BitsOf(std::numeric_limits<double>::denorm_min()));
  EXPECT_EQ(rows->Int64(4), 1);
  EXPECT_EQ(rows->Text(5), text);
  EXPECT_EQ(std::string(rows->Blob(6)), bytes);
  // An empty value is not NULL.
  EXPECT_FALSE(rows->IsNull(7));
  EXPECT_EQ(rows->Blob(7).size(), 0u);
  EXPECT_TRUE(rows->IsNull(8));
  EXPECT_EQ(rows->Int64(8), 0);
  EXPECT_EQ(rows->Text(8), "");
  EXPECT_FALSE(rows->Next());
}

TEST_F(PgHelpersTest, IntegersOfEveryWidthAndRowsInOrder) {
  absl::StatusOr<Rows> rows = conn_->Exec(
      "SELECT (-2)::int2, (-70000)::int4, 5000000000::int8, false, "
      "1.5::float4 FROM generate_series(1, 3)",
      "widths");
  ASSERT_THAT(rows, IsOk());
  EXPECT_EQ(rows->size(), 3);
  int read = 0;
  while (rows->Next()) {
    ++read;
    EXPECT_EQ(rows->Int64(0), -2);
    EXPECT_EQ(rows->Int64(1), -70000);
    EXPECT_EQ(rows->Int64(2), 5000000000);
    EXPECT_EQ(rows->Int64(3), 0);
    // A float4 is not the float8 the stores keep: it reads as 0.
    EXPECT_EQ(rows->Double(4), 0.0);
  }
  EXPECT_EQ(read, 3);
}

TEST_F(PgHelpersTest, EachStatementIsPreparedOnceAndSessionsCommitDurably) {
  for (int i = 1; i <= 3; ++i) {
    ASSERT_THAT(conn_->Exec("INSERT INTO t VALUES ($1, $2)",
                            Params().Int64(i).Double(0.5 * i), "insert"),
                IsOk());
  }
  EXPECT_EQ(Int(*conn_, "SELECT count(*) FROM t"), 3);
  // INSERT, the count, and this query.
  EXPECT_EQ(Int(*conn_, "SELECT count(*) FROM pg_prepared_statements"), 3);
  absl::StatusOr<Rows> setting =
      conn_->Exec("SELECT current_setting('synchronous_commit')", "setting");
  ASSERT_THAT(setting, IsOk());
  ASSERT_TRUE(setting->Next());
  EXPECT_EQ(setting->Text(0), "on");
}

TEST_F(PgHelpersTest, ErrorsNameTheOperationTheDatabaseAndTheSqlstate) {
  ASSERT_THAT(conn_->Exec("INSERT INTO t VALUES ($1, $2)",
                          Params().Int64(1).Double(1), "insert"),
              IsOk());
  EXPECT_THAT(conn_->Exec("INSERT INTO t VALUES ($1, $2)",
                          Params().Int64(1).Double(2), "adding row 1"),
              StatusIs(absl::StatusCode::kAlreadyExists,
                       AllOf(HasSubstr("adding row 1: PostgreSQL database \"" +
                                       database_ + "\" at "),
                             HasSubstr("duplicate key"),
                             HasSubstr("(SQLSTATE 23505)"))));
  EXPECT_THAT(
      conn_->Exec("INSERT INTO t VALUES ($1, $2)", Params().Int64(2).Double(-1),
                  "negative"),
      StatusIs(absl::StatusCode::kFailedPrecondition,
               AllOf(HasSubstr("negative: "), HasSubstr("check constraint"),
                     HasSubstr("(SQLSTATE 23514)"))));
  EXPECT_THAT(
      conn_->Exec("SELECT 1 / $1", Params().Int64(0), "dividing"),
      StatusIs(absl::StatusCode::kInvalidArgument,
               AllOf(HasSubstr("dividing: "), HasSubstr("division by zero"),
                     HasSubstr("(SQLSTATE 22012)"))));
  EXPECT_THAT(conn_->Exec("SELECT * FROM nowhere", "listing"),
              StatusIs(absl::StatusCode::kInternal,
                       AllOf(HasSubstr("listing: "), HasSubstr("nowhere"),
                             HasSubstr("(SQLSTATE 42P01)"))));
  // Nothing of the failed statements was kept.
  EXPECT_EQ(Int(*conn_, "SELECT count(*) FROM t"), 1);
}

// The SQLSTATE of an error the server raises, as the store sees it.
absl::Status Raised(Connection& conn, const std::string& sqlstate) {
  return conn.ExecScript(
      absl::StrCat("DO $$ BEGIN RAISE EXCEPTION 'raised %', '", sqlstate,
                   "' USING ERRCODE = '", sqlstate, "'; END $$"),
      "raising");
}

TEST_F(PgHelpersTest, SqlstatesMapToTheCodeTheirRemedyNeeds) {
  struct Case {
    const char* sqlstate;
    absl::StatusCode code;
    bool storage_fault;
  };
  const Case cases[] = {
      {"40001", absl::StatusCode::kAborted, false},  // serialization
      {"40P01", absl::StatusCode::kAborted, false},  // deadlock
      {"23503", absl::StatusCode::kFailedPrecondition, false},
      {"22003", absl::StatusCode::kInvalidArgument, false},
      {"53200", absl::StatusCode::kResourceExhausted, false},  // memory
      {"57014", absl::StatusCode::kDeadlineExceeded, false},
      {"XX001", absl::StatusCode::kDataLoss, false},  // data corrupted
      {"XX002", absl::StatusCode::kDataLoss, false},  // index corrupted
      {"XX000", absl::StatusCode::kInternal, false},
      {"42601", absl::StatusCode::kInternal, false},
      // Contention: retry later, the server itself is fine.
      {"55P03", absl::StatusCode::kUnavailable, false},
      {"53300", absl::StatusCode::kUnavailable, false},
      // The server cannot take writes.
      {"57P01", absl::StatusCode::kUnavailable, true},
      {"53100", absl::StatusCode::kResourceExhausted, true},
      {"58030", absl::StatusCode::kUnavailable, true},
      {"25006", absl::StatusCode::kUnavailable, true},
  };
  for (const Case& c : cases) {
    const absl::Status status = Raised(*conn_, c.sqlstate);
    EXPECT_EQ(status.code(), c.code) << c.sqlstate << ": " << status;
    EXPECT_EQ(IsStorageFault(status), c.storage_fault) << status;
    EXPECT_THAT(status.message(),
                AllOf(HasSubstr("raising"), HasSubstr("raised"),
                      HasSubstr(absl::StrCat("(SQLSTATE ", c.sqlstate, ")")),
                      HasSubstr("database \"" + database_ + "\"")));
  }
  EXPECT_THAT(Raised(*conn_, "53100").message(), HasSubstr("out of space"));
  EXPECT_THAT(Raised(*conn_, "25006").message(), HasSubstr("read-only"));
  EXPECT_THAT(Raised(*conn_, "58030").message(), HasSubstr("I/O error"));
}

TEST_F(PgHelpersTest, AReadOnlyTransactionRefusesWritesAsAStorageFault) {
  absl::StatusOr<Transaction> tx =
      Transaction::Begin(*conn_, "read", "READ ONLY");
  ASSERT_THAT(tx, IsOk());
  const absl::StatusOr<Rows> write = conn_->Exec(
      "INSERT INTO t VALUES ($1, $2)", Params().Int64(1).Double(1), "writing");
  EXPECT_THAT(write, StatusIs(absl::StatusCode::kUnavailable,
                              HasSubstr("the server is read-only")));
  EXPECT_TRUE(IsStorageFault(write.status()));
}

TEST_F(PgHelpersTest, TransactionsRollBackUnlessCommittedAndFailedOnesAbort) {
  {
    absl::StatusOr<Transaction> tx = Transaction::Begin(*conn_, "write");
    ASSERT_THAT(tx, IsOk());
    EXPECT_TRUE(conn_->in_transaction());
    ASSERT_THAT(conn_->Exec("INSERT INTO t VALUES ($1, $2)",
                            Params().Int64(1).Double(1), "insert"),
                IsOk());
  }  // not committed
  EXPECT_FALSE(conn_->in_transaction());
  EXPECT_EQ(Int(*conn_, "SELECT count(*) FROM t"), 0);

  {
    absl::StatusOr<Transaction> tx = Transaction::Begin(*conn_, "write");
    ASSERT_THAT(tx, IsOk());
    ASSERT_THAT(conn_->Exec("INSERT INTO t VALUES ($1, $2)",
                            Params().Int64(1).Double(1), "insert"),
                IsOk());
    // A failed statement fails the transaction: COMMIT would roll back
    // and report success, so Commit says ABORTED instead.
    EXPECT_THAT(conn_->Exec("INSERT INTO t VALUES ($1, $2)",
                            Params().Int64(2).Double(-1), "insert"),
                Not(IsOk()));
    EXPECT_TRUE(conn_->transaction_failed());
    EXPECT_THAT(tx->Commit(),
                StatusIs(absl::StatusCode::kAborted,
                         HasSubstr("write: the transaction failed and was "
                                   "rolled back")));
  }
  EXPECT_FALSE(conn_->in_transaction());
  EXPECT_EQ(Int(*conn_, "SELECT count(*) FROM t"), 0);

  {
    absl::StatusOr<Transaction> tx = Transaction::Begin(*conn_, "write");
    ASSERT_THAT(tx, IsOk());
    ASSERT_THAT(conn_->Exec("INSERT INTO t VALUES ($1, $2)",
                            Params().Int64(3).Double(1), "insert"),
                IsOk());
    ASSERT_THAT(tx->Commit(), IsOk());
  }
  std::unique_ptr<Connection> other = MustConnect();
  ASSERT_NE(other, nullptr);
  EXPECT_EQ(Int(*other, "SELECT id FROM t"), 3);
}

TEST_F(PgHelpersTest, AScriptAnswersWithItsFirstErrorAndWritesNothing) {
  // Statements of a script run as one transaction; the first error is the
  // answer (not a later statement's), as PQexec gave it.
  const absl::Status failed = conn_->ExecScript(
      "INSERT INTO t VALUES (1, 1); INSERT INTO t VALUES (2, -1); "
      "INSERT INTO t VALUES (3, 3)",
      "script");
  EXPECT_THAT(failed, StatusIs(absl::StatusCode::kFailedPrecondition,
                               AllOf(HasSubstr("script"), HasSubstr("23514"))));
  EXPECT_EQ(Int(*conn_, "SELECT count(*) FROM t"), 0);
  ASSERT_THAT(conn_->ExecScript("INSERT INTO t VALUES (1, 1); INSERT INTO t "
                                "VALUES (2, 2)",
                                "script"),
              IsOk());
  EXPECT_EQ(Int(*conn_, "SELECT count(*) FROM t"), 2);
}

// A server that stops answering (a stopped process, whose kernel still
// takes the bytes) used to hold the call, its pooled connection and the
// health check for ever.
TEST_F(PgHelpersTest, AServerThatStopsAnsweringFailsTheCallAndIsLetGo) {
  absl::StatusOr<std::unique_ptr<Connection>> conn =
      Connection::Open(conninfo_, absl::Seconds(1));
  ASSERT_THAT(conn, IsOk());
  ASSERT_THAT((*conn)->Exec("SELECT 1", "warm"), IsOk());
  absl::Duration waited;
  {
    absl::StatusOr<std::unique_ptr<::bitewise::testing::TestPostgres::Frozen>>
        frozen = server_->Freeze();
    ASSERT_THAT(frozen, IsOk());
    const absl::Time start = absl::Now();
    const absl::StatusOr<Rows> hung = (*conn)->Exec("SELECT 2", "a read");
    waited = absl::Now() - start;
    EXPECT_THAT(hung, StatusIs(absl::StatusCode::kUnavailable,
                               AllOf(HasSubstr("database \"" + database_),
                                     HasSubstr("did not answer within 1s "
                                               "(a read); the connection was "
                                               "closed"))));
    EXPECT_TRUE(IsStorageFault(hung.status()));
    EXPECT_TRUE((*conn)->broken());
  }
  // A bound on a hang, not a measure of speed: one timeout and a margin.
  EXPECT_GE(waited, absl::Seconds(1));
  EXPECT_LT(waited, absl::Seconds(20));
  ASSERT_THAT((*conn)->Reconnect(), IsOk());
  EXPECT_EQ(Int(**conn, "SELECT 3"), 3);
}

TEST_F(PgHelpersTest, TheWaitIsForTheNextBytesNotForTheWholeAnswer) {
  absl::StatusOr<std::unique_ptr<Connection>> conn =
      Connection::Open(conninfo_, absl::Seconds(1));
  ASSERT_THAT(conn, IsOk());
  // A statement that runs 2 s but says something every 0.3 s is waited
  // for; one silent for 1.5 s is not.
  ASSERT_THAT((*conn)->ExecScript("SET client_min_messages = notice", "set"),
              IsOk());
  EXPECT_THAT((*conn)->ExecScript(
                  "DO $$ BEGIN FOR i IN 1..7 LOOP PERFORM pg_sleep(0.3); "
                  "RAISE NOTICE 'still here'; END LOOP; END $$",
                  "talking"),
              IsOk());
  EXPECT_THAT((*conn)->Exec("SELECT pg_sleep(1.5)", "silent"),
              StatusIs(absl::StatusCode::kUnavailable,
                       HasSubstr("did not answer within 1s (silent)")));
}

TEST_F(PgHelpersTest, ACommitTheServerNeverAnsweredMayStillBeApplied) {
  absl::StatusOr<std::unique_ptr<Connection>> conn =
      Connection::Open(conninfo_, absl::Seconds(1));
  ASSERT_THAT(conn, IsOk());
  {
    absl::StatusOr<Transaction> tx = Transaction::Begin(**conn, "completing");
    ASSERT_THAT(tx, IsOk());
    ASSERT_THAT((*conn)->Exec("INSERT INTO t VALUES ($1, $2)",
                              Params().Int64(1).Double(1), "insert"),
                IsOk());
    absl::StatusOr<std::unique_ptr<::bitewise::testing::TestPostgres::Frozen>>
        frozen = server_->Freeze();
    ASSERT_THAT(frozen, IsOk());
    const absl::Status committed = tx->Commit();
    EXPECT_THAT(committed,
                StatusIs(absl::StatusCode::kUnavailable,
                         AllOf(HasSubstr("did not answer within 1s"),
                               HasSubstr("the outcome is unknown: it may have "
                                         "been applied. Retrying is safe"))));
    EXPECT_TRUE(IsStorageFault(committed));
  }
  // The COMMIT was sent before the server stopped: once it goes on, it
  // commits, which is why the error cannot say that nothing was written.
  std::string count;
  const absl::Time deadline = absl::Now() + absl::Seconds(20);
  while (absl::Now() < deadline) {
    count = server_->Query(database_, "SELECT count(*) FROM t").value_or("");
    if (count == "1") break;
    absl::SleepFor(absl::Milliseconds(50));
  }
  EXPECT_EQ(count, "1");
}

TEST_F(PgHelpersTest, NoServerIsUnavailableOnOneLineNamingWhereItLooked) {
  absl::StatusOr<std::unique_ptr<Connection>> absent = Connection::Open(
      absl::StrCat("postgresql:///nothing?host=", server_->dir(), "&port=1"));
  ASSERT_FALSE(absent.ok());
  EXPECT_TRUE(IsStorageFault(absent.status()));
  EXPECT_THAT(absent.status(),
              StatusIs(absl::StatusCode::kUnavailable,
                       AllOf(HasSubstr("PostgreSQL database \"nothing\" at "),
                             HasSubstr(":1 is unavailable: "))));
  EXPECT_EQ(absent.status().message().find('\n'), absl::string_view::npos)
      << absent.status();
}

TEST_F(PgHelpersTest, ALostConnectionIsUnavailableAndReconnects) {
  ASSERT_THAT(conn_->Exec("SELECT 1", "warm"), IsOk());
  Terminate(*conn_);
  const absl::StatusOr<Rows> lost = conn_->Exec("SELECT 2", "after the loss");
  EXPECT_THAT(lost, StatusIs(absl::StatusCode::kUnavailable,
                             AllOf(HasSubstr("after the loss"),
                                   HasSubstr("database \"" + database_))));
  EXPECT_TRUE(conn_->broken());
  ASSERT_THAT(conn_->Reconnect(), IsOk());
  EXPECT_FALSE(conn_->broken());
  // Its statements are prepared again on the new session.
  EXPECT_EQ(Int(*conn_, "SELECT 1"), 1);
}

TEST_F(PgHelpersTest, ABeginOnALostConnectionReconnectsOnce) {
  ASSERT_THAT(conn_->Exec("SELECT 1", "warm"), IsOk());
  const int64_t before = Int(*conn_, "SELECT pg_backend_pid()");
  Terminate(*conn_);
  {
    absl::StatusOr<Transaction> tx = Transaction::Begin(*conn_, "begin");
    ASSERT_THAT(tx, IsOk());
    ASSERT_THAT(conn_->Exec("INSERT INTO t VALUES ($1, $2)",
                            Params().Int64(1).Double(1), "insert"),
                IsOk());
    ASSERT_THAT(tx->Commit(), IsOk());
  }
  EXPECT_NE(Int(*conn_, "SELECT pg_backend_pid()"), before);
  EXPECT_EQ(Int(*conn_, "SELECT count(*) FROM t"), 1);
}

TEST_F(PgHelpersTest, ACommitOnALostConnectionSaysTheOutcomeIsUnknown) {
  absl::StatusOr<Transaction> tx = Transaction::Begin(*conn_, "completing");
  ASSERT_THAT(tx, IsOk());
  ASSERT_THAT(conn_->Exec("INSERT INTO t VALUES ($1, $2)",
                          Params().Int64(1).Double(1), "insert"),
              IsOk());
  Terminate(*conn_);
  const absl::Status committed = tx->Commit();
  EXPECT_THAT(committed, StatusIs(absl::StatusCode::kUnavailable,
                                  HasSubstr("the outcome is unknown")));
  EXPECT_TRUE(IsStorageFault(committed));
  EXPECT_EQ(*server_->Query(database_, "SELECT count(*) FROM t"), "0");
}

TEST_F(PgHelpersTest, APoolLendsEachConnectionOnceAndRestoresLostOnes) {
  absl::StatusOr<std::unique_ptr<Pool>> pool = Pool::Open(conninfo_, 1);
  ASSERT_THAT(pool, IsOk());
  EXPECT_THAT((*pool)->description(), HasSubstr("database \"" + database_));
  int64_t first_pid = 0;
  absl::Notification acquired;
  std::thread waiter;
  {
    absl::StatusOr<Pool::Lease> lease = (*pool)->Acquire("first");
    ASSERT_THAT(lease, IsOk());
    first_pid = Int(**lease, "SELECT pg_backend_pid()");
    // The only connection is lent: a second caller waits for it.
    waiter = std::thread([&] {
      absl::StatusOr<Pool::Lease> second = (*pool)->Acquire("second");
      EXPECT_THAT(second, IsOk());
      acquired.Notify();
    });
    EXPECT_FALSE(acquired.WaitForNotificationWithTimeout(absl::Seconds(0.3)));
    Terminate(**lease);
  }
  EXPECT_TRUE(acquired.WaitForNotificationWithTimeout(absl::Seconds(10)));
  waiter.join();
  // The connection the server ended is restored before it is lent again.
  absl::StatusOr<Pool::Lease> again = (*pool)->Acquire("again");
  ASSERT_THAT(again, IsOk());
  EXPECT_FALSE((*again)->broken());
  const int64_t pid = Int(**again, "SELECT pg_backend_pid()");
  EXPECT_GT(pid, 0);
  EXPECT_NE(pid, first_pid);
}

}  // namespace
}  // namespace bitewise::bandit::pg
