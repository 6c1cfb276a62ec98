// Write faults: how a store says that its storage refused a write, and how
// the service notices and recovers without a restart.
//
// A storage fault is a write refused for a reason outside the call: a full
// disk or a file-size limit (RESOURCE_EXHAUSTED), a read-only file or file
// system, an I/O error, or a database server gone or out of space
// (UNAVAILABLE). Its status carries a payload (IsStorageFault) and its
// message names the cause and the file or server. Bad input, unknown ids
// and lost races are never storage faults.
//
// FaultWatchStore wraps any EventStore: the first storage fault of a write
// makes CheckHealth (and so the service's health) report it; while it does,
// writes are refused with it at once, and a probe write (the store's
// ProbeWrite) is tried at most every `probe_period`; the first probe that
// succeeds clears the fault. Reads pass through.
#ifndef BITEWISE_SERVICES_BANDIT_STORE_WRITE_FAULTS_H_
#define BITEWISE_SERVICES_BANDIT_STORE_WRITE_FAULTS_H_

#include <cstdint>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "absl/base/thread_annotations.h"
#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "absl/synchronization/mutex.h"
#include "absl/time/time.h"
#include "services/bandit/store/event_store.h"

namespace bitewise::bandit {

// `message` as a storage fault with `code` (RESOURCE_EXHAUSTED or
// UNAVAILABLE).
absl::Status StorageFault(absl::StatusCode code, absl::string_view message);
bool IsStorageFault(const absl::Status& status);

// What an errno of a failed write means for the service, in words ("the
// disk is full", "the file size limit is reached", "the file or file
// system is read-only", "an I/O error"), and its code: RESOURCE_EXHAUSTED
// for a full disk, quota or size limit, UNAVAILABLE otherwise.
struct WriteErrno {
  absl::StatusCode code;
  const char* cause;
};
WriteErrno DescribeWriteErrno(int error);

// The storage fault of a failed file operation: "cannot <what> <path>: the
// disk is full (No space left on device)".
absl::Status FileWriteFault(absl::string_view what, absl::string_view path,
                            int error);

class FaultWatchStore : public EventStore {
 public:
  explicit FaultWatchStore(
      std::unique_ptr<EventStore> store,
      absl::Duration probe_period = absl::Milliseconds(200));

  // Joins the deferred checks' thread.
  ~FaultWatchStore() override;

  EventStore& inner() { return *store_; }

  // Runs the store's RunDeferredChecks on a thread of its own. Until it
  // returns, writes wait for it and reads and health go on; when it fails
  // (a damaged file), its error is a fault no probe clears: health reports
  // it and every write is refused with it until the store is restored and
  // the service restarted. Call once, before the store is used.
  void StartDeferredChecks();

  // The store's own health, then the remembered fault (probing first when
  // a probe is due).
  absl::Status CheckHealth() override;
  absl::Status ProbeWrite() override { return store_->ProbeWrite(); }
  // Already run by StartDeferredChecks, or OK.
  absl::Status RunDeferredChecks() override;
  // May be set while the store is in use.
  void SetFaultObserver(FaultObserver observer) override {
    absl::MutexLock lock(&mu_);
    observer_ = std::move(observer);
  }
  StoreWriteStats write_stats() const override;

