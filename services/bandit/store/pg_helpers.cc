#include "services/bandit/store/pg_helpers.h"

#include <libpq-fe.h>
#include <poll.h>
#include <sys/socket.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <utility>
#include <vector>

#include "absl/strings/ascii.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "absl/strings/str_split.h"
#include "absl/strings/strip.h"
#include "services/bandit/store/write_faults.h"
#include "services/common/status_macros.h"

namespace bitewise::bandit::pg {
namespace {

// Type OIDs (PostgreSQL's pg_type.dat; stable across versions).
constexpr unsigned int kBoolOid = 16;
constexpr unsigned int kByteaOid = 17;
constexpr unsigned int kInt8Oid = 20;
constexpr unsigned int kTextOid = 25;
constexpr unsigned int kFloat8Oid = 701;

// Every session: commits wait for the WAL flush whatever the database's
// default, a transaction left idle (a stalled client) is ended by the
// server rather than holding its row locks, and a lock waited for longer
// than half the response timeout ends the statement (55P03: contention,
// UNAVAILABLE, no storage fault) before the client gives up on a server
// that says nothing while it waits.
std::string SessionSetup(absl::Duration response_timeout) {
  return absl::StrCat(
      "SET synchronous_commit = on; SET client_min_messages = warning; "
      "SET idle_in_transaction_session_timeout = '60s'; SET lock_timeout = ",
      std::max<int64_t>(1, absl::ToInt64Milliseconds(response_timeout / 2)));
}

std::string BigEndian(uint64_t bits) {
  std::string out(8, '\0');
  for (int b = 0; b < 8; ++b) {
    out[b] = static_cast<char>((bits >> (8 * (7 - b))) & 0xff);
  }
  return out;
}

uint64_t FromBigEndian(const char* data, int length) {
  uint64_t bits = 0;
  for (int b = 0; b < length; ++b) {
    bits = (bits << 8) | static_cast<unsigned char>(data[b]);
  }
  return bits;
}

// libpq's messages end in a newline.
std::string Trimmed(const char* message) {
  return std::string(
      absl::StripTrailingAsciiWhitespace(message == nullptr ? "" : message));
}

// A libpq connection message on one line: its lines joined with "; ", each
// without its indentation or a "FATAL:  " prefix.
std::string OneLine(const char* message) {
  std::vector<std::string> lines;
  for (absl::string_view line :
       absl::StrSplit(Trimmed(message), '\n', absl::SkipWhitespace())) {
    line = absl::StripAsciiWhitespace(line);
    absl::ConsumePrefix(&line, "FATAL:");
    lines.emplace_back(absl::StripAsciiWhitespace(line));
  }
  return absl::StrJoin(lines, "; ");
}

absl::StatusCode CodeFor(absl::string_view sqlstate) {
  if (sqlstate.size() != 5) return absl::StatusCode::kInternal;
  const absl::string_view klass = sqlstate.substr(0, 2);
  if (klass == "08" || sqlstate == "57P01" || sqlstate == "57P02" ||
      sqlstate == "57P03" || sqlstate == "55P03" || sqlstate == "53300") {
    return absl::StatusCode::kUnavailable;
  }
  if (sqlstate == "40001" || sqlstate == "40P01") {
    return absl::StatusCode::kAborted;
  }
  if (sqlstate == "23505") return absl::StatusCode::kAlreadyExists;
  if (klass == "23") return absl::StatusCode::kFailedPrecondition;
  if (klass == "53") return absl::StatusCode::kResourceExhausted;
  if (klass == "22") return absl::StatusCode::kInvalidArgument;
  if (sqlstate == "57014") return absl::StatusCode::kDeadlineExceeded;
  if (klass == "XX" && sqlstate != "XX000") return absl::StatusCode::kDataLoss;
  return absl::StatusCode::kInternal;
}

}  // namespace

// ---------------------------------------------------------------------------
// Params

Params& Params::Add(unsigned int type, std::string bytes, bool null) {
  lengths_.push_back(static_cast<int>(bytes.size()));
  storage_.push_back(std::move(bytes));
  nulls_.push_back(null);
  types_.push_back(type);
  formats_.push_back(1);
  return *this;
}

Params& Params::Int64(int64_t value) {
  return Add(kInt8Oid, BigEndian(static_cast<uint64_t>(value)));
}

Params& Params::Double(double value) {
  uint64_t bits;
  std::memcpy(&bits, &value, sizeof(bits));
  return Add(kFloat8Oid, BigEndian(bits));
}

Params& Params::Bool(bool value) {
  return Add(kBoolOid, std::string(1, value ? '\1' : '\0'));
}

Params& Params::Text(absl::string_view value) {
  return Add(kTextOid, std::string(value));
}

Params& Params::Bytes(absl::string_view value) {
  return Add(kByteaOid, std::string(value));
}

Params& Params::NullBytes() { return Add(kByteaOid, std::string(), true); }

std::vector<const char*> Params::values() const {
  std::vector<const char*> out(storage_.size());
  for (size_t i = 0; i < storage_.size(); ++i) {
    // An empty value must still be a non-null pointer, or it reads as NULL.
    out[i] = nulls_[i] ? nullptr : storage_[i].data();
  }
  return out;
}

// ---------------------------------------------------------------------------
// Rows

Rows::Rows(pg_result* result) : result_(result) {}
Rows::Rows(Rows&& other) noexcept
    : result_(std::exchange(other.result_, nullptr)), row_(other.row_) {}
Rows& Rows::operator=(Rows&& other) noexcept {
  if (this != &other) {
    PQclear(result_);
    result_ = std::exchange(other.result_, nullptr);
    row_ = other.row_;
  }
  return *this;
}
Rows::~Rows() { PQclear(result_); }

int Rows::size() const { return PQntuples(result_); }

bool Rows::Next() { return ++row_ < PQntuples(result_); }

bool Rows::IsNull(int col) const {
  return PQgetisnull(result_, row_, col) != 0;
}

int64_t Rows::Int64(int col) const {
  if (IsNull(col)) return 0;
  const int length = PQgetlength(result_, row_, col);
  const char* data = PQgetvalue(result_, row_, col);
  const uint64_t bits = FromBigEndian(data, length);
  switch (length) {
    case 1:
      return static_cast<int64_t>(bits);
    case 2:
      return static_cast<int16_t>(bits);
    case 4:
      return static_cast<int32_t>(bits);
    case 8:
      return static_cast<int64_t>(bits);
    default:
      return 0;
  }
}

double Rows::Double(int col) const {
  if (IsNull(col) || PQgetlength(result_, row_, col) != 8) return 0.0;
  const uint64_t bits = FromBigEndian(PQgetvalue(result_, row_, col), 8);
  double value;
  std::memcpy(&value, &bits, sizeof(value));
  return value;
}

std::string Rows::Text(int col) const { return std::string(Blob(col)); }

absl::string_view Rows::Blob(int col) const {
  if (IsNull(col)) return absl::string_view();
  return absl::string_view(
      PQgetvalue(result_, row_, col),
      static_cast<size_t>(PQgetlength(result_, row_, col)));
}

// ---------------------------------------------------------------------------
// Connection

absl::StatusOr<std::unique_ptr<Connection>> Connection::Open(
    const std::string& conninfo, absl::Duration response_timeout) {
  // Defaults first: the connection string, expanded in dbname's place,
  // overrides them.
  // TCP keepalives and a user timeout: a server host that dies or a
  // network that splits fails the call within about 30 s instead of
  // holding a pooled connection (and a user's row lock) for ever.
  const char* keywords[] = {"connect_timeout",
                            "application_name",
                            "keepalives",
                            "keepalives_idle",
                            "keepalives_interval",
                            "keepalives_count",
                            "tcp_user_timeout",
                            "dbname",
                            nullptr};
  const char* values[] = {"5",     "bitewise-bandit", "1",    "10", "5", "3",
                          "30000", conninfo.c_str(),  nullptr};
  pg_conn* raw = PQconnectdbParams(keywords, values, /*expand_dbname=*/1);
  if (raw == nullptr) {
    return absl::ResourceExhaustedError("libpq could not allocate");
  }
  std::unique_ptr<Connection> conn(
      new Connection(raw, conninfo, response_timeout));
  if (PQstatus(raw) != CONNECTION_OK) {
    return StorageFault(
        absl::StatusCode::kUnavailable,
        absl::StrCat("PostgreSQL ", conn->description(),
                     " is unavailable: ", OneLine(PQerrorMessage(raw))));
  }
  conn->Describe();
  RETURN_IF_ERROR(
      conn->ExecScript(SessionSetup(response_timeout), "connecting"));
  return conn;
}

Connection::Connection(pg_conn* conn, std::string conninfo,
                       absl::Duration response_timeout)
    : conn_(conn),
      conninfo_(std::move(conninfo)),
      response_timeout_(response_timeout) {
  Describe();
}

Connection::~Connection() { PQfinish(conn_); }

void Connection::Describe() {
  const char* db = PQdb(conn_);
  const char* host = PQhost(conn_);
  const char* port = PQport(conn_);
  description_ = absl::StrCat("database \"", db == nullptr ? "" : db, "\" at ",
                              host == nullptr ? "" : host, ":",
                              port == nullptr ? "" : port);
}

bool Connection::broken() const {
  return closed_ || PQstatus(conn_) != CONNECTION_OK;
}

void Connection::Probe() {
  if (broken()) return;
  // What the server sent meanwhile (a FATAL at its shutdown) is consumed;
  // then an end of file on the socket means the server has closed it.
  PQconsumeInput(conn_);
  const int fd = PQsocket(conn_);
  if (fd < 0) {
    closed_ = true;
    return;
  }
  pollfd readable{fd, POLLIN, 0};
  if (poll(&readable, 1, 0) == 1) {
    char byte;
    const ssize_t n = recv(fd, &byte, 1, MSG_PEEK | MSG_DONTWAIT);
    if (n == 0 || (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK)) {
      closed_ = true;
    }
  }
}

bool Connection::in_transaction() const {
  const PGTransactionStatusType status = PQtransactionStatus(conn_);
  return status == PQTRANS_INTRANS || status == PQTRANS_INERROR ||
         status == PQTRANS_ACTIVE;
}

bool Connection::transaction_failed() const {
  return PQtransactionStatus(conn_) == PQTRANS_INERROR;
}

absl::Status Connection::Reconnect() {
  PQreset(conn_);
  prepared_.clear();
  closed_ = false;
  timed_out_ = false;
  if (PQstatus(conn_) != CONNECTION_OK) {
    return StorageFault(
        absl::StatusCode::kUnavailable,
        absl::StrCat("PostgreSQL ", description_,
                     " is unavailable: ", OneLine(PQerrorMessage(conn_))));
  }
  return ExecScript(SessionSetup(response_timeout_), "reconnecting");
}

absl::Status Connection::Error(pg_result* result, absl::string_view op) const {
  if (timed_out_) {
    return StorageFault(
        absl::StatusCode::kUnavailable,
        absl::StrCat("PostgreSQL ", description_, " did not answer within ",
                     absl::FormatDuration(response_timeout_), " (", op,
                     "); the connection was closed"));
  }
  if (result == nullptr || PQstatus(conn_) != CONNECTION_OK) {
    // libpq's message may run over several lines ("server closed the
    // connection unexpectedly\n\tThis probably means..."): one line here.
    return StorageFault(
        absl::StatusCode::kUnavailable,
        absl::StrCat("PostgreSQL ", description_, " is unavailable (", op,
                     "): ", OneLine(PQerrorMessage(conn_))));
  }
  const char* state = PQresultErrorField(result, PG_DIAG_SQLSTATE);
  const std::string sqlstate = state == nullptr ? "" : state;
  const absl::StatusCode code = CodeFor(sqlstate);
  const std::string message =
      Trimmed(PQresultErrorField(result, PG_DIAG_MESSAGE_PRIMARY));
  // The server cannot take writes: gone, shutting down, out of space, a
  // disk error, or read-only (a standby, default_transaction_read_only).
  if (sqlstate == "53100") {
    return StorageFault(
        absl::StatusCode::kResourceExhausted,
        absl::StrCat("PostgreSQL ", description_, " is out of space (", op,
                     "): ", message, " (SQLSTATE ", sqlstate, ")"));
  }
  if (sqlstate == "58030" || sqlstate == "25006") {
    return StorageFault(
        absl::StatusCode::kUnavailable,
        absl::StrCat("PostgreSQL ", description_, " cannot write (", op, "): ",
                     sqlstate == "58030" ? "an I/O error on the server: "
                                         : "the server is read-only: ",
                     message, " (SQLSTATE ", sqlstate, ")"));
  }
  if (code == absl::StatusCode::kUnavailable) {
    const std::string text =
        absl::StrCat("PostgreSQL ", description_, " is unavailable (", op,
                     "): ", message, " (SQLSTATE ", sqlstate, ")");
    // 55P03 (a lock not granted) and 53300 (no connection slot) are
    // contention, not a server that cannot write.
    if (sqlstate == "55P03" || sqlstate == "53300") {
      return absl::UnavailableError(text);
    }
    return StorageFault(absl::StatusCode::kUnavailable, text);
  }
  return absl::Status(
      code, absl::StrCat(op, ": PostgreSQL ", description_, ": ", message,
                         " (SQLSTATE ", sqlstate, ")"));
}

absl::StatusOr<std::string> Connection::Prepared(absl::string_view sql,
                                                 const Params& params,
                                                 absl::string_view op) {
  auto found = prepared_.find(sql);
  if (found != prepared_.end()) return found->second;
  std::string name = absl::StrCat("bw", prepared_.size());
  if (PQsendPrepare(conn_, name.c_str(), std::string(sql).c_str(),
                    params.size(), params.types()) != 1) {
    return Error(nullptr, op);
  }
  Rows prepared(Await());
  if (prepared.result_ == nullptr ||
      PQresultStatus(prepared.result_) != PGRES_COMMAND_OK) {
    return Error(prepared.result_, op);
  }
  prepared_.emplace(std::string(sql), name);
  return name;
}

pg_result* Connection::Await() {
  pg_result* kept = nullptr;
  // The server has response_timeout_ from the last bytes it sent (or the
  // statement's sending) to send more: a long result that keeps arriving
  // is not cut off, a server that stopped (frozen, or a host gone while
  // the kernel still answers) is.
  absl::Time deadline = absl::Now() + response_timeout_;
  for (;;) {
    while (true) {
      // What has arrived (or TLS has decrypted already, which poll cannot
      // see) first.
      if (PQconsumeInput(conn_) == 0) break;  // lost: PQgetResult says so
      if (!PQisBusy(conn_)) break;
      const int fd = PQsocket(conn_);
      if (fd < 0) break;  // lost: PQgetResult reports it
      const absl::Duration left = deadline - absl::Now();
      if (left <= absl::ZeroDuration()) {
        // Given up on: the statement may still run (or have committed) on
        // the server, which sees its client gone once it reads again.
        timed_out_ = true;
        closed_ = true;
        shutdown(fd, SHUT_RDWR);
        PQclear(kept);
        return nullptr;
      }
      pollfd readable{fd, POLLIN, 0};
      const int ready = poll(&readable, 1,
                             static_cast<int>(std::min<int64_t>(
                                 absl::ToInt64Milliseconds(
                                     absl::Ceil(left, absl::Milliseconds(1))),
                                 1 << 30)));
      if (ready <= 0) continue;  // the deadline is checked again
      deadline = absl::Now() + response_timeout_;  // bytes came
    }
    pg_result* result = PQgetResult(conn_);
    if (result == nullptr) return kept;
    // A script's results: the first error, else the last (as PQexec).
    if (kept != nullptr) {
      const ExecStatusType status = PQresultStatus(kept);
      if (status != PGRES_TUPLES_OK && status != PGRES_COMMAND_OK) {
        PQclear(result);
        continue;
      }
      PQclear(kept);
    }
    kept = result;
  }
}

absl::StatusOr<Rows> Connection::Exec(absl::string_view sql,
                                      const Params& params,
                                      absl::string_view op) {
  if (broken()) return Error(nullptr, op);
  ASSIGN_OR_RETURN(const std::string name, Prepared(sql, params, op));
  const std::vector<const char*> values = params.values();
  if (PQsendQueryPrepared(conn_, name.c_str(), params.size(), values.data(),
                          params.lengths(), params.formats(),
                          /*resultFormat=*/1) != 1) {
    return Error(nullptr, op);
  }
  Rows rows(Await());
  const ExecStatusType status = PQresultStatus(rows.result_);
  if (rows.result_ == nullptr ||
      (status != PGRES_TUPLES_OK && status != PGRES_COMMAND_OK)) {
    return Error(rows.result_, op);
  }
  return rows;
}

absl::Status Connection::ExecScript(absl::string_view sql,
                                    absl::string_view op) {
  if (broken()) return Error(nullptr, op);
  if (PQsendQuery(conn_, std::string(sql).c_str()) != 1) {
    return Error(nullptr, op);
  }
  Rows rows(Await());
  const ExecStatusType status = PQresultStatus(rows.result_);
  if (rows.result_ == nullptr ||
      (status != PGRES_TUPLES_OK && status != PGRES_COMMAND_OK)) {
    return Error(rows.result_, op);
  }
  return absl::OkStatus();
}

absl::Status OutcomeUnknownIfLost(const Connection& conn, absl::Status status,
                                  absl::string_view retry) {
  if (status.ok() || !conn.broken()) return status;
  return StorageFault(
      absl::StatusCode::kUnavailable,
      absl::StrCat(status.message(),
                   "; the connection was lost before the server's answer, so "
                   "the outcome is unknown: it may have been applied",
                   retry.empty() ? "" : ". ", retry));
}

// ---------------------------------------------------------------------------
// Pool

absl::StatusOr<std::unique_ptr<Pool>> Pool::Open(
    const std::string& conninfo, int size, absl::Duration response_timeout) {
  auto pool = std::make_unique<Pool>();
  for (int i = 0; i < std::max(size, 1); ++i) {
    ASSIGN_OR_RETURN(std::unique_ptr<Connection> conn,
                     Connection::Open(conninfo, response_timeout));
    pool->description_ = conn->description();
    pool->all_.push_back(std::move(conn));
  }
  absl::MutexLock lock(&pool->mu_);
  for (const auto& conn : pool->all_) pool->free_.push_back(conn.get());
  return pool;
}

absl::StatusOr<Pool::Lease> Pool::Acquire(absl::string_view op) {
  Connection* conn = nullptr;
  {
    absl::MutexLock lock(&mu_);
    mu_.Await(absl::Condition(
        +[](std::vector<Connection*>* free) { return !free->empty(); },
        &free_));
    conn = free_.back();
    free_.pop_back();
  }
  Lease lease(this, conn);
  conn->Probe();
  if (conn->broken()) {
    absl::Status restored = conn->Reconnect();
    if (!restored.ok()) {
      return absl::UnavailableError(
          absl::StrCat(restored.message(), " (", op, ")"));
    }
  }
  return lease;
}

void Pool::Release(Connection* conn) {
  absl::MutexLock lock(&mu_);
  free_.push_back(conn);
}

// ---------------------------------------------------------------------------
// Transaction

absl::StatusOr<Transaction> Transaction::Begin(Connection& conn,
                                               absl::string_view op,
                                               absl::string_view mode) {
  const std::string begin = absl::StrCat("BEGIN ", mode);
  absl::Status begun = conn.ExecScript(begin, op);
  if (!begun.ok() && conn.broken()) {
    // Lost since its last use (a server restart): nothing has run yet, so
    // one reconnect and retry is safe.
    RETURN_IF_ERROR(conn.Reconnect());
    begun = conn.ExecScript(begin, op);
  }
  RETURN_IF_ERROR(begun);
  return Transaction(&conn, op);
}

Transaction::~Transaction() {
  if (conn_ != nullptr && !conn_->broken() && conn_->in_transaction()) {
    conn_->ExecScript("ROLLBACK", op_).IgnoreError();
  }
}

absl::Status Transaction::Commit() {
  Connection* conn = std::exchange(conn_, nullptr);
  if (conn->transaction_failed()) {
    // COMMIT would only roll it back (and report success).
    conn->ExecScript("ROLLBACK", op_).IgnoreError();
    return absl::AbortedError(
        absl::StrCat(op_, ": the transaction failed and was rolled back"));
  }
  return OutcomeUnknownIfLost(*conn, conn->ExecScript("COMMIT", op_),
                              kRetryAfterUnknownOutcome);
}

}  // namespace bitewise::bandit::pg
