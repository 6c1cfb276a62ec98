#include "services/bandit/store/write_faults.h"

#include <cerrno>
#include <cstring>
#include <utility>

#include "absl/strings/cord.h"
#include "absl/strings/str_cat.h"
#include "services/common/status_macros.h"

namespace bitewise::bandit {
namespace {

constexpr char kStorageFaultPayload[] = "type.bitewise/bandit.StorageFault";

}  // namespace

absl::Status StorageFault(absl::StatusCode code, absl::string_view message) {
  absl::Status status(code, message);
  status.SetPayload(kStorageFaultPayload, absl::Cord("1"));
  return status;
}

bool IsStorageFault(const absl::Status& status) {
  return !status.ok() && status.GetPayload(kStorageFaultPayload).has_value();
}

WriteErrno DescribeWriteErrno(int error) {
  switch (error) {
    case ENOSPC:
      return {absl::StatusCode::kResourceExhausted, "the disk is full"};
    case EDQUOT:
      return {absl::StatusCode::kResourceExhausted,
              "the disk quota is exhausted"};
    case EFBIG:
      return {absl::StatusCode::kResourceExhausted,
              "the file size limit is reached"};
    case EROFS:
    case EPERM:
    case EACCES:
      return {absl::StatusCode::kUnavailable,
              "the file or file system is read-only"};
    case EIO:
      return {absl::StatusCode::kUnavailable, "an I/O error"};
    default:
      return {absl::StatusCode::kUnavailable, "a write error"};
  }
}

absl::Status FileWriteFault(absl::string_view what, absl::string_view path,
                            int error) {
  const WriteErrno described = DescribeWriteErrno(error);
  return StorageFault(described.code, absl::StrCat("cannot ", what, " ", path,
                                                   ": ", described.cause, " (",
                                                   std::strerror(error), ")"));
}

FaultWatchStore::FaultWatchStore(std::unique_ptr<EventStore> store,
                                 absl::Duration probe_period)
    : store_(std::move(store)), probe_period_(probe_period) {}

FaultWatchStore::~FaultWatchStore() {
  if (checker_.joinable()) checker_.join();
}

void FaultWatchStore::StartDeferredChecks() {
  {
    absl::MutexLock lock(&mu_);
    checked_ = false;
  }
  checker_ = std::thread([this] {
    const absl::Status checked = store_->RunDeferredChecks();
    FaultObserver observer;
    {
      absl::MutexLock lock(&mu_);
      checked_ = true;
      damage_ = checked;
      if (!checked.ok()) {
        ++faults_;
        observer = observer_;
      }
    }
    if (observer) observer(checked);
  });
}

absl::Status FaultWatchStore::RunDeferredChecks() {
  absl::MutexLock lock(&mu_);
  mu_.Await(absl::Condition(&checked_));
  return damage_;
}

namespace {

// A write refused because of an earlier fault: named as this write, with
// the fault (whose message names the write that met it) and its payloads.
absl::Status Refused(absl::string_view op, const absl::Status& fault) {
  absl::Status refused(
      fault.code(),
      absl::StrCat(op,
                   " refused: the store's storage failed a write and has not "
                   "taken one since (",
                   fault.message(),
                   "); writes resume once a probe write "
                   "succeeds"));
  fault.ForEachPayload([&refused](absl::string_view url, const absl::Cord& p) {
    refused.SetPayload(url, p);
  });
  return refused;
}

}  // namespace

absl::Status FaultWatchStore::Writable(absl::string_view op) {
  // The health check (no op) is told the fault as it is, and is no write:
  // only writes count as refused.
  const bool write = !op.empty();
  const auto refuse = [&](const absl::Status& fault)
                          ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_) {
                            if (!write) return fault;
                            ++faults_;
                            return Refused(op, fault);
                          };
  {
    absl::MutexLock lock(&mu_);
    mu_.Await(absl::Condition(&checked_));
    if (!damage_.ok()) {
      // Said as it is: no probe clears it (a restored file and a restart).
      if (write) ++faults_;
      return damage_;
    }
    if (fault_.ok()) return absl::OkStatus();
  }
  absl::MutexLock probing(&probe_mu_);
  {
    absl::MutexLock lock(&mu_);
    if (fault_.ok()) return absl::OkStatus();  // another caller's probe
    if (absl::Now() - last_probe_ < probe_period_) return refuse(fault_);
  }
  const absl::Status probed = store_->ProbeWrite();
  absl::MutexLock lock(&mu_);
  last_probe_ = absl::Now();
  if (probed.ok()) {
    fault_ = absl::OkStatus();
    return absl::OkStatus();
  }
  // A new cause (the disk went from full to read-only) replaces the first.
  if (IsStorageFault(probed) && probed.code() != fault_.code()) {
    fault_ = probed;
  }
  return refuse(fault_);
}

