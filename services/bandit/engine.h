// BanditEngine: the BanditService's behaviour without gRPC. It pairs the
// durable EventStore (the truth) with an LRU cache of per-user learner models
// (LearnerModel) (derived state, rebuilt from the log when loaded), chooses
// actions, and applies updates exactly once.
//
// Thread-safe. Calls for one user are serialised by that user's mutex;
// different users run in parallel. When the store is shared by several
// processes (replicas), a call writes only where its cached model says the
// user's log stands, and on a conflict brings the model up to the log and
// tries again (EventStore::shared), so every process's model equals the
// log's. Every mutation is written to the store
// before the in-memory model changes, so an acknowledged Update survives a
// crash and a failed one changes nothing.
//
// Errors: INVALID_ARGUMENT (names the field), NOT_FOUND (unknown user or
// event), ALREADY_EXISTS (CreateUser), and the store's own errors.
#ifndef BITEWISE_SERVICES_BANDIT_ENGINE_H_
#define BITEWISE_SERVICES_BANDIT_ENGINE_H_

#include <atomic>
#include <cstdint>
#include <list>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "absl/base/thread_annotations.h"
#include "absl/container/flat_hash_map.h"
#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/synchronization/mutex.h"
#include "absl/time/time.h"
#include "absl/types/span.h"
#include "services/bandit/core/config.h"
#include "services/bandit/core/learner_model.h"
#include "services/bandit/store/event_store.h"
#include "services/domain/user_id.h"

namespace bitewise::bandit {

struct EngineOptions {
  // Loaded models are evicted, least recently used first, while their
  // total size exceeds this. A model in use is never evicted.
  size_t cache_budget_bytes = size_t{2} << 30;
  // Passed to the learners: LinUcbModel's primal threshold (0: 3d/4).
  int primal_threshold = 0;
  // CreateUser refuses a configuration whose model could grow beyond this
  // (MaxModelBytes), so that no user's model can take the machine's
  // memory (d = 65536 would need terabytes in primal form).
  size_t max_model_bytes = size_t{2} << 30;
  // CreateUser refuses a configuration whose GetModel reply (ModelReplyBytes)
  // would pass this, so that every user's model can be read under the
  // default 4 MiB message limit.
  size_t max_reply_bytes = size_t{3} << 20;
  // Model checkpoints (docs/operations.md): a loaded model is saved to the
  // store when it has at least checkpoint_min_events completed events since
  // its last checkpoint and its user has been idle for checkpoint_idle (the
  // end of a meal), or at checkpoint_max_events events regardless; a cold
  // load then reads the checkpoint and the events after it. A background
  // thread looks every checkpoint_poll. checkpoint_min_events 0: never.
  int64_t checkpoint_min_events = 50;
  int64_t checkpoint_max_events = 250;
  absl::Duration checkpoint_idle = absl::Seconds(30);
  absl::Duration checkpoint_poll = absl::Seconds(1);
};

// About how many bytes GetModel's reply for `config` takes at most: per
// action its name, theta (d) and phi (q) doubles, and the same again for a
// population prior in the config, with the message overhead.
size_t ModelReplyBytes(const BanditConfig& config);

// The most memory a model of `config` can need, in bytes: per action, the
// primal form's d x d and q x q matrices and the d x q cross terms, with
// the dual form's whitened rows held beside it while an action converts
// (another d x d), all in doubles. An upper bound, not the size of a new model.
size_t MaxModelBytes(const BanditConfig& config);

// Longest meal_id and item_label a Select may carry (bytes): labels, not
// documents, so that every page of ListEvents stays small.
constexpr size_t kMaxLabelBytes = 256;

struct SelectInput {
  std::string user_id;
  std::vector<double> context;
  std::string meal_id;
  std::string item_label;
};

struct SelectResult {
  int64_t event_id = 0;
  int action = 0;
  std::string action_name;
  double propensity = 1.0;
  std::vector<ActionEstimate> estimates;
  std::vector<std::string> action_names;  // index-aligned with estimates
  int64_t model_version = 0;
  // LearnerModel::PredictedPosthoc at the context (poLinUCB); empty else.
  std::vector<double> predicted_posthoc;
};

// The model's answer for a context with nothing recorded (Estimate): what
// a Select there would weigh, without choosing or writing an event.
struct EstimateResult {
  std::vector<ActionEstimate> estimates;
  std::vector<std::string> action_names;  // index-aligned with estimates
  int64_t model_version = 0;
  // LearnerModel::PredictedPosthoc at the context (poLinUCB); empty else.
  std::vector<double> predicted_posthoc;
};

struct UpdateInput {
  int64_t event_id = 0;
  double loss = 0.0;
  std::vector<double> posthoc;
};

struct UpdateResult {
  std::string user_id;
  int64_t model_version = 0;
  bool already_applied = false;
};

struct ActionModelExport {
  int action = 0;
  std::string action_name;
  int64_t count = 0;
  std::vector<double> theta;
  std::vector<double> phi;
  double mean_loss = 0.0;
};

struct ModelExport {
  UserRecord user;
  std::vector<ActionModelExport> actions;
};

// INVALID_ARGUMENT unless `user_id` is 1-128 characters of [A-Za-z0-9._-].
using ::bitewise::domain::ValidateUserId;

class BanditEngine {
 public:
  // `store` must outlive the engine.
  BanditEngine(EventStore* store, const EngineOptions& options);

