// bitewise-replay: offline tuning of alpha, lambda_c and lambda_p on a
// user's logged history (docs/experiments.md, "Offline tuning"). Reads the
// BanditService's SQLite file (--db, --user) or a CSV export (--log_csv),
// replays every setting of the grid over bootstrap resamples of the log and
// reports each setting's estimated cumulative loss with a 95% interval,
// best first.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "absl/flags/flag.h"
#include "absl/flags/usage.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_format.h"
#include "experiments/event_log.h"
#include "experiments/replay.h"
#include "services/common/flags_usage.h"

ABSL_FLAG(std::string, db, "", "BanditService SQLite file to read.");
ABSL_FLAG(std::string, user, "", "User whose log --db holds.");
ABSL_FLAG(std::string, log_csv, "",
          "CSV export (event log or labelled dataset) instead of --db.");
ABSL_FLAG(int, num_actions, 6, "K of a CSV event log.");
ABSL_FLAG(std::string, export_csv, "",
          "Also write the loaded log in the CSV export format here.");
ABSL_FLAG(std::vector<std::string>, learners,
          std::vector<std::string>({"posthoc", "context_only"}),
          "Learners to try.");
ABSL_FLAG(std::vector<std::string>, alphas,
          std::vector<std::string>({"0", "0.01", "0.1", "1"}), "Alphas.");
ABSL_FLAG(std::vector<std::string>, lambda_cs,
          std::vector<std::string>({"1", "10", "100", "1000"}),
          "Context ridges.");
ABSL_FLAG(std::vector<std::string>, lambda_ps,
          std::vector<std::string>({"0.1", "1", "10"}),
          "Post hoc ridges (post hoc learner only).");
ABSL_FLAG(int, replays, 20, "Bootstrap replays per setting.");
ABSL_FLAG(std::string, dr_weight, "num_actions",
          "Doubly robust correction weight: num_actions (K, for uniformly "
          "collected logs) or propensity (1/logged propensity).");
ABSL_FLAG(uint64_t, seed, 1, "Seed of the bootstrap resamples.");
ABSL_FLAG(std::string, out, "", "CSV file for the per-setting results.");

