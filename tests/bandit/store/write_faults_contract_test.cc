// Write faults in the store contract, on every backend: the store wrapped
// as the service wraps it (FaultWatchStore), and storage that refuses
// writes beneath the store's own code. The test binary runs with the
// write-fault injector (tests/common) preloaded, and so does the
// PostgreSQL server it starts; a file fails while a control file named
// "bitewise-write-fault" is in its directory (the test's SQLite directory,
// or the database's directory under the server's data directory).
//
// For each fault: the failing write answers RESOURCE_EXHAUSTED or
// UNAVAILABLE naming the cause and the file or server; health reports it;
// other writes are refused with it; reads still answer and nothing was
// written; once the storage takes writes again the probe clears health
// and the refused write succeeds; the full check finds nothing wrong.
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include "services/bandit/store/write_faults.h"
#include "tests/bandit/store/store_test_fixture.h"

// The injector is preloaded before a sanitizer's runtime (a full
// sanitizer build): let it.
extern "C" const char* __asan_default_options() {
  return "verify_asan_link_order=0";
}

namespace bitewise::bandit::store_test {
namespace {

constexpr char kControl[] = "bitewise-write-fault";

struct Fault {
  const char* error;
  absl::StatusCode code;
  const char* sqlite_cause;
  const char* postgres_cause;  // null: not tried on PostgreSQL
};

// PostgreSQL maps a full disk to SQLSTATE 53100; its other file errors are
// internal errors of the server (its own crash-safety handles them).
constexpr Fault kFaults[] = {
    {"ENOSPC", absl::StatusCode::kResourceExhausted, "the disk is full",
     "is out of space"},
    {"EFBIG", absl::StatusCode::kResourceExhausted,
     "the file size limit is reached", nullptr},
    {"EIO", absl::StatusCode::kUnavailable, "an I/O error", nullptr},
    {"EROFS", absl::StatusCode::kUnavailable,
     "the file or file system is read-only", nullptr},
};

class WriteFaultsContractTest : public StoreContractTest {
 protected:
  // The directory whose files are to fail.
  std::string FaultDir() {
    if (sqlite()) return dir_;
    absl::StatusOr<std::string> oid = server_->Query(
        database_,
        "SELECT oid FROM pg_database WHERE datname = current_database()");
    EXPECT_TRUE(oid.ok()) << oid.status();
    return absl::StrCat(server_->dir(), "/data/base/", oid.value_or(""));
  }
  // How messages name the store.
  std::string StoreName() const {
    return sqlite() ? path_ : absl::StrCat("database \"", database_, "\"");
  }
};

INSTANTIATE_TEST_SUITE_P(Stores, WriteFaultsContractTest, kAllBackends,
                         BackendName);

TEST_P(WriteFaultsContractTest, EachFaultIsNamedVisibleAndRecovered) {
  // CTest preloads the injector (CMakeLists.txt); without it no fault
  // could happen, and the test would prove nothing.
  const char* preload = std::getenv("LD_PRELOAD");
  ASSERT_TRUE(preload != nullptr &&
              std::string(preload).find("write_fault_injector") !=
                  std::string::npos)
      << "the write-fault injector is not preloaded: run this test through "
         "ctest, or with LD_PRELOAD=<build>/tests/common/"
         "libbitewise_write_fault_injector.so";
  FaultWatchStore store(std::move(store_), absl::Milliseconds(50));
  ASSERT_TRUE(store.CreateUser(MakeUser("u")).ok());
  int64_t completed = 0;
  for (int i = 0; i < 3; ++i) {
    absl::StatusOr<int64_t> id = store.AppendPending(MakeEvent("u", "m"));
    ASSERT_TRUE(id.ok()) << id.status();
    ASSERT_TRUE(
        store.CompleteEvent(*id, 0.0, {0.5, 0.5}, 1.0, absl::Now()).ok());
    ++completed;
  }
  const std::string control = FaultDir() + "/" + kControl;
  for (const Fault& fault : kFaults) {
    const char* cause = sqlite() ? fault.sqlite_cause : fault.postgres_cause;
    if (cause == nullptr) continue;
    SCOPED_TRACE(fault.error);
    absl::StatusOr<int64_t> pending = store.AppendPending(MakeEvent("u", "m"));
    ASSERT_TRUE(pending.ok()) << pending.status();
    std::ofstream(control) << fault.error;

    // SQLite writes every commit to its files at once; PostgreSQL reaches
    // its table files when a table needs a new page, so events are added
    // until one does (each a pending event nobody completes if it lands).
    absl::Status refused;
    if (sqlite()) {
      refused =
          store.CompleteEvent(*pending, 1.0, {0.25, 0.75}, 1.0, absl::Now())
              .status();
    } else {
      for (int i = 0; i < 2000 && refused.ok(); ++i) {
        refused = store.AppendPending(MakeEvent("u", "m", 0.01 * i)).status();
      }
    }
    ASSERT_FALSE(refused.ok());
    EXPECT_TRUE(IsStorageFault(refused)) << refused;
    EXPECT_EQ(refused.code(), fault.code) << refused;
    EXPECT_THAT(refused.message(), HasSubstr(cause));
    EXPECT_THAT(refused.message(), HasSubstr(StoreName()));

    // Health says so (and is no write: the count of refused writes does
    // not move with it; it did, with every poll and scrape); other writes
    // are refused with it, named as themselves; reads answer.
    const int64_t counted = store.write_stats().write_faults;
    EXPECT_GT(counted, 0);
    for (int i = 0; i < 5; ++i) {
      const absl::Status health = store.CheckHealth();
      EXPECT_EQ(health.code(), fault.code) << health;
      EXPECT_THAT(health.message(), HasSubstr(cause));
    }
    EXPECT_EQ(store.write_stats().write_faults, counted);
    const absl::Status other =
        store.CompleteEvent(*pending, 1.0, {0.25, 0.75}, 1.0, absl::Now())
            .status();
    EXPECT_EQ(other.code(), fault.code);
    EXPECT_TRUE(IsStorageFault(other));
    EXPECT_THAT(std::string(other.message()),
                ::testing::StartsWith("CompleteEvent refused: the store's "
                                      "storage failed a write"));
    EXPECT_THAT(other.message(), HasSubstr(cause));
    EXPECT_EQ(store.write_stats().write_faults, counted + 1);
    absl::StatusOr<UserRecord> user = store.GetUser("u");
    ASSERT_TRUE(user.ok()) << user.status();
    EXPECT_EQ(user->model_version, completed);
    EXPECT_FALSE(store.GetEvent(*pending)->completed);

    // The storage takes writes again: the probe clears health.
    std::filesystem::remove(control);
    absl::SleepFor(absl::Milliseconds(60));
    EXPECT_TRUE(store.CheckHealth().ok()) << store.CheckHealth();
    absl::StatusOr<EventRecord> done =
        store.CompleteEvent(*pending, 1.0, {0.25, 0.75}, 1.0, absl::Now());
    ASSERT_TRUE(done.ok()) << done.status();
    EXPECT_EQ(done->model_version, ++completed);
  }
  absl::StatusOr<StoreCheckReport> check = store.CheckStore();
  ASSERT_TRUE(check.ok()) << check.status();
  EXPECT_THAT(check->findings, IsEmpty());
}

}  // namespace
}  // namespace bitewise::bandit::store_test