absl::Status FaultWatchStore::Note(absl::Status status) {
  if (!IsStorageFault(status)) return status;
  FaultObserver observer;
  {
    absl::MutexLock lock(&mu_);
    ++faults_;
    if (fault_.ok()) {
      fault_ = status;
      observer = observer_;
      // The write itself was the first probe.
      last_probe_ = absl::Now();
    }
  }
  if (observer) observer(status);
  return status;
}

absl::Status FaultWatchStore::CheckHealth() {
  RETURN_IF_ERROR(store_->CheckHealth());
  {
    // Health does not wait for the deferred checks (writes do).
    absl::MutexLock lock(&mu_);
    if (!damage_.ok()) return damage_;
    if (!checked_) return absl::OkStatus();
  }
  return Writable(/*op=*/"");
}

StoreWriteStats FaultWatchStore::write_stats() const {
  StoreWriteStats stats = store_->write_stats();
  absl::MutexLock lock(&mu_);
  stats.write_faults = faults_;
  return stats;
}

absl::Status FaultWatchStore::CreateUser(const UserRecord& user) {
  RETURN_IF_ERROR(Writable("CreateUser"));
  return Note(store_->CreateUser(user));
}

absl::Status FaultWatchStore::DeleteUser(const std::string& user_id) {
  RETURN_IF_ERROR(Writable("DeleteUser"));
  return Note(store_->DeleteUser(user_id));
}

absl::Status FaultWatchStore::ResetUser(const std::string& user_id) {
  RETURN_IF_ERROR(Writable("ResetUser"));
  return Note(store_->ResetUser(user_id));
}

absl::Status FaultWatchStore::SetLearner(const std::string& user_id,
                                         Learner learner,
                                         int64_t model_version) {
  RETURN_IF_ERROR(Writable("SetLearner"));
  return Note(store_->SetLearner(user_id, learner, model_version));
}

absl::StatusOr<int64_t> FaultWatchStore::AppendPending(
    const EventRecord& event) {
  RETURN_IF_ERROR(Writable("AppendPending"));
  return Note(store_->AppendPending(event));
}

absl::StatusOr<EventRecord> FaultWatchStore::CompleteEvent(
    int64_t event_id, double loss, const std::vector<double>& posthoc,
    double weight, absl::Time updated_at) {
  RETURN_IF_ERROR(Writable("CompleteEvent"));
  return Note(
      store_->CompleteEvent(event_id, loss, posthoc, weight, updated_at));
}

absl::Status FaultWatchStore::PutCheckpoint(const std::string& user_id,
                                            const ModelCheckpoint& checkpoint) {
  RETURN_IF_ERROR(Writable("PutCheckpoint"));
  return Note(store_->PutCheckpoint(user_id, checkpoint));
}

absl::Status FaultWatchStore::DeleteCheckpoint(const std::string& user_id) {
  RETURN_IF_ERROR(Writable("DeleteCheckpoint"));
  return Note(store_->DeleteCheckpoint(user_id));
}

absl::StatusOr<int64_t> FaultWatchStore::AppendPendingAt(
    const EventRecord& event, const UserLogPosition& at) {
  RETURN_IF_ERROR(Writable("AppendPendingAt"));
  return Note(store_->AppendPendingAt(event, at));
}

absl::StatusOr<EventRecord> FaultWatchStore::CompleteEventAt(
    const std::string& user_id, int64_t event_id, double loss,
    const std::vector<double>& posthoc, double weight, absl::Time updated_at,
    const UserLogPosition& at) {
  RETURN_IF_ERROR(Writable("CompleteEventAt"));
  return Note(store_->CompleteEventAt(user_id, event_id, loss, posthoc, weight,
                                      updated_at, at));
}

absl::StatusOr<int64_t> FaultWatchStore::AddPool(const PoolRecord& pool) {
  RETURN_IF_ERROR(Writable("AddPool"));
  return Note(store_->AddPool(pool));
}

absl::StatusOr<int64_t> FaultWatchStore::AppendAudit(const AuditEntry& entry) {
  RETURN_IF_ERROR(Writable("AppendAudit"));
  return Note(store_->AppendAudit(entry));
}

}  // namespace bitewise::bandit
