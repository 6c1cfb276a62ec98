// PostgreSQL helpers (internal to services/bandit/store): a libpq
// connection that prepares each statement once and sends and reads every
// value in binary (so doubles cross bit for bit), a small pool of such
// connections, transactions that roll back unless committed, and the
// mapping of PostgreSQL's errors (SQLSTATE) to absl::Status codes with a
// message naming the database and the operation.
#ifndef BITEWISE_SERVICES_BANDIT_STORE_PG_HELPERS_H_
#define BITEWISE_SERVICES_BANDIT_STORE_PG_HELPERS_H_

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "absl/base/thread_annotations.h"
#include "absl/container/flat_hash_map.h"
#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "absl/synchronization/mutex.h"
#include "absl/time/time.h"

struct pg_conn;
struct pg_result;

namespace bitewise::bandit::pg {

// A statement's parameters, each sent in binary with its type.
class Params {
 public:
  Params& Int64(int64_t value);
  Params& Double(double value);
  Params& Bool(bool value);
  Params& Text(absl::string_view value);
  Params& Bytes(absl::string_view value);
  Params& NullBytes();

  int size() const { return static_cast<int>(types_.size()); }
  const unsigned int* types() const { return types_.data(); }
  const int* lengths() const { return lengths_.data(); }
  const int* formats() const { return formats_.data(); }
  // Pointers into the stored values, valid while this object is unchanged.
  std::vector<const char*> values() const;

 private:
  Params& Add(unsigned int type, std::string bytes, bool null = false);
  std::vector<std::string> storage_;
  std::vector<bool> nulls_;
  std::vector<unsigned int> types_;
  std::vector<int> lengths_;
  std::vector<int> formats_;
};

// The rows of a statement's result, read in binary. Next() moves to the
// first row, then on; the accessors read the current row (as
// sqlite::Statement does, so store_rows' readers take either). A NULL or a
// value of an unexpected width reads as 0 or empty.
class Rows {
 public:
  explicit Rows(pg_result* result);
  Rows(Rows&& other) noexcept;
  Rows& operator=(Rows&& other) noexcept;
  ~Rows();

  int size() const;
  bool Next();
  bool IsNull(int col) const;
  int64_t Int64(int col) const;  // int2, int4, int8 or bool
  double Double(int col) const;
  std::string Text(int col) const;
  absl::string_view Blob(int col) const;

 private:
  friend class Connection;
  pg_result* result_;
  int row_ = -1;
};

class Connection {
 public:
  // Connects (connect_timeout 5 s unless the string sets one) and sets
  // synchronous_commit on for the session, so a commit returns only once
  // it is flushed to disk whatever the database's default.
  //
  // Every statement then waits at most `response_timeout` for the server's
  // next bytes (not for its whole answer): a server that stops answering
  // (a stopped process, whose kernel still acknowledges) fails the call
  // with UNAVAILABLE, a storage fault naming the database, the wait and the
  // operation, and the connection is closed (the next use reconnects).
  static absl::StatusOr<std::unique_ptr<Connection>> Open(
      const std::string& conninfo,
      absl::Duration response_timeout = kDefaultResponseTimeout);
  static constexpr absl::Duration kDefaultResponseTimeout = absl::Seconds(30);
  Connection(const Connection&) = delete;
  Connection& operator=(const Connection&) = delete;
  ~Connection();

  // Runs one statement (prepared on this connection the first time its
  // text is seen) and returns its rows. `op` names the calling operation.
  absl::StatusOr<Rows> Exec(absl::string_view sql, const Params& params,
                            absl::string_view op);
  absl::StatusOr<Rows> Exec(absl::string_view sql, absl::string_view op) {
    return Exec(sql, Params(), op);
  }
  // Runs statements without parameters (a script), unprepared.
  absl::Status ExecScript(absl::string_view sql, absl::string_view op);