  // `prior_rounds` > 0 starts the user from the newest population pool for
  // users like `config`, worth that many rounds (config.prior is replaced);
  // FAILED_PRECONDITION naming what is missing when there is no such pool.
  absl::StatusOr<UserRecord> CreateUser(const std::string& user_id,
                                        const BanditConfig& config,
                                        double prior_rounds = 0.0);

  // Pools every user like `like` (learner, context_dim, posthoc_dim, action
  // names) that has completed rounds, one model at a time, into a new
  // durable population pool, and returns it. Users' raw events are not
  // read beyond rebuilding their own models. FAILED_PRECONDITION when no
  // such user has a completed round; INVALID_ARGUMENT for a bad `like`.
  absl::StatusOr<PoolRecord> BuildPopulationPool(const BanditConfig& like);
  absl::StatusOr<UserRecord> GetUser(const std::string& user_id);
  absl::StatusOr<PageResult<UserRecord>> ListUsers(const Page& page);
  absl::StatusOr<UserRecord> ResetUser(const std::string& user_id);
  // Moves the user to `learner`, keeping every event: the model is rebuilt
  // from the log under the new learner at the next call (model_version
  // unchanged). The same learner changes nothing. INVALID_ARGUMENT for an
  // unknown learner or one whose model would not fit (as at CreateUser);
  // FAILED_PRECONDITION for a user started from a population pool (its
  // prior is of the old learner's statistics) or a log the new learner
  // cannot learn; ABORTED when another process completed a bite while the
  // log was read; NOT_FOUND if unknown. Nothing is changed when refused.
  absl::StatusOr<UserRecord> SetLearner(const std::string& user_id,
                                        Learner learner);
  absl::Status DeleteUser(const std::string& user_id);

  absl::StatusOr<SelectResult> Select(const SelectInput& input);
  absl::StatusOr<UpdateResult> Update(const UpdateInput& input);

  absl::StatusOr<ModelExport> GetModel(const std::string& user_id);
  // Every action's estimate at `context` from the user's current model, as
  // Select computes them (every learner's own prediction, width and lcb),
  // with no event and nothing changed. NOT_FOUND for an unknown user;
  // INVALID_ARGUMENT for a context of the wrong length or not finite.
  absl::StatusOr<EstimateResult> Estimate(const std::string& user_id,
                                          absl::Span<const double> context);
  absl::StatusOr<PageResult<EventRecord>> ListEvents(const std::string& user_id,
                                                     const std::string& meal_id,
                                                     const Page& page);

  // The store's full check (EventStore::CheckStore) and its audit log.
  absl::StatusOr<StoreCheckReport> CheckStore() { return store_->CheckStore(); }
  absl::StatusOr<PageResult<AuditEntry>> ListAudit(const Page& page) {
    return store_->ListAudit(page);
  }