namespace bitewise::experiments {
namespace {

int Fail(const absl::Status& status) {
  absl::FPrintF(stderr, "error: %s\n", status.ToString());
  return 1;
}

absl::StatusOr<std::vector<double>> Numbers(
    const std::vector<std::string>& texts, const char* flag) {
  std::vector<double> out;
  for (const std::string& t : texts) {
    double v;
    if (!absl::SimpleAtod(t, &v) || v < 0) {
      return absl::InvalidArgumentError(
          absl::StrFormat("--%s: bad value '%s'", flag, t));
    }
    out.push_back(v);
  }
  return out;
}

const char* Name(bandit::Learner learner) {
  return learner == bandit::Learner::kPostHoc ? "posthoc" : "context_only";
}

int Run() {
  const auto start = std::chrono::steady_clock::now();
  absl::StatusOr<EventLog> log;
  if (!absl::GetFlag(FLAGS_log_csv).empty()) {
    log = ReadEventLogCsv(absl::GetFlag(FLAGS_log_csv),
                          absl::GetFlag(FLAGS_num_actions));
  } else if (!absl::GetFlag(FLAGS_db).empty()) {
    log =
        ReadEventLogSqlite(absl::GetFlag(FLAGS_db), absl::GetFlag(FLAGS_user));
  } else {
    return Fail(absl::InvalidArgumentError("give --log_csv or --db/--user"));
  }
  if (!log.ok()) return Fail(log.status());
  if (!absl::GetFlag(FLAGS_export_csv).empty()) {
    std::ofstream(absl::GetFlag(FLAGS_export_csv)) << FormatEventLogCsv(*log);
  }
  const std::string dr = absl::GetFlag(FLAGS_dr_weight);
  if (dr != "num_actions" && dr != "propensity") {
    return Fail(absl::InvalidArgumentError("--dr_weight"));
  }
  auto imputed =
      ImputeLosses(*log, dr == "num_actions" ? DrWeight::kNumActions
                                             : DrWeight::kInversePropensity);
  if (!imputed.ok()) return Fail(imputed.status());
  auto alphas = Numbers(absl::GetFlag(FLAGS_alphas), "alphas");
  auto lambda_cs = Numbers(absl::GetFlag(FLAGS_lambda_cs), "lambda_cs");
  auto lambda_ps = Numbers(absl::GetFlag(FLAGS_lambda_ps), "lambda_ps");
  if (!alphas.ok()) return Fail(alphas.status());
  if (!lambda_cs.ok()) return Fail(lambda_cs.status());
  if (!lambda_ps.ok()) return Fail(lambda_ps.status());

  std::vector<ReplaySetting> grid;
  for (const std::string& name : absl::GetFlag(FLAGS_learners)) {
    bandit::Learner learner;
    if (name == "posthoc") {
      learner = bandit::Learner::kPostHoc;
    } else if (name == "context_only") {
      learner = bandit::Learner::kContextOnly;
    } else {
      return Fail(absl::InvalidArgumentError("--learners: " + name));
    }
    for (double a : *alphas) {
      for (double lc : *lambda_cs) {
        // lambda_p means nothing to the context-only learner: one entry,
        // reported as 1 (the value its config must hold).
        const std::vector<double> lps = learner == bandit::Learner::kPostHoc
                                            ? *lambda_ps
                                            : std::vector<double>{1.0};
        for (double lp : lps) {
          if (lc <= 0 || (learner == bandit::Learner::kPostHoc && lp <= 0)) {
            return Fail(absl::InvalidArgumentError("ridges must be positive"));
          }
          grid.push_back({learner, a, lc, lp});
        }
      }
    }
  }
  absl::FPrintF(stderr,
                "%zu %s rows, K=%d, d_c=%zu, d_p=%zu; %zu settings x %d "
                "replays\n",
                log->events.size(), log->labelled ? "labelled" : "event log",
                log->num_actions, log->events.front().context.size(),
                log->events.front().posthoc.size(), grid.size(),
                absl::GetFlag(FLAGS_replays));
  std::vector<ReplayEstimate> results;
  for (size_t s = 0; s < grid.size(); ++s) {
    auto est = ReplaySettingOnLog(*log, *imputed, grid[s],
                                  absl::GetFlag(FLAGS_replays),
                                  absl::GetFlag(FLAGS_seed));
    if (!est.ok()) return Fail(est.status());
    results.push_back(*est);
    absl::FPrintF(
        stderr, "setting %zu/%zu done (%.1f s)\n", s + 1, grid.size(),
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start)
            .count());
  }
  // Ranked by the doubly robust estimate: unbiased for a uniformly collected
  // log, where the direct method is biased wherever the per-food means are
  // off. (Both are equal on a labelled dataset.)
  std::stable_sort(results.begin(), results.end(),
                   [](const ReplayEstimate& a, const ReplayEstimate& b) {
                     return a.doubly_robust.mean < b.doubly_robust.mean;
                   });
  const std::string header =
      "learner,alpha,lambda_c,lambda_p,dm_mean,dm_lower,dm_upper,dr_mean,"
      "dr_lower,dr_upper";
  std::string csv = header + "\n";
  absl::PrintF(
      "estimated cumulative loss over %zu rounds (mean [95%% "
      "bootstrap interval]), best first:\n",
      log->events.size());
  absl::PrintF("%-12s %7s %8s %8s  %-26s %-26s\n", "learner", "alpha",
               "lambda_c", "lambda_p", "direct method", "doubly robust");
  for (const ReplayEstimate& r : results) {
    const ReplaySetting& s = r.setting;
    absl::PrintF(
        "%-12s %7g %8g %8g  %7.2f [%7.2f, %7.2f]  %7.2f [%7.2f, "
        "%7.2f]\n",
        Name(s.learner), s.alpha, s.lambda_c, s.lambda_p, r.direct.mean,
        r.direct.lower, r.direct.upper, r.doubly_robust.mean,
        r.doubly_robust.lower, r.doubly_robust.upper);
    csv += absl::StrFormat(
        "%s,%g,%g,%g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g\n", Name(s.learner), s.alpha,
        s.lambda_c, s.lambda_p, r.direct.mean, r.direct.lower, r.direct.upper,
        r.doubly_robust.mean, r.doubly_robust.lower, r.doubly_robust.upper);
  }
  if (!absl::GetFlag(FLAGS_out).empty()) {
    std::ofstream out(absl::GetFlag(FLAGS_out));
    out << csv;
    if (!out) return Fail(absl::InternalError("cannot write --out"));
  }
  return 0;
}

}  // namespace
}  // namespace bitewise::experiments

int main(int argc, char** argv) {
  absl::SetProgramUsageMessage(
      "Offline tuning of alpha and the ridges by replaying a logged history.");
  bitewise::ShowOwnFlagsInHelp();
  bitewise::ParseFlagsOnly(argc, argv);
  return bitewise::experiments::Run();
}