  // Whether the connection is lost; Reconnect tries once to restore it.
  bool broken() const;
  // Reads what the server sent while the connection sat idle, without
  // blocking, so that one the server closed (a restart) shows as broken()
  // before a statement is sent on it.
  void Probe();
  absl::Status Reconnect();
  // Whether a transaction is open (or failed and not yet rolled back), and
  // whether it failed.
  bool in_transaction() const;
  bool transaction_failed() const;
  // "database NAME on HOST:PORT" for messages.
  const std::string& description() const { return description_; }

 private:
  Connection(pg_conn* conn, std::string conninfo,
             absl::Duration response_timeout);
  absl::Status Error(pg_result* result, absl::string_view op) const;
  // The name `sql` is prepared under on this connection, preparing it the
  // first time.
  absl::StatusOr<std::string> Prepared(absl::string_view sql,
                                       const Params& params,
                                       absl::string_view op);
  // The result of the statement just sent (a script's first error, else
  // its last result), waiting for the server as Open says; nullptr when
  // the connection was lost or the wait given up (timed_out_).
  pg_result* Await();
  void Describe();

  pg_conn* conn_;
  const std::string conninfo_;
  std::string description_;
  absl::flat_hash_map<std::string, std::string> prepared_;
  const absl::Duration response_timeout_;
  bool closed_ = false;     // Probe found the server's end closed
  bool timed_out_ = false;  // Await gave up on the server
};

// A fixed set of connections shared by the store's callers. A caller holds
// one for a whole transaction.
class Pool {
 public:
  static absl::StatusOr<std::unique_ptr<Pool>> Open(
      const std::string& conninfo, int size,
      absl::Duration response_timeout = Connection::kDefaultResponseTimeout);

  class Lease {
   public:
    Lease(Pool* pool, Connection* conn) : pool_(pool), conn_(conn) {}
    Lease(Lease&& other) noexcept
        : pool_(other.pool_), conn_(std::exchange(other.conn_, nullptr)) {}
    Lease& operator=(Lease&&) = delete;
    ~Lease() {
      if (conn_ != nullptr) pool_->Release(conn_);
    }
    Connection* operator->() const { return conn_; }
    Connection& operator*() const { return *conn_; }

   private:
    Pool* pool_;
    Connection* conn_;
  };

  // Waits for a free connection; one that was lost is reconnected first
  // (UNAVAILABLE naming the database if that fails).
  absl::StatusOr<Lease> Acquire(absl::string_view op);
  const std::string& description() const { return description_; }

 private:
  void Release(Connection* conn);

  absl::Mutex mu_;
  std::vector<std::unique_ptr<Connection>> all_;
  std::vector<Connection*> free_ ABSL_GUARDED_BY(mu_);
  std::string description_;
};

// BEGIN on construction (with `mode`, e.g. "ISOLATION LEVEL REPEATABLE
// READ READ ONLY"), ROLLBACK on destruction unless committed.
class Transaction {
 public:
  static absl::StatusOr<Transaction> Begin(Connection& conn,
                                           absl::string_view op,
                                           absl::string_view mode = "");
  Transaction(Transaction&& other) noexcept
      : conn_(std::exchange(other.conn_, nullptr)), op_(other.op_) {}
  Transaction& operator=(Transaction&&) = delete;
  ~Transaction();
  // UNAVAILABLE if the connection was lost while committing: the outcome
  // is then unknown to this process (docs/operations.md).
  absl::Status Commit();

 private:
  Transaction(Connection* conn, absl::string_view op) : conn_(conn), op_(op) {}
  Connection* conn_;
  std::string op_;
};

// What a caller may do after a write whose outcome is unknown.
inline constexpr char kRetryAfterUnknownOutcome[] =
    "Retrying is safe: a retried Update that was applied answers OK with "
    "already_applied";

// `status`, or, when it failed and `conn` was lost meanwhile (a statement
// that commits by itself, or COMMIT), a storage fault saying that the
// outcome is unknown, then `retry` (what a retry does).
absl::Status OutcomeUnknownIfLost(const Connection& conn, absl::Status status,
                                  absl::string_view retry);

}  // namespace bitewise::bandit::pg

#endif  // BITEWISE_SERVICES_BANDIT_STORE_PG_HELPERS_H_