  // Saves the user's loaded model as its checkpoint now if it has events
  // the last one does not cover (OK and nothing written otherwise, or when
  // the model is not loaded). What the background thread does when due.
  absl::Status CheckpointUser(const std::string& user_id);
  // At a clean stop (after the server drained): saves every loaded model
  // with at least checkpoint_min_events events its checkpoint does not
  // cover, so the next start needs no long replay, until `budget` has
  // passed. Returns how many were saved (errors are logged).
  int CheckpointAll(absl::Duration budget);

  ~BanditEngine();

  // Bytes held by loaded models, and how many are loaded.
  size_t CachedBytes() const;
  int CachedModels() const;

  // Cache activity since the engine started (for metrics).
  struct CacheCounters {
    int64_t hits = 0;      // a model was already loaded
    int64_t rebuilds = 0;  // a model was loaded (checkpoint or full log)
    double rebuild_seconds = 0.0;
    int64_t evictions = 0;            // models dropped for the cache budget
    int64_t checkpoint_loads = 0;     // loads that started from a checkpoint
    int64_t checkpoints_ignored = 0;  // damaged, stale or unreadable ones
    int64_t checkpoints_written = 0;
    // Shared stores: events another process completed, learned at a
    // call's start, and cached models dropped for another's reset.
    int64_t caught_up_events = 0;
    int64_t dropped_stale = 0;
    // Writes refused because another process had written to the user's
    // log since this one read it (each followed by a catch-up and a retry).
    int64_t write_conflicts = 0;
  };
  CacheCounters Counters() const;

 private:
  // A configuration a user may have here: valid, and its model within the
  // service's limits and cache budget and its GetModel reply within a
  // message (INVALID_ARGUMENT naming which).
  absl::Status CheckConfigFits(const BanditConfig& config) const;
  // Every completed round of the user's log, in order (`last_event_id`: the
  // last one's event, 0 for none).
  absl::StatusOr<std::vector<Round>> CompletedRounds(
      const std::string& user_id, int64_t* last_event_id = nullptr);
  struct UserSlot {
    absl::Mutex mu;
    // Loaded state, valid while `model` has a value.
    std::unique_ptr<LearnerModel> model ABSL_GUARDED_BY(mu);
    UserRecord record ABSL_GUARDED_BY(mu);
    int64_t select_count ABSL_GUARDED_BY(mu) = 0;
    // The latest Select's products, for the Update of that event (reused
    // only while the model has not changed; dropped with the model).
    int64_t products_event ABSL_GUARDED_BY(mu) = 0;
    SelectProducts products ABSL_GUARDED_BY(mu);
    // The latest Select's event as written (its id set), so its Update
    // need not read it back; taken by that Update, dropped with the model.
    std::optional<EventRecord> last_selected ABSL_GUARDED_BY(mu);
    // The event at the model's version (what a checkpoint of it names),
    // the version the newest checkpoint covers, and the last call's time.
    int64_t last_event_id ABSL_GUARDED_BY(mu) = 0;
    int64_t checkpoint_version ABSL_GUARDED_BY(mu) = 0;
    // The version of the checkpoint being written now (0: none): events
    // before it count as saved for deciding when the next one is due.
    int64_t checkpoint_saving ABSL_GUARDED_BY(mu) = 0;
    absl::Time last_used ABSL_GUARDED_BY(mu) = absl::InfinitePast();
    // Set by the Update that brings the model to checkpoint_max_events
    // unsaved events; taken by the checkpoint thread.
    std::atomic<bool> checkpoint_due{false};
    // Cache bookkeeping, guarded by the engine's cache_mu_.
    size_t bytes = 0;
    bool in_lru = false;
    std::list<UserSlot*>::iterator lru_pos;
  };

