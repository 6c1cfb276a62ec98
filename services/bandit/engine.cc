#include "services/bandit/engine.h"

#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <utility>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/time/clock.h"
#include "services/bandit/core/learners.h"
#include "services/bandit/core/policy.h"
#include "services/bandit/core/population_prior.h"
#include "services/common/status_macros.h"

namespace bitewise::bandit {

BanditEngine::BanditEngine(EventStore* store, const EngineOptions& options)
    : store_(store), options_(options) {
  if (options_.checkpoint_min_events > 0) {
    checkpointer_ = std::thread([this] { CheckpointLoop(); });
  }
}

BanditEngine::~BanditEngine() {
  {
    absl::MutexLock lock(&stop_mu_);
    stop_ = true;
  }
  if (checkpointer_.joinable()) checkpointer_.join();
}

void BanditEngine::CheckpointLoop() {
  while (true) {
    {
      absl::MutexLock lock(&stop_mu_);
      const auto woken = [this]() ABSL_SHARED_LOCKS_REQUIRED(stop_mu_) {
        return stop_ || checkpoint_wanted_;
      };
      stop_mu_.AwaitWithTimeout(absl::Condition(&woken),
                                options_.checkpoint_poll);
      if (stop_) return;
      checkpoint_wanted_ = false;
    }
    std::vector<std::pair<std::string, std::shared_ptr<UserSlot>>> slots;
    {
      absl::MutexLock lock(&slots_mu_);
      for (const auto& [user_id, slot] : slots_)
        slots.emplace_back(user_id, slot);
    }
    for (const auto& [user_id, slot] : slots) {
      const absl::Status status = MaybeCheckpoint(
          user_id, *slot, /*force=*/false,
          /*wait_for_lock=*/slot->checkpoint_due.exchange(false));
      if (!status.ok()) {
        std::fprintf(stderr,
                     "bitewise-bandit: checkpoint of user %s not written: %s\n",
                     user_id.c_str(),
                     status.ToString(absl::StatusToStringMode::kWithNoExtraData)
                         .c_str());
      }
    }
  }
}

absl::Status BanditEngine::CheckpointUser(const std::string& user_id) {
  ASSIGN_OR_RETURN(std::shared_ptr<UserSlot> slot, Slot(user_id, false));
  return MaybeCheckpoint(user_id, *slot, /*force=*/true,
                         /*wait_for_lock=*/true);
}

int BanditEngine::CheckpointAll(absl::Duration budget) {
  const absl::Time deadline = absl::Now() + budget;
  std::vector<std::pair<std::string, std::shared_ptr<UserSlot>>> slots;
  {
    absl::MutexLock lock(&slots_mu_);
    for (const auto& [user_id, slot] : slots_)
      slots.emplace_back(user_id, slot);
  }
  int saved = 0;
  for (const auto& [user_id, slot] : slots) {
    if (absl::Now() > deadline || options_.checkpoint_min_events <= 0) break;
    {
      absl::MutexLock lock(&slot->mu);
      if (slot->model == nullptr ||
          slot->model->TotalRounds() - slot->checkpoint_version <
              options_.checkpoint_min_events) {
        continue;
      }
    }
    const absl::Status status = MaybeCheckpoint(user_id, *slot,
                                                /*force=*/true,
                                                /*wait_for_lock=*/true);
    if (status.ok()) {
      ++saved;
    } else {
      std::fprintf(
          stderr, "bitewise-bandit: checkpoint of user %s not written: %s\n",
          user_id.c_str(),
          status.ToString(absl::StatusToStringMode::kWithNoExtraData).c_str());
    }
  }
  return saved;
}

absl::Status BanditEngine::MaybeCheckpoint(
    const std::string& user_id, UserSlot& slot, bool force,
    bool wait_for_lock) ABSL_NO_THREAD_SAFETY_ANALYSIS {
  ModelCheckpoint checkpoint;
  // The state's storage, allocated and touched before the user's lock is
  // taken, so the copy under the lock is only a copy (at d = 2048 about
  // 100 MB: page faults would double its time).
  std::string buffer;
  for (int attempt = 0;; ++attempt) {
    if (wait_for_lock) {
      slot.mu.Lock();
    } else if (!slot.mu.TryLock()) {
      // In use: next poll. (A model at checkpoint_max_events does not wait
      // for a free moment: its Update set checkpoint_due, and this is
      // called waiting for the lock.)
      return absl::OkStatus();
    }
    const bool loaded = slot.model != nullptr;
    const int64_t version = loaded ? slot.model->TotalRounds() : 0;
    const int64_t fresh =
        version - std::max(slot.checkpoint_version, slot.checkpoint_saving);
    const bool due =
        force ? fresh > 0
              : fresh >= options_.checkpoint_min_events &&
                    (fresh >= options_.checkpoint_max_events ||
                     absl::Now() - slot.last_used >= options_.checkpoint_idle);
    if (!loaded || !due || slot.last_event_id == 0) {
      slot.mu.Unlock();
      return absl::OkStatus();
    }
    const size_t needed = slot.model->StateBytesBound();
    if (buffer.size() < needed && attempt == 0) {
      slot.mu.Unlock();
      buffer.resize(needed);  // zero-filled: every page touched
      wait_for_lock = true;
      continue;
    }
    checkpoint.model_version = version;
    checkpoint.last_event_id = slot.last_event_id;
    checkpoint.learner = slot.model->config().learner;
    checkpoint.created_at = absl::Now();
    slot.model->SaveState(&buffer);
    checkpoint.state = std::move(buffer);
    slot.checkpoint_saving = version;
    break;
  }
  slot.mu.Unlock();
  // Written outside the user's lock, in chunks: nobody waits for it.
  const absl::Status written = store_->PutCheckpoint(user_id, checkpoint);
  {
    absl::MutexLock lock(&slot.mu);
    if (slot.checkpoint_saving == checkpoint.model_version) {
      slot.checkpoint_saving = 0;
    }
  }
  if (absl::IsFailedPrecondition(written) || absl::IsNotFound(written)) {
    // The log no longer has this model's last event, or the user is gone
    // (reset or deleted, by another replica): the model is stale, and is
    // dropped rather than offered again every poll.
    absl::MutexLock lock(&slot.mu);
    if (slot.model != nullptr &&
        slot.model->TotalRounds() == checkpoint.model_version &&
        slot.last_event_id == checkpoint.last_event_id &&
        slot.model->config().learner == checkpoint.learner) {
      Unload(slot);
    }
  }
  RETURN_IF_ERROR(written);
  {
    absl::MutexLock lock(&slot.mu);
    slot.checkpoint_version =
        std::max(slot.checkpoint_version, checkpoint.model_version);
  }
  absl::MutexLock lock(&cache_mu_);
  ++counters_.checkpoints_written;
  return absl::OkStatus();
}

std::unique_ptr<LearnerModel> BanditEngine::LoadFromCheckpoint(
    const UserRecord& record, int64_t* last_event_id,
    int64_t* checkpoint_version) {
  const std::string& user_id = record.user_id;
  absl::StatusOr<ModelCheckpoint> checkpoint = store_->GetCheckpoint(user_id);
  if (!checkpoint.ok() && absl::IsNotFound(checkpoint.status())) {
    return nullptr;
  }
  absl::Status why = checkpoint.status();
  std::unique_ptr<LearnerModel> model;
  if (why.ok() && checkpoint->model_version > record.model_version) {
    why = absl::FailedPreconditionError("it is newer than the log");
  }
  absl::StatusOr<std::vector<EventRecord>> tail;
  if (why.ok()) {
    tail = store_->CompletedEventsFrom(user_id, checkpoint->model_version);
    why = tail.status();
  }
  if (why.ok() &&
      (tail->empty() || tail->front().event_id != checkpoint->last_event_id)) {
    why = absl::FailedPreconditionError(
        absl::StrCat("the log has another event at model version ",
                     checkpoint->model_version));
  }
  if (why.ok()) {
    absl::StatusOr<std::unique_ptr<LearnerModel>> loaded =
        LoadModel(record.config, checkpoint->state, options_.primal_threshold);
    why = loaded.status();
    if (why.ok()) model = *std::move(loaded);
  }
  if (why.ok()) {
    std::vector<Round> rounds;
    rounds.reserve(tail->size() - 1);
    for (size_t i = 1; i < tail->size() && why.ok(); ++i) {
      rounds.push_back(EventRound(std::move((*tail)[i])));
      why = model->ValidateRound(rounds.back());
    }
    if (why.ok()) model->Replay(rounds);
  }
  if (!why.ok()) {
    std::fprintf(
        stderr,
        "bitewise-bandit: the model checkpoint of user %s is not "
        "used (%s); rebuilding from the whole log\n",
        user_id.c_str(),
        why.ToString(absl::StatusToStringMode::kWithNoExtraData).c_str());
    absl::MutexLock lock(&cache_mu_);
    ++counters_.checkpoints_ignored;
    return nullptr;
  }
  *last_event_id = tail->back().event_id;
  *checkpoint_version = checkpoint->model_version;
  absl::MutexLock lock(&cache_mu_);
  ++counters_.checkpoint_loads;
  return model;
}

absl::StatusOr<std::shared_ptr<BanditEngine::UserSlot>> BanditEngine::Slot(
    const std::string& user_id, bool create) {
  RETURN_IF_ERROR(ValidateUserId(user_id));
  {
    absl::MutexLock lock(&slots_mu_);
    auto it = slots_.find(user_id);
    if (it != slots_.end()) return it->second;
  }
  // Unknown ids do not get a slot, so lookups of made-up users cost nothing.
  if (!create) RETURN_IF_ERROR(store_->GetUser(user_id).status());
  absl::MutexLock lock(&slots_mu_);
  std::shared_ptr<UserSlot>& slot = slots_[user_id];
  if (slot == nullptr) slot = std::make_shared<UserSlot>();
  return slot;
}

absl::Status BanditEngine::EnsureLoaded(const std::string& user_id,
                                        UserSlot& slot) {
  if (slot.model != nullptr) {
    {
      absl::MutexLock lock(&cache_mu_);
      ++counters_.hits;
    }
    Touch(slot);
    return absl::OkStatus();
  }
  const absl::Time start = absl::Now();
  ASSIGN_OR_RETURN(UserRecord record, store_->GetUser(user_id));
  int64_t last_event_id = 0, checkpoint_version = 0;
  std::unique_ptr<LearnerModel> model;
  if (record.model_version > 0) {
    model = LoadFromCheckpoint(record, &last_event_id, &checkpoint_version);
  }
  if (model == nullptr) {
    ASSIGN_OR_RETURN(const std::vector<Round> rounds,
                     CompletedRounds(user_id, &last_event_id));
    ASSIGN_OR_RETURN(
        model, RebuildModel(record.config, rounds, options_.primal_threshold));
  }
  // Selects since creation or reset index the user's random stream. With
  // replicas the log may have moved between the reads: the model counts
  // what it learned, and the writes conditioned on this find any other.
  slot.select_count = record.model_version + record.pending_events;
  record.model_version = model->TotalRounds();
  record.pending_events = slot.select_count - record.model_version;
  slot.record = std::move(record);
  slot.model = std::move(model);
  slot.last_event_id = last_event_id;
  slot.checkpoint_version = checkpoint_version;
  {
    absl::MutexLock lock(&cache_mu_);
    ++counters_.rebuilds;
    counters_.rebuild_seconds += absl::ToDoubleSeconds(absl::Now() - start);
  }
  Touch(slot);
  return absl::OkStatus();
}

absl::Status BanditEngine::Sync(const std::string& user_id, UserSlot& slot) {
  if (!store_->shared()) return EnsureLoaded(user_id, slot);
  ASSIGN_OR_RETURN(UserLogPosition log, store_->LogPosition(user_id));
  if (slot.model != nullptr &&
      (log.incarnation != slot.record.incarnation ||
       log.model_version < slot.record.model_version)) {
    Unload(slot);
    absl::MutexLock cache(&cache_mu_);
    ++counters_.dropped_stale;
  }
  if (slot.model != nullptr && log.model_version > slot.record.model_version) {
    ASSIGN_OR_RETURN(
        std::vector<EventRecord> events,
        store_->CompletedEventsFrom(user_id, slot.record.model_version + 1));
    int64_t version = slot.record.model_version;
    for (EventRecord& event : events) {
      const int64_t event_id = event.event_id;
      const int64_t event_version = event.model_version;
      const Round round = EventRound(std::move(event));
      // Not the next one (the log started over meanwhile), or a stored
      // event the model refuses: start afresh from the log.
      if (event_version != version + 1) {
        Unload(slot);
        break;
      }
      if (absl::Status valid = slot.model->ValidateRound(round); !valid.ok()) {
        Unload(slot);
        return valid;
      }
      slot.model->Update(round, nullptr);
      version = event_version;
      slot.last_event_id = event_id;
    }
    if (slot.model != nullptr && version < log.model_version) {
      // Fewer events than the position said (the log started over
      // meanwhile): start afresh rather than from a shifted random stream.
      Unload(slot);
    }
    if (slot.model != nullptr && !events.empty()) {
      // The events were read after the position: if the log started over
      // in between (a new incarnation, never an old one again), some may
      // be the new log's. The model is then of neither.
      const absl::StatusOr<UserLogPosition> after =
          store_->LogPosition(user_id);
      if (!after.ok()) {
        // The model already holds the events: not knowing whether they
        // were the log's, it must not be kept as if it did not.
        Unload(slot);
        return after.status();
      }
      if (after->incarnation != log.incarnation) Unload(slot);
    }
    if (slot.model != nullptr) {
      // The Select products were of the older model.
      slot.products_event = 0;
      slot.products = SelectProducts();
      slot.record.model_version = version;
      absl::MutexLock cache(&cache_mu_);
      counters_.caught_up_events += static_cast<int64_t>(events.size());
    }
  }
  if (slot.model != nullptr) {
    // Events completed after the position was read leave the count of
    // selections as it was read: a conditioned write then finds it stale.
    slot.select_count = log.model_version + log.pending_events;
    slot.record.pending_events = slot.select_count - slot.record.model_version;
  }
  return EnsureLoaded(user_id, slot);
}

bool BanditEngine::RetryAfterConflict(const absl::Status& status, int attempt) {
  if (!absl::IsAborted(status) || !store_->shared()) return false;
  absl::MutexLock cache(&cache_mu_);
  ++counters_.write_conflicts;
  return attempt < kMaxWriteAttempts;
}

absl::Status BanditEngine::GiveUpAfterConflicts(const absl::Status& status,
                                                const std::string& user_id) {
  if (!absl::IsAborted(status) || !store_->shared()) return status;
  // UNAVAILABLE: clients retry it (and the orchestrator keeps the Update
  // in its journal), which is what it needs.
  return absl::UnavailableError(absl::StrCat(
      "user \"", user_id,
      "\": other processes wrote to the user's log at each of ",
      kMaxWriteAttempts, " attempts; nothing was written, try again (",
      status.message(), ")"));
}

UserLogPosition BanditEngine::SlotPosition(const UserSlot& slot) {
  return UserLogPosition{slot.record.model_version,
                         slot.select_count - slot.record.model_version,
                         slot.record.incarnation};
}

void BanditEngine::Unload(UserSlot& slot) {
  slot.model.reset();
  slot.last_selected.reset();
  slot.checkpoint_version = 0;
  slot.checkpoint_saving = 0;
  slot.last_event_id = 0;
  slot.products_event = 0;
  slot.products = SelectProducts();
  absl::MutexLock lock(&cache_mu_);
  if (slot.in_lru) {
    lru_.erase(slot.lru_pos);
    slot.in_lru = false;
    cached_bytes_ -= slot.bytes;
    slot.bytes = 0;
  }
}

void BanditEngine::Touch(UserSlot& slot) {
  // The model and the latest Select's products the user's Update will use.
  const size_t bytes =
      slot.model->MemoryBytes() + slot.products.Bytes() +
      (slot.last_selected.has_value()
           ? sizeof(double) * slot.last_selected->context.size()
           : 0);
  absl::MutexLock lock(&cache_mu_);
  if (slot.in_lru) {
    lru_.erase(slot.lru_pos);
    cached_bytes_ -= slot.bytes;
  }
  lru_.push_front(&slot);
  slot.lru_pos = lru_.begin();
  slot.in_lru = true;
  slot.bytes = bytes;
  cached_bytes_ += bytes;
  // Evict from the oldest end; a model in use (its mutex held) is skipped
  // rather than waited for, which also rules out lock-order deadlocks.
  auto it = lru_.end();
  while (cached_bytes_ > options_.cache_budget_bytes && it != lru_.begin()) {
    --it;
    UserSlot* victim = *it;
    if (victim == &slot || !victim->mu.TryLock()) continue;
    victim->model.reset();
    victim->products_event = 0;
    victim->products = SelectProducts();
    victim->last_selected.reset();
    victim->checkpoint_version = 0;
    victim->checkpoint_saving = 0;
    victim->last_event_id = 0;
    cached_bytes_ -= victim->bytes;
    victim->bytes = 0;
    victim->in_lru = false;
    ++counters_.evictions;
    it = lru_.erase(it);
    victim->mu.Unlock();
  }
}

size_t MaxModelBytes(const BanditConfig& config) {
  const double d = config.context_dim;
  const double q = config.posthoc_dim;
  const double per_action = 2 * d * d + 2 * d * q + q * q + 4 * (d + q);
  const double bytes = 8.0 * config.num_actions() * per_action;
  return bytes >= static_cast<double>(std::numeric_limits<size_t>::max())
             ? std::numeric_limits<size_t>::max()
             : static_cast<size_t>(bytes);
}

size_t ModelReplyBytes(const BanditConfig& config) {
  size_t names = 0;
  for (const std::string& name : config.action_names) names += name.size();
  const size_t doubles = static_cast<size_t>(config.num_actions()) *
                         (static_cast<size_t>(config.context_dim) +
                          static_cast<size_t>(config.posthoc_dim));
  // Twice: the model and a prior of the same shape; 32 bytes of tags and
  // lengths per action; 1 KB for the rest of the config.
  return 2 * (8 * doubles + names + 32 * config.action_names.size()) + 1024;
}

namespace {

// CheckEstimatesFinite, naming the user.
absl::Status FiniteFor(const std::string& user_id,
                       const std::vector<ActionEstimate>& estimates) {
  absl::Status finite = CheckEstimatesFinite(estimates);
  if (finite.ok()) return finite;
  return absl::Status(finite.code(), absl::StrCat("user \"", user_id,
                                                  "\": ", finite.message()));
}

// INVALID_ARGUMENT naming the configuration, the limit and its flag when a
// model of `config` could grow to `bytes`, beyond `limit`.
absl::Status CheckModelFits(const BanditConfig& config, size_t bytes,
                            size_t limit, const char* what, const char* flag) {
  if (bytes <= limit) return absl::OkStatus();
  return absl::InvalidArgumentError(absl::StrFormat(
      "config: a model with context_dim %d, posthoc_dim %d and %d actions "
      "can grow to %.1f GB, over %s of %.1f GB (%s); use fewer dimensions "
      "or actions",
      config.context_dim, config.posthoc_dim, config.num_actions(), bytes / 1e9,
      what, limit / 1e9, flag));
}

}  // namespace

absl::StatusOr<std::vector<Round>> BanditEngine::CompletedRounds(
    const std::string& user_id, int64_t* last_event_id) {
  ASSIGN_OR_RETURN(std::vector<EventRecord> events,
                   store_->CompletedEvents(user_id));
  if (last_event_id != nullptr) {
    *last_event_id = events.empty() ? 0 : events.back().event_id;
  }
  std::vector<Round> rounds;
  rounds.reserve(events.size());
  for (EventRecord& event : events) {
    rounds.push_back(EventRound(std::move(event)));
  }
  return rounds;
}

absl::Status BanditEngine::CheckConfigFits(const BanditConfig& config) const {
  RETURN_IF_ERROR(ValidateConfig(config));
  const size_t worst_bytes = MaxModelBytes(config);
  RETURN_IF_ERROR(CheckModelFits(config, worst_bytes, options_.max_model_bytes,
                                 "this service's limit", "--max_model_mb"));
  if (const size_t bytes = ModelReplyBytes(config);
      bytes > options_.max_reply_bytes) {
    return absl::InvalidArgumentError(absl::StrFormat(
        "config: GetModel's reply for context_dim %d, posthoc_dim %d and %d "
        "actions would take about %.1f MB, over the %.1f MB a reply may take "
        "(4 MiB message limit); use fewer dimensions or actions",
        config.context_dim, config.posthoc_dim, config.num_actions(),
        bytes / 1e6, options_.max_reply_bytes / 1e6));
  }
  // A model that cannot fit the cache budget on its own would be rebuilt
  // from the log at every call: refused like one over the limit.
  return CheckModelFits(config, worst_bytes, options_.cache_budget_bytes,
                        "this service's whole model cache",
                        "--cache_budget_mb");
}

absl::StatusOr<UserRecord> BanditEngine::CreateUser(
    const std::string& user_id, const BanditConfig& requested,
    double prior_rounds) {
  RETURN_IF_ERROR(CheckConfigFits(requested));
  if (!std::isfinite(prior_rounds) || prior_rounds < 0.0 ||
      prior_rounds > 1e6) {
    return absl::InvalidArgumentError(absl::StrCat(
        "config.prior_rounds: must be in [0, 1e6], got ", prior_rounds));
  }
  BanditConfig config = requested;
  if (prior_rounds > 0.0) {
    absl::StatusOr<PoolRecord> pool = store_->LatestPool(config);
    if (absl::IsNotFound(pool.status())) {
      return absl::FailedPreconditionError(pool.status().message());
    }
    RETURN_IF_ERROR(pool.status());
    config.prior = std::move(pool->prior);
    config.prior.rounds = prior_rounds;
    RETURN_IF_ERROR(ValidateConfig(config));
  }
  ASSIGN_OR_RETURN(std::shared_ptr<UserSlot> slot, Slot(user_id, true));
  absl::MutexLock lock(&slot->mu);
  UserRecord record;
  record.user_id = user_id;
  record.config = config;
  record.created_at = absl::FromUnixMicros(absl::ToUnixMicros(absl::Now()));
  RETURN_IF_ERROR(store_->CreateUser(record));
  Unload(*slot);
  return record;
}

absl::StatusOr<PoolRecord> BanditEngine::BuildPopulationPool(
    const BanditConfig& like) {
  RETURN_IF_ERROR(ValidateConfig(like));
  PriorPool pool(like);
  Page page;
  page.page_size = 1000;
  while (true) {
    ASSIGN_OR_RETURN(PageResult<UserRecord> users, store_->ListUsers(page));
    for (const UserRecord& user : users.items) {
      if (user.model_version == 0) continue;
      absl::StatusOr<std::shared_ptr<UserSlot>> slot =
          Slot(user.user_id, false);
      if (absl::IsNotFound(slot.status())) continue;  // deleted meanwhile
      RETURN_IF_ERROR(slot.status());
      absl::MutexLock lock(&(*slot)->mu);
      // Up to the log, with replicas: another process may have taught it.
      const absl::Status synced = Sync(user.user_id, **slot);
      if (absl::IsNotFound(synced)) continue;
      RETURN_IF_ERROR(synced);
      const LearnerModel& model = *(*slot)->model;
      if (model.TotalRounds() > 0 && pool.Accepts(model)) {
        if (absl::Status added = pool.Add(model); !added.ok()) {
          return absl::Status(
              added.code(),
              absl::StrCat("user \"", user.user_id, "\": ", added.message(),
                           "; nothing pooled (CheckStore, then ResetUser if "
                           "it persists)"));
        }
      }
    }
    if (users.next_page_token.empty()) break;
    page.page_token = users.next_page_token;
  }
  if (pool.users() == 0) {
    return absl::FailedPreconditionError(absl::StrCat(
        "no ", LearnerName(like.learner), " user with context_dim ",
        like.context_dim, " and these ", like.num_actions(),
        " actions has completed rounds; nothing to pool"));
  }
  PoolRecord record;
  record.created_at = absl::FromUnixMicros(absl::ToUnixMicros(absl::Now()));
  record.users = pool.users();
  record.learner = like.learner;
  record.context_dim = like.context_dim;
  record.posthoc_dim = UsesPosthoc(like.learner) ? like.posthoc_dim : 0;
  record.action_names = like.action_names;
  // The version is the store's; the vectors do not depend on it.
  ASSIGN_OR_RETURN(record.prior, pool.Finish(/*rounds=*/0.0, 1));
  ASSIGN_OR_RETURN(record.pool_version, store_->AddPool(record));
  record.prior.pool_version = record.pool_version;
  return record;
}

absl::StatusOr<UserRecord> BanditEngine::GetUser(const std::string& user_id) {
  RETURN_IF_ERROR(ValidateUserId(user_id));
  return store_->GetUser(user_id);
}

absl::StatusOr<PageResult<UserRecord>> BanditEngine::ListUsers(
    const Page& page) {
  return store_->ListUsers(page);
}

absl::StatusOr<UserRecord> BanditEngine::ResetUser(const std::string& user_id) {
  ASSIGN_OR_RETURN(std::shared_ptr<UserSlot> slot, Slot(user_id, false));
  absl::MutexLock lock(&slot->mu);
  RETURN_IF_ERROR(store_->ResetUser(user_id));
  Unload(*slot);
  return store_->GetUser(user_id);
}

absl::StatusOr<UserRecord> BanditEngine::SetLearner(const std::string& user_id,
                                                    Learner learner) {
  if (FindLearner(learner) == nullptr) {
    return absl::InvalidArgumentError(
        absl::StrCat("learner: unknown learner ", static_cast<int>(learner),
                     "; expected one of ", LearnerNames()));
  }
  ASSIGN_OR_RETURN(std::shared_ptr<UserSlot> slot, Slot(user_id, false));
  absl::MutexLock lock(&slot->mu);
  ASSIGN_OR_RETURN(UserRecord user, store_->GetUser(user_id));
  if (user.config.learner == learner) return user;
  if (user.config.prior.enabled()) {
    return absl::FailedPreconditionError(absl::StrCat(
        "user \"", user_id, "\" started from population pool ",
        user.config.prior.pool_version, " of ",
        LearnerName(user.config.learner),
        " users, whose prior does not carry to ", LearnerName(learner),
        "; keep the learner, or delete the user and create it again with the "
        "new one (that forgets the history; ResetUser keeps the prior)"));
  }
  BanditConfig config = user.config;
  config.learner = learner;
  RETURN_IF_ERROR(CheckConfigFits(config));
  // The new learner must be able to learn every round of the log (a
  // context-only user's rounds may have no post hoc context): rebuilt
  // here, before anything is written; the write then requires the log to
  // be the one checked (another process may complete a bite meanwhile).
  int64_t checked = 0;
  {
    ASSIGN_OR_RETURN(const std::vector<Round> rounds, CompletedRounds(user_id));
    checked = static_cast<int64_t>(rounds.size());
    if (absl::StatusOr<std::unique_ptr<LearnerModel>> rebuilt =
            RebuildModel(config, rounds, options_.primal_threshold);
        !rebuilt.ok()) {
      return absl::FailedPreconditionError(
          absl::StrCat("user \"", user_id, "\"'s log cannot be learned by ",
                       LearnerName(learner), ": ", rebuilt.status().message(),
                       "; the learner is unchanged"));
    }
  }
  RETURN_IF_ERROR(store_->SetLearner(user_id, learner, checked));
  Unload(*slot);
  return store_->GetUser(user_id);
}

absl::Status BanditEngine::DeleteUser(const std::string& user_id) {
  ASSIGN_OR_RETURN(std::shared_ptr<UserSlot> slot, Slot(user_id, false));
  absl::MutexLock lock(&slot->mu);
  RETURN_IF_ERROR(store_->DeleteUser(user_id));
  Unload(*slot);
  return absl::OkStatus();
}

absl::StatusOr<SelectResult> BanditEngine::Select(const SelectInput& input) {
  for (const auto& [field, value] :
       {std::pair{"meal_id", &input.meal_id},
        std::pair{"item_label", &input.item_label}}) {
    if (value->size() > kMaxLabelBytes) {
      return absl::InvalidArgumentError(absl::StrCat(
          field, ": at most ", kMaxLabelBytes, " bytes, got ", value->size()));
    }
    // Valid UTF-8 (proto3 checks that), but PostgreSQL's text refuses it.
    if (const size_t nul = value->find('\0'); nul != std::string::npos) {
      return absl::InvalidArgumentError(absl::StrCat(
          field, ": must not contain a NUL byte (at byte ", nul, ")"));
    }
  }
  ASSIGN_OR_RETURN(std::shared_ptr<UserSlot> slot, Slot(input.user_id, false));
  absl::MutexLock lock(&slot->mu);
  for (int attempt = 1;; ++attempt) {
    ASSIGN_OR_RETURN(std::optional<SelectResult> result,
                     TrySelect(input, *slot, attempt));
    if (result.has_value()) return *std::move(result);
  }
}

absl::StatusOr<std::optional<SelectResult>> BanditEngine::TrySelect(
    const SelectInput& input, UserSlot& slot, int attempt) {
  RETURN_IF_ERROR(attempt == 1 ? EnsureLoaded(input.user_id, slot)
                               : Sync(input.user_id, slot));
  const LearnerModel& model = *slot.model;
  RETURN_IF_ERROR(model.ValidateContext(input.context));
  RETURN_IF_ERROR(ValidateInputScale(model.config(), input.context, {}));

  SelectResult result;
  SelectProducts products;
  result.estimates = model.Estimate(input.context, &products);
  RETURN_IF_ERROR(FiniteFor(input.user_id, result.estimates));
  result.predicted_posthoc = model.PredictedPosthoc(input.context);
  std::mt19937_64 rng = SelectRng(slot.record.config.seed, slot.select_count);
  const Choice choice = ChooseAction(model.config(), result.estimates, rng);

  EventRecord event;
  event.user_id = input.user_id;
  event.meal_id = input.meal_id;
  event.item_label = input.item_label;
  event.context = input.context;
  event.action = choice.action;
  event.propensity = choice.propensity;
  event.selected_at = absl::Now();
  absl::StatusOr<int64_t> event_id =
      store_->shared() ? store_->AppendPendingAt(event, SlotPosition(slot))
                       : store_->AppendPending(event);
  if (RetryAfterConflict(event_id.status(), attempt)) return std::nullopt;
  RETURN_IF_ERROR(GiveUpAfterConflicts(event_id.status(), input.user_id));
  result.event_id = *event_id;
  ++slot.select_count;
  ++slot.record.pending_events;
  event.event_id = *event_id;
  slot.last_selected = std::move(event);
  RememberSelect(*event_id, input.user_id);
  slot.products_event = result.event_id;
  slot.products = std::move(products);
  slot.last_used = absl::Now();
  Touch(slot);

  result.action = choice.action;
  result.action_name = model.config().action_names[choice.action];
  result.action_names = model.config().action_names;
  result.propensity = choice.propensity;
  result.model_version = model.TotalRounds();
  return result;
}

absl::StatusOr<UpdateResult> BanditEngine::Update(const UpdateInput& input) {
  if (input.event_id <= 0) {
    return absl::InvalidArgumentError(absl::StrCat(
        "event_id: must be a positive integer, got ", input.event_id));
  }
  // The event as this process's Select wrote it, without a read when it is
  // still remembered (its selection never changes; whether it is still
  // pending, the store decides when completing it).
  std::optional<EventRecord> found;
  std::shared_ptr<UserSlot> slot;
  if (std::optional<std::string> user = ForgetSelect(input.event_id)) {
    absl::StatusOr<std::shared_ptr<UserSlot>> remembered = Slot(*user, false);
    if (remembered.ok()) slot = *std::move(remembered);
  }
  if (slot == nullptr) {
    ASSIGN_OR_RETURN(found, store_->GetEvent(input.event_id));
    ASSIGN_OR_RETURN(slot, Slot(found->user_id, false));
  }
  absl::MutexLock lock(&slot->mu);
  if (!found.has_value()) {
    if (slot->last_selected.has_value() &&
        slot->last_selected->event_id == input.event_id) {
      found = std::move(slot->last_selected);
      slot->last_selected.reset();
    } else {
      ASSIGN_OR_RETURN(found, store_->GetEvent(input.event_id));
    }
  }
  for (int attempt = 1;; ++attempt) {
    ASSIGN_OR_RETURN(std::optional<UpdateResult> result,
                     TryUpdate(input, *found, *slot, attempt));
    if (result.has_value()) return *std::move(result);
  }
}

void BanditEngine::RememberSelect(int64_t event_id,
                                  const std::string& user_id) {
  absl::MutexLock lock(&selects_mu_);
  // Bounded: past the limit the oldest are not told apart, and their
  // Updates read the event instead.
  if (recent_selects_.size() >= kRememberedSelects) recent_selects_.clear();
  recent_selects_[event_id] = user_id;
}

std::optional<std::string> BanditEngine::ForgetSelect(int64_t event_id) {
  absl::MutexLock lock(&selects_mu_);
  auto it = recent_selects_.find(event_id);
  if (it == recent_selects_.end()) return std::nullopt;
  std::string user_id = std::move(it->second);
  recent_selects_.erase(it);
  return user_id;
}

absl::StatusOr<std::optional<UpdateResult>> BanditEngine::TryUpdate(
    const UpdateInput& input, const EventRecord& found, UserSlot& slot,
    int attempt) {
  RETURN_IF_ERROR(attempt == 1 ? EnsureLoaded(found.user_id, slot)
                               : Sync(found.user_id, slot));
  LearnerModel& model = *slot.model;
  // Bad input is an error even on a retry of a completed event.
  RETURN_IF_ERROR(model.ValidateOutcome(input.loss, input.posthoc));
  UpdateResult result;
  result.user_id = found.user_id;
  // A retry carries the same outcome; another outcome is a conflict, and
  // the client must learn that its outcome was not the one recorded.
  auto answer_retry =
      [&](const EventRecord& event) -> absl::StatusOr<UpdateResult> {
    if (input.loss != event.loss) {
      return absl::AlreadyExistsError(absl::StrCat(
          "event ", event.event_id, " was completed with loss ", event.loss,
          "; this Update says ", input.loss, " (not applied)"));
    }
    if (input.posthoc != event.posthoc) {
      return absl::AlreadyExistsError(absl::StrCat(
          "event ", event.event_id,
          " was completed with another posthoc vector (not applied)"));
    }
    result.model_version = event.model_version;
    result.already_applied = true;
    return result;
  };
  if (found.completed) return answer_retry(found);
  // A new outcome's post hoc context, as a request (a retry of one applied
  // before this check existed is answered above).
  RETURN_IF_ERROR(ValidateInputScale(model.config(), {}, input.posthoc));

  // The selection (read before the user's lock, or remembered from this
  // process's Select) is what was stored, and never changes; whether the
  // event is still pending, the store decides.
  Round round = EventRound(found);
  round.loss = input.loss;
  round.posthoc = input.posthoc;
  round.weight =
      model.config().importance_weighting ? 1.0 / found.propensity : 1.0;
  // The stored event is validated like the request: a log written by an
  // older build must not corrupt the model.
  RETURN_IF_ERROR(model.ValidateRound(round));

  absl::StatusOr<EventRecord> completed =
      store_->shared()
          ? store_->CompleteEventAt(found.user_id, found.event_id, round.loss,
                                    round.posthoc, round.weight, absl::Now(),
                                    SlotPosition(slot))
          : store_->CompleteEvent(found.event_id, round.loss, round.posthoc,
                                  round.weight, absl::Now());
  if (RetryAfterConflict(completed.status(), attempt)) return std::nullopt;
  if (absl::IsFailedPrecondition(completed.status())) {
    // Completed since the first read (a concurrent retry): answer as one.
    ASSIGN_OR_RETURN(const EventRecord now, store_->GetEvent(found.event_id));
    if (now.completed) return answer_retry(now);
  }
  RETURN_IF_ERROR(GiveUpAfterConflicts(completed.status(), found.user_id));
  if (completed->model_version != slot.record.model_version + 1) {
    // Not the next version of the cached model (unreachable: one process
    // serialises a store's writes, and replicas write at the model's
    // version): the model is rebuilt from the log at the next call.
    Unload(slot);
    result.model_version = completed->model_version;
    return result;
  }
  model.Update(
      round, slot.products_event == found.event_id ? &slot.products : nullptr);
  if (options_.checkpoint_min_events > 0 &&
      model.TotalRounds() -
              std::max(slot.checkpoint_version, slot.checkpoint_saving) >=
          std::max(options_.checkpoint_max_events,
                   options_.checkpoint_min_events) &&
      !slot.checkpoint_due.exchange(true)) {
    // Due whether or not its user ever pauses: the checkpoint thread is
    // told now and waits for this lock (a call's length) to take it.
    absl::MutexLock lock(&stop_mu_);
    checkpoint_wanted_ = true;
  }
  slot.products_event = 0;
  slot.products = SelectProducts();
  slot.last_event_id = completed->event_id;
  slot.last_used = absl::Now();
  slot.record.model_version = completed->model_version;
  --slot.record.pending_events;
  Touch(slot);
  result.model_version = completed->model_version;
  return result;
}

absl::StatusOr<ModelExport> BanditEngine::GetModel(const std::string& user_id) {
  ASSIGN_OR_RETURN(std::shared_ptr<UserSlot> slot, Slot(user_id, false));
  absl::MutexLock lock(&slot->mu);
  RETURN_IF_ERROR(Sync(user_id, *slot));
  const LearnerModel& model = *slot->model;
  ModelExport out;
  ASSIGN_OR_RETURN(out.user, store_->GetUser(user_id));
  // The position is the model's, not the store's now: another replica may
  // have completed an event since Sync, and a reply pairing version v + 1
  // with the numbers of version v would mislead an analysis.
  out.user.model_version = model.TotalRounds();
  out.user.config = slot->record.config;
  for (int a = 0; a < model.num_actions(); ++a) {
    ActionModelExport action;
    action.action = a;
    action.action_name = model.config().action_names[a];
    action.count = model.Count(a);
    const Eigen::VectorXd theta = model.Theta(a);
    action.theta.assign(theta.data(), theta.data() + theta.size());
    const Eigen::VectorXd phi = model.Phi(a);
    action.phi.assign(phi.data(), phi.data() + phi.size());
    action.mean_loss =
        action.count > 0 ? model.LossSum(a) / static_cast<double>(action.count)
                         : 0.0;
    out.actions.push_back(std::move(action));
  }
  return out;
}

absl::StatusOr<EstimateResult> BanditEngine::Estimate(
    const std::string& user_id, absl::Span<const double> context) {
  ASSIGN_OR_RETURN(std::shared_ptr<UserSlot> slot, Slot(user_id, false));
  absl::MutexLock lock(&slot->mu);
  RETURN_IF_ERROR(Sync(user_id, *slot));
  const LearnerModel& model = *slot->model;
  RETURN_IF_ERROR(model.ValidateContext(context));
  RETURN_IF_ERROR(ValidateInputScale(model.config(), context, {}));
  EstimateResult result;
  result.estimates = model.Estimate(context);
  RETURN_IF_ERROR(FiniteFor(user_id, result.estimates));
  result.predicted_posthoc = model.PredictedPosthoc(context);
  result.action_names = model.config().action_names;
  result.model_version = model.TotalRounds();
  return result;
}

absl::StatusOr<PageResult<EventRecord>> BanditEngine::ListEvents(
    const std::string& user_id, const std::string& meal_id, const Page& page) {
  RETURN_IF_ERROR(ValidateUserId(user_id));
  return store_->ListEvents(user_id, meal_id, page);
}

size_t BanditEngine::CachedBytes() const {
  absl::MutexLock lock(&cache_mu_);
  return cached_bytes_;
}

BanditEngine::CacheCounters BanditEngine::Counters() const {
  absl::MutexLock lock(&cache_mu_);
  return counters_;
}

int BanditEngine::CachedModels() const {
  absl::MutexLock lock(&cache_mu_);
  return static_cast<int>(lru_.size());
}

}  // namespace bitewise::bandit
