// bitewise-bandit: the BanditService binary. Flags are parsed here and
// nowhere else; everything below main takes Options structs.
#include <csignal>
#include <cstdio>
#include <limits>
#include <memory>
#include <string>

#include "absl/flags/flag.h"
#include "absl/flags/usage.h"
#include "absl/strings/str_cat.h"
#include "services/bandit/bandit_service.h"
#include "services/bandit/core/learners.h"
#include "services/bandit/core/split_run.h"
#include "services/bandit/engine.h"
#include "services/bandit/store/open_store.h"
#include "services/common/flags_usage.h"
#include "services/common/metrics.h"
#include "services/common/readiness_monitor.h"
#include "services/common/rpc_environment.h"
#include "services/common/server.h"
#include "services/common/server_flags.h"

ABSL_FLAG(std::string, db, "bitewise-bandit.db",
          "Where users and event logs are kept: a SQLite file (PATH or "
          "sqlite:PATH) or a PostgreSQL database (postgresql://USER@HOST/DB, "
          "password in ~/.pgpass or PGPASSWORD).");
ABSL_FLAG(int, db_connections, 8,
          "PostgreSQL: connections kept open for the store's work (one "
          "call holds one for its transaction), plus one for the health "
          "check.");
ABSL_FLAG(double, db_response_timeout_s, 30,
          "PostgreSQL: seconds a statement waits for the server's next bytes "
          "before the call fails UNAVAILABLE, health turns NOT_SERVING and "
          "the connection is closed (a stopped or unreachable server). The "
          "health check waits at most 5 s.");
ABSL_FLAG(bool, sqlite_fsync, true,
          "fsync every commit (synchronous=FULL). false still survives a "
          "crash of the process, but not a power loss.");
ABSL_FLAG(int64_t, cache_budget_mb, 2048,
          "Memory budget for loaded user models; least recently used models "
          "beyond it are unloaded and rebuilt from the log on next use.");
ABSL_FLAG(bool, create, false,
          "Make a new store when --db does not exist or is an empty file. "
          "Without it such a --db stops the start (a mistyped path must not "
          "silently start everyone from scratch).");
ABSL_FLAG(int64_t, max_model_mb, 2048,
          "CreateUser refuses a configuration whose model could grow beyond "
          "this (all actions in primal form: about 16 d^2 bytes per action).");
ABSL_FLAG(int64_t, checkpoint_min_events, 50,
          "Save a loaded model as its checkpoint once it has this many new "
          "events and its user has been idle --checkpoint_idle_s; a cold "
          "load then replays only the events after it. 0: never.");
ABSL_FLAG(int64_t, checkpoint_max_events, 250,
          "Save it at this many new events even if its user is not idle.");
ABSL_FLAG(double, checkpoint_idle_s, 30,
          "Seconds without a call that count as idle (the end of a meal).");
ABSL_FLAG(std::string, default_learner, "posthoc",
          "Learner for new users: posthoc, context_only or polinucb.");
ABSL_FLAG(std::string, default_strategy, "linucb",
          "Strategy for new users: linucb, greedy, epsilon_greedy, thompson, "
          "uniform.");
ABSL_FLAG(double, default_alpha, 0.01, "Exploration weight for new users.");
ABSL_FLAG(double, default_lambda_c, 1000.0, "Context ridge for new users.");
ABSL_FLAG(double, default_lambda_p, 1.0, "Post hoc ridge for new users.");
ABSL_FLAG(double, default_epsilon, 0.1, "Epsilon for epsilon-greedy users.");
ABSL_FLAG(double, default_phi_radius,
          bitewise::bandit::BanditConfig().phi_radius,
          "poLinUCB's radius of the predicted post hoc context's ball for new "
          "users (docs/algorithms.md); stored with each user.");
ABSL_FLAG(int, default_context_dim, 2048,
          "Context dimension for new users (SPANet: 2048).");
ABSL_FLAG(int, default_posthoc_dim, 4,
          "Post hoc dimension for new users (HapticNet: 4).");
ABSL_FLAG(int, select_threads, 2,
          "Threads one Select may use: 2 splits a large model's per-action "
          "passes over two cores (at least 8 MB read; docs/benchmarks.md), 1 "
          "keeps every Select on its gRPC thread.");