  absl::Status CreateUser(const UserRecord& user) override;
  absl::StatusOr<UserRecord> GetUser(const std::string& user_id) override {
    return store_->GetUser(user_id);
  }
  absl::StatusOr<PageResult<UserRecord>> ListUsers(const Page& page) override {
    return store_->ListUsers(page);
  }
  absl::Status DeleteUser(const std::string& user_id) override;
  absl::Status ResetUser(const std::string& user_id) override;
  absl::Status SetLearner(const std::string& user_id, Learner learner,
                          int64_t model_version) override;
  absl::StatusOr<int64_t> AppendPending(const EventRecord& event) override;
  absl::StatusOr<EventRecord> CompleteEvent(int64_t event_id, double loss,
                                            const std::vector<double>& posthoc,
                                            double weight,
                                            absl::Time updated_at) override;
  absl::StatusOr<EventRecord> GetEvent(int64_t event_id) override {
    return store_->GetEvent(event_id);
  }
  absl::StatusOr<PageResult<EventRecord>> ListEvents(
      const std::string& user_id, const std::string& meal_id,
      const Page& page) override {
    return store_->ListEvents(user_id, meal_id, page);
  }
  absl::StatusOr<std::vector<EventRecord>> CompletedEvents(
      const std::string& user_id) override {
    return store_->CompletedEvents(user_id);
  }
  absl::StatusOr<std::vector<EventRecord>> CompletedEventsFrom(
      const std::string& user_id, int64_t from_version) override {
    return store_->CompletedEventsFrom(user_id, from_version);
  }
  absl::Status PutCheckpoint(const std::string& user_id,
                             const ModelCheckpoint& checkpoint) override;
  absl::StatusOr<ModelCheckpoint> GetCheckpoint(
      const std::string& user_id) override {
    return store_->GetCheckpoint(user_id);
  }
  absl::Status DeleteCheckpoint(const std::string& user_id) override;
  bool shared() const override { return store_->shared(); }
  absl::StatusOr<UserLogPosition> LogPosition(
      const std::string& user_id) override {
    return store_->LogPosition(user_id);
  }
  absl::StatusOr<int64_t> AppendPendingAt(const EventRecord& event,
                                          const UserLogPosition& at) override;
  absl::StatusOr<EventRecord> CompleteEventAt(
      const std::string& user_id, int64_t event_id, double loss,
      const std::vector<double>& posthoc, double weight, absl::Time updated_at,
      const UserLogPosition& at) override;
  void SetCommitObserver(CommitObserver observer) override {
    store_->SetCommitObserver(std::move(observer));
  }
  absl::StatusOr<int64_t> AddPool(const PoolRecord& pool) override;
  absl::StatusOr<PoolRecord> LatestPool(const BanditConfig& config) override {
    return store_->LatestPool(config);
  }
  absl::StatusOr<int64_t> AppendAudit(const AuditEntry& entry) override;
  absl::StatusOr<PageResult<AuditEntry>> ListAudit(const Page& page) override {
    return store_->ListAudit(page);
  }
  absl::StatusOr<StoreCheckReport> CheckStore() override {
    return store_->CheckStore();
  }

 private:
  // OK, or, while writes are still refused, the write `op` refused naming
  // the remembered fault (counted in write_faults); with an empty `op` (the
  // health check) the fault itself, not counted.
  absl::Status Writable(absl::string_view op) ABSL_LOCKS_EXCLUDED(mu_);
  // `status`, remembered when it is a storage fault.
  absl::Status Note(absl::Status status) ABSL_LOCKS_EXCLUDED(mu_);
  template <typename T>
  absl::StatusOr<T> Note(absl::StatusOr<T> result) {
    if (!result.ok()) Note(result.status()).IgnoreError();
    return result;
  }

  const std::unique_ptr<EventStore> store_;
  const absl::Duration probe_period_;
  mutable absl::Mutex mu_;
  absl::Status fault_ ABSL_GUARDED_BY(mu_);
  // The deferred checks: done (or never started), and their failure.
  bool checked_ ABSL_GUARDED_BY(mu_) = true;
  absl::Status damage_ ABSL_GUARDED_BY(mu_);
  std::thread checker_;
  absl::Time last_probe_ ABSL_GUARDED_BY(mu_) = absl::InfinitePast();
  int64_t faults_ ABSL_GUARDED_BY(mu_) = 0;
  FaultObserver observer_ ABSL_GUARDED_BY(mu_);
  // One probe at a time; writers and the health check wait for it.
  absl::Mutex probe_mu_ ABSL_ACQUIRED_BEFORE(mu_);
};

}  // namespace bitewise::bandit

#endif  // BITEWISE_SERVICES_BANDIT_STORE_WRITE_FAULTS_H_