  // The slot for a user, created on first use. NOT_FOUND without creating
  // a slot if the store does not know the user and `create` is false.
  absl::StatusOr<std::shared_ptr<UserSlot>> Slot(const std::string& user_id,
                                                 bool create);
  // Loads the user's model if it is not loaded: from its checkpoint and the
  // events after it when there is a usable one, else rebuilt from the log.
  absl::Status EnsureLoaded(const std::string& user_id, UserSlot& slot)
      ABSL_EXCLUSIVE_LOCKS_REQUIRED(slot.mu);
  void Unload(UserSlot& slot) ABSL_EXCLUSIVE_LOCKS_REQUIRED(slot.mu);
  // Brings the slot up to the user's log when the store is shared by
  // several processes (replicas): reads where the log stands; a model of an
  // older log (another process reset or recreated the user) is dropped, one
  // behind it learns the events the others completed, one Update each (as
  // they learned them), and the select index becomes the log's count of
  // selections, so a user's k-th Select draws the same random numbers
  // whichever process answers. Then (any store) loads the model if it is
  // not loaded. Reads, and the retries after a conflict, start with it.
  absl::Status Sync(const std::string& user_id, UserSlot& slot)
      ABSL_EXCLUSIVE_LOCKS_REQUIRED(slot.mu);
  // Where the slot's model says the user's log stands.
  static UserLogPosition SlotPosition(const UserSlot& slot)
      ABSL_EXCLUSIVE_LOCKS_REQUIRED(slot.mu);
  // One try of Select or Update with the cached model (attempt 1) or one
  // brought up to the log (later attempts); nullopt when the write met
  // another process's (the caller tries again).
  absl::StatusOr<std::optional<SelectResult>> TrySelect(
      const SelectInput& input, UserSlot& slot, int attempt)
      ABSL_EXCLUSIVE_LOCKS_REQUIRED(slot.mu);
  absl::StatusOr<std::optional<UpdateResult>> TryUpdate(
      const UpdateInput& input, const EventRecord& found, UserSlot& slot,
      int attempt) ABSL_EXCLUSIVE_LOCKS_REQUIRED(slot.mu);
  // Whether `status` is a write refused for another process's (ABORTED
  // from a shared store) that may be tried again: counted; false from the
  // kMaxWriteAttempts-th attempt (then GiveUpAfterConflicts).
  bool RetryAfterConflict(const absl::Status& status, int attempt);
  // `status`, or UNAVAILABLE naming the user for the last attempt's
  // conflict (clients retry UNAVAILABLE; ABORTED would be dropped).
  absl::Status GiveUpAfterConflicts(const absl::Status& status,
                                    const std::string& user_id);
  static constexpr int kMaxWriteAttempts = 8;
  // The users of the events this process selected and not yet updated:
  // what lets an Update find its user's slot without reading the event.
  void RememberSelect(int64_t event_id, const std::string& user_id);
  std::optional<std::string> ForgetSelect(int64_t event_id);
  static constexpr size_t kRememberedSelects = 4096;
  // Records the slot's size as most recently used and evicts others.
  void Touch(UserSlot& slot) ABSL_EXCLUSIVE_LOCKS_REQUIRED(slot.mu);

  // Loads from the user's checkpoint and the events after it; nullopt
  // (after counting it) when there is none or it cannot be used.
  std::unique_ptr<LearnerModel> LoadFromCheckpoint(const UserRecord& record,
                                                   int64_t* last_event_id,
                                                   int64_t* checkpoint_version);
  // Saves `slot`'s model if due (or, with `force`, if it has anything new).
  absl::Status MaybeCheckpoint(const std::string& user_id, UserSlot& slot,
                               bool force, bool wait_for_lock);
  void CheckpointLoop();

  EventStore* const store_;
  const EngineOptions options_;

  mutable absl::Mutex slots_mu_;
  absl::flat_hash_map<std::string, std::shared_ptr<UserSlot>> slots_
      ABSL_GUARDED_BY(slots_mu_);

  absl::Mutex selects_mu_;
  absl::flat_hash_map<int64_t, std::string> recent_selects_
      ABSL_GUARDED_BY(selects_mu_);

  mutable absl::Mutex cache_mu_;
  std::list<UserSlot*> lru_ ABSL_GUARDED_BY(cache_mu_);  // front: newest
  size_t cached_bytes_ ABSL_GUARDED_BY(cache_mu_) = 0;
  CacheCounters counters_ ABSL_GUARDED_BY(cache_mu_);

  absl::Mutex stop_mu_;
  bool stop_ ABSL_GUARDED_BY(stop_mu_) = false;
  // An Update brought a model to checkpoint_max_events unsaved events: the
  // checkpoint thread looks now, and waits for that user's lock.
  bool checkpoint_wanted_ ABSL_GUARDED_BY(stop_mu_) = false;
  std::thread checkpointer_;
};

}  // namespace bitewise::bandit

#endif  // BITEWISE_SERVICES_BANDIT_ENGINE_H_