namespace {

constexpr char kProgram[] = "bitewise-bandit";
constexpr int kDefaultPort = 50051;

absl::StatusOr<bitewise::bandit::BanditConfig> DefaultsFromFlags() {
  using bitewise::bandit::BanditConfig;
  using bitewise::bandit::Learner;
  using bitewise::bandit::Strategy;
  BanditConfig config;
  const std::string learner = absl::GetFlag(FLAGS_default_learner);
  const bitewise::bandit::LearnerSpec* spec =
      bitewise::bandit::FindLearnerByName(learner);
  if (spec == nullptr) {
    return absl::InvalidArgumentError(
        absl::StrCat("--default_learner: unknown learner \"", learner,
                     "\" (known: ", bitewise::bandit::LearnerNames(), ")"));
  }
  config.learner = spec->learner;
  const std::string strategy = absl::GetFlag(FLAGS_default_strategy);
  bool found = false;
  for (Strategy s :
       {Strategy::kLinUcb, Strategy::kGreedy, Strategy::kEpsilonGreedy,
        Strategy::kThompson, Strategy::kUniform}) {
    if (strategy == bitewise::bandit::StrategyName(s)) {
      config.strategy = s;
      found = true;
    }
  }
  if (!found) {
    return absl::InvalidArgumentError(absl::StrCat(
        "--default_strategy: unknown strategy \"", strategy, "\""));
  }
  config.alpha = absl::GetFlag(FLAGS_default_alpha);
  config.lambda_c = absl::GetFlag(FLAGS_default_lambda_c);
  config.lambda_p = absl::GetFlag(FLAGS_default_lambda_p);
  config.epsilon = absl::GetFlag(FLAGS_default_epsilon);
  config.phi_radius = absl::GetFlag(FLAGS_default_phi_radius);
  config.context_dim = absl::GetFlag(FLAGS_default_context_dim);
  config.posthoc_dim = absl::GetFlag(FLAGS_default_posthoc_dim);
  absl::Status status = bitewise::bandit::ValidateConfig(config);
  if (!status.ok()) return status;
  return config;
}

}  // namespace

