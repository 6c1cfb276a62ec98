#include "services/bandit/store/open_store.h"

#include <utility>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/strip.h"
#include "services/bandit/store/postgres_event_store.h"
#include "services/bandit/store/sqlite_event_store.h"
#include "services/bandit/store/write_faults.h"

namespace bitewise::bandit {

bool IsPostgresSpec(const std::string& spec) {
  return absl::StartsWith(spec, "postgresql://") ||
         absl::StartsWith(spec, "postgres://");
}

// libpq's other form, "host=db dbname=bitewise password=...": taken for a
// file name it would be echoed in messages (password and all) and, with
// --create, made as a file.
bool LooksLikeLibpqKeyValue(const std::string& spec) {
  for (const char* key : {"host=", "hostaddr=", "dbname=", "user=", "password=",
                          "port=", "sslmode=", "service="}) {
    if (absl::StartsWith(spec, key) ||
        absl::StrContains(spec, absl::StrCat(" ", key))) {
      return true;
    }
  }
  return false;
}

absl::StatusOr<std::unique_ptr<EventStore>> OpenEventStore(
    const std::string& spec, const OpenStoreOptions& options) {
  if (spec.empty()) {
    return absl::InvalidArgumentError("the store location is empty");
  }
  if (!IsPostgresSpec(spec) && LooksLikeLibpqKeyValue(spec)) {
    return absl::InvalidArgumentError(
        "the store location looks like libpq's key=value form (not echoed "
        "here: it may hold a password); give a PostgreSQL database as a URI, "
        "postgresql://USER@HOST:PORT/DB?sslmode=..., or a SQLite file name");
  }
  if (IsPostgresSpec(spec)) {
    PostgresStoreOptions pg;
    pg.conninfo = spec;
    pg.connections = options.postgres_connections;
    pg.response_timeout = options.postgres_response_timeout;
    pg.create_if_missing = options.create_if_missing;
    auto store = PostgresEventStore::Open(pg);
    if (!store.ok()) return store.status();
    return std::unique_ptr<EventStore>(
        std::make_unique<FaultWatchStore>(std::move(store).value()));
  }
  SqliteStoreOptions sqlite;
  sqlite.path = std::string(absl::StripPrefix(spec, "sqlite:"));
  sqlite.create_if_missing = options.create_if_missing;
  sqlite.synchronous_full = options.sqlite_fsync;
  sqlite.check_at_open = !options.defer_full_check;
  auto store = SqliteEventStore::Open(sqlite);
  if (!store.ok()) return store.status();
  auto watched = std::make_unique<FaultWatchStore>(std::move(store).value());
  if (options.defer_full_check) watched->StartDeferredChecks();
  return std::unique_ptr<EventStore>(std::move(watched));
}

std::string DescribeStoreSpec(const std::string& spec) {
  if (LooksLikeLibpqKeyValue(spec)) return "(a libpq key=value string)";
  if (!IsPostgresSpec(spec)) return spec;
  std::string out = spec;
  // postgresql://user:password@host/...: the password goes.
  const size_t scheme_end = out.find("://") + 3;
  const size_t at = out.find('@', scheme_end);
  const size_t slash = out.find('/', scheme_end);
  if (at != std::string::npos && (slash == std::string::npos || at < slash)) {
    const size_t colon = out.find(':', scheme_end);
    if (colon != std::string::npos && colon < at) {
      out = absl::StrCat(out.substr(0, colon), ":***", out.substr(at));
    }
  }
  // ...?password=secret&... and the client key's passphrase,
  // ...?sslpassword=secret&...: so do these.
  for (const std::string name : {"password=", "sslpassword="}) {
    for (size_t key = out.find(name); key != std::string::npos;
         key = out.find(name, key + 1)) {
      if (key > 0 && out[key - 1] != '?' && out[key - 1] != '&') continue;
      const size_t value = key + name.size();
      const size_t end = out.find('&', value);
      out = absl::StrCat(out.substr(0, value), "***",
                         end == std::string::npos ? "" : out.substr(end));
    }
  }
  return out;
}

}  // namespace bitewise::bandit