int main(int argc, char** argv) {
  bitewise::BlockTerminationSignals();
  // A write past the file-size limit (ulimit -f) fails with EFBIG, which the
  // store reports like a full disk, instead of killing the process.
  std::signal(SIGXFSZ, SIG_IGN);
  absl::SetProgramUsageMessage(
      "BanditService: per-user post hoc contextual bandits over gRPC.");
  bitewise::ShowOwnFlagsInHelp();
  bitewise::ParseFlagsOnly(argc, argv);

  absl::StatusOr<bitewise::bandit::BanditConfig> defaults = DefaultsFromFlags();
  if (!defaults.ok()) {
    return bitewise::ReportFatal(kProgram, "bad flags", defaults.status());
  }
  const int select_threads = absl::GetFlag(FLAGS_select_threads);
  if (select_threads != 1 && select_threads != 2) {
    return bitewise::ReportFatal(
        kProgram, "bad flags",
        absl::InvalidArgumentError(absl::StrCat(
            "--select_threads must be 1 or 2, not ", select_threads)));
  }
  if (select_threads == 1) {
    bitewise::bandit::SetSplitMinCost(std::numeric_limits<double>::infinity());
  }

  // What every call runs with (metrics, authorizer, audit sink). Made
  // before the store, whose commit observer records into its metrics.
  bitewise::RpcEnvironment env;

  bitewise::bandit::OpenStoreOptions store_options;
  store_options.create_if_missing = absl::GetFlag(FLAGS_create);
  store_options.sqlite_fsync = absl::GetFlag(FLAGS_sqlite_fsync);
  store_options.postgres_connections = absl::GetFlag(FLAGS_db_connections);
  const double response_timeout_s = absl::GetFlag(FLAGS_db_response_timeout_s);
  if (!(response_timeout_s >= 0.1 && response_timeout_s <= 3600)) {
    return bitewise::ReportFatal(
        kProgram, "bad flags",
        absl::InvalidArgumentError(absl::StrCat(
            "--db_response_timeout_s must be between 0.1 and 3600, not ",
            response_timeout_s)));
  }
  store_options.postgres_response_timeout = absl::Seconds(response_timeout_s);
  // SERVING does not wait for SQLite's integrity check (it reads the whole
  // file); the first write does.
  store_options.defer_full_check = true;
  const std::string db = absl::GetFlag(FLAGS_db);
  auto store = bitewise::bandit::OpenEventStore(db, store_options);
  if (!store.ok()) {
    return bitewise::ReportFatal(kProgram, "cannot open the event store",
                                 store.status());
  }

  bitewise::bandit::EngineOptions engine_options;
  engine_options.cache_budget_bytes =
      static_cast<size_t>(absl::GetFlag(FLAGS_cache_budget_mb)) << 20;
  engine_options.max_model_bytes =
      static_cast<size_t>(absl::GetFlag(FLAGS_max_model_mb)) << 20;
  engine_options.checkpoint_min_events =
      absl::GetFlag(FLAGS_checkpoint_min_events);
  engine_options.checkpoint_max_events =
      absl::GetFlag(FLAGS_checkpoint_max_events);
  engine_options.checkpoint_idle =
      absl::Seconds(absl::GetFlag(FLAGS_checkpoint_idle_s));
  if (engine_options.checkpoint_min_events < 0 ||
      engine_options.checkpoint_max_events <
          engine_options.checkpoint_min_events ||
      !(absl::GetFlag(FLAGS_checkpoint_idle_s) >= 0)) {
    return bitewise::ReportFatal(
        kProgram, "bad flags",
        absl::InvalidArgumentError(
            "--checkpoint_min_events must be >= 0, --checkpoint_max_events "
            ">= it, --checkpoint_idle_s >= 0"));
  }
  // Commit latency and group size, as histograms (docs/operations.md).
  (*store)->SetCommitObserver([metrics = &env.metrics()](double seconds,
                                                         int64_t writes) {
    metrics->ObserveHistogram(
        "bitewise_bandit_store_commit_latency_seconds",
        "Time of each commit of the hot path's writes (its fsync included)",
        {0.0005, 0.001, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.25, 1}, seconds);
    metrics->ObserveHistogram(
        "bitewise_bandit_store_commit_writes",
        "Writes carried by each commit (SQLite's group commit; 1 on "
        "PostgreSQL, whose server shares WAL flushes itself)",
        {1, 2, 4, 8, 16, 32, 64}, static_cast<double>(writes));
  });
  bitewise::bandit::BanditEngine engine(store->get(), engine_options);
  bitewise::bandit::BanditServiceImpl service(&env, &engine, *defaults);
  // Metrics read at scrape time (docs/operations.md).
  {
    using bitewise::ScrapeType;
    using bitewise::ScrapeValue;
    bitewise::Metrics& metrics = env.metrics();
    bitewise::bandit::BanditEngine* e = &engine;
    metrics.AddScrapeValues(
        "bitewise_bandit_cached_models", "User models loaded in memory",
        ScrapeType::kGauge, [e]() -> std::vector<ScrapeValue> {
          return {{{}, static_cast<double>(e->CachedModels())}};
        });
    metrics.AddScrapeValues(
        "bitewise_bandit_cached_bytes", "Bytes of the loaded user models",
        ScrapeType::kGauge, [e]() -> std::vector<ScrapeValue> {
          return {{{}, static_cast<double>(e->CachedBytes())}};
        });
    metrics.AddScrapeValues(
        "bitewise_bandit_model_cache_total",
        "Model cache events: hit (already loaded), rebuild (loaded: from a "
        "checkpoint or the whole log), eviction (for the cache budget)",
        ScrapeType::kCounter, [e]() -> std::vector<ScrapeValue> {
          const auto c = e->Counters();
          return {{{{"event", "hit"}}, static_cast<double>(c.hits)},
                  {{{"event", "rebuild"}}, static_cast<double>(c.rebuilds)},
                  {{{"event", "eviction"}}, static_cast<double>(c.evictions)}};
        });
    metrics.AddScrapeValues(
        "bitewise_bandit_checkpoints_total",
        "Model checkpoints: written, loaded (a cold load started from one), "
        "ignored (damaged or stale; the log was replayed instead)",
        ScrapeType::kCounter, [e]() -> std::vector<ScrapeValue> {
          const auto c = e->Counters();
          return {
              {{{"event", "written"}},
               static_cast<double>(c.checkpoints_written)},
              {{{"event", "loaded"}}, static_cast<double>(c.checkpoint_loads)},
              {{{"event", "ignored"}},
               static_cast<double>(c.checkpoints_ignored)}};
        });
    metrics.AddScrapeValues(
        "bitewise_bandit_replica_sync_total",
        "PostgreSQL replicas: writes refused because another process had "
        "written to the user's log first (write_conflict, each retried), "
        "events another process completed that this one learned "
        "(caught_up_event), and cached models dropped because another "
        "process reset or recreated the user (dropped_stale)",
        ScrapeType::kCounter, [e]() -> std::vector<ScrapeValue> {
          const auto c = e->Counters();
          return {{{{"event", "write_conflict"}},
                   static_cast<double>(c.write_conflicts)},
                  {{{"event", "caught_up_event"}},
                   static_cast<double>(c.caught_up_events)},
                  {{{"event", "dropped_stale"}},
                   static_cast<double>(c.dropped_stale)}};
        });
    metrics.AddScrapeValues("bitewise_bandit_rebuild_seconds_total",
                            "Time spent rebuilding models from the event log",
                            ScrapeType::kCounter,
                            [e]() -> std::vector<ScrapeValue> {
                              return {{{}, e->Counters().rebuild_seconds}};
                            });
    metrics.AddScrapeValues(
        "bitewise_bandit_store_writes_total",
        "Durable writes of the hot path: append (Select) and complete "
        "(Update)",
        ScrapeType::kCounter, [s = store->get()]() -> std::vector<ScrapeValue> {
          const auto w = s->write_stats();
          return {{{{"op", "append"}}, static_cast<double>(w.appends)},
                  {{{"op", "complete"}}, static_cast<double>(w.completions)}};
        });
    metrics.AddScrapeValues(
        "bitewise_bandit_store_write_seconds_total",
        "Time until those writes were committed, waiting for their group "
        "and fsync included",
        ScrapeType::kCounter, [s = store->get()]() -> std::vector<ScrapeValue> {
          const auto w = s->write_stats();
          return {{{{"op", "append"}}, w.append_seconds},
                  {{{"op", "complete"}}, w.completion_seconds}};
        });
    metrics.AddScrapeValues(
        "bitewise_bandit_store_commits_total",
        "Group commits of those writes (one transaction and one fsync each)",
        ScrapeType::kCounter, [s = store->get()]() -> std::vector<ScrapeValue> {
          return {{{}, static_cast<double>(s->write_stats().commits)}};
        });
    metrics.AddScrapeValues(
        "bitewise_bandit_store_committed_writes_total",
        "Writes the group commits carried (over commits: the mean group "
        "size), refused ones included",
        ScrapeType::kCounter, [s = store->get()]() -> std::vector<ScrapeValue> {
          return {{{}, static_cast<double>(s->write_stats().committed_writes)}};
        });
    metrics.AddScrapeValues("bitewise_bandit_store_commit_seconds_total",
                            "Time the group commits took, fsync included",
                            ScrapeType::kCounter,
                            [s = store->get()]() -> std::vector<ScrapeValue> {
                              return {{{}, s->write_stats().commit_seconds}};
                            });
    metrics.AddScrapeValues(
        "bitewise_bandit_store_write_faults_total",
        "Writes the storage refused (a full disk or size limit, a read-only "
        "file, an I/O error, the database server gone or out of space), and "
        "writes refused while it did",
        ScrapeType::kCounter, [s = store->get()]() -> std::vector<ScrapeValue> {
          return {{{}, static_cast<double>(s->write_stats().write_faults)}};
        });
    metrics.AddScrapeValues("bitewise_bandit_store_healthy",
                            "1 while the store can durably accept writes",
                            ScrapeType::kGauge,
                            [s = store->get()]() -> std::vector<ScrapeValue> {
                              return {{{}, s->CheckHealth().ok() ? 1.0 : 0.0}};
                            });
  }
  // Administrative calls are kept in the store (ListAudit) as well as logged.
  bitewise::bandit::StoreAuditSink audit(store->get());
  env.set_audit_sink(&audit);

  auto server = bitewise::ServiceServer::Start(
      bitewise::ServerOptionsFromFlags(kDefaultPort), &env, {&service},
      {"bitewise.v1.BanditService"});
  if (!server.ok()) {
    return bitewise::ReportFatal(kProgram, "cannot start the server",
                                 server.status());
  }
  // Ready while the store can durably accept writes (SQLite: its file is
  // still the one opened; PostgreSQL: the server answers and is no standby).
  // Both run on the monitor's thread; each change is logged with its
  // reason, the first (SERVING at start) by the line below.
  bitewise::LoggedReadiness logged = bitewise::LogReadiness(
      kProgram, [s = store->get()] { return s->CheckHealth(); },
      [srv = server->get()](bool serving) { srv->SetServing(serving); },
      ": the store takes writes again");
  bitewise::ReadinessMonitor readiness(logged.live, logged.set_serving,
                                       /*period_s=*/0.5);
  // A write the storage refused turns health NOT_SERVING at once (the
  // monitor polls now, and logs it); its polls then probe and turn it
  // back once writes succeed.
  (*store)->SetFaultObserver(
      [&readiness](const absl::Status& fault) { readiness.Recheck(); });
  std::fprintf(stderr, "bitewise-bandit: serving on %s (db %s)\n",
               (*server)->description().c_str(),
               bitewise::bandit::DescribeStoreSpec(db).c_str());
  std::fflush(stderr);
  absl::Status status = bitewise::RunUntilSignal(**server);
  if (!status.ok()) return bitewise::ReportFatal(kProgram, "shutdown", status);
  // Drained: models with unsaved events are saved, so the next start reads
  // checkpoints instead of replaying (bounded: systemd's stop timeout).
  const absl::Time saving = absl::Now();
  const int saved = engine.CheckpointAll(absl::Seconds(15));
  std::fprintf(stderr,
               "bitewise-bandit: saved %d model checkpoint(s) in %s; "
               "stopped\n",
               saved,
               absl::FormatDuration(
                   absl::Trunc(absl::Now() - saving, absl::Milliseconds(1)))
                   .c_str());
  return 0;
}
