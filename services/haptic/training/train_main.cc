// bitewise-haptic-train: trains HapticNet on labelled force/torque traces
// (simulated by default, or a CSV file) and writes the ONNX model. Flags are
// parsed here and nowhere else. The shipped model is regenerated, bit for
// bit, by running this with its defaults (docs/haptic.md).
#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <iterator>
#include <map>
#include <memory>
#include <numeric>
#include <optional>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "absl/flags/flag.h"
#include "absl/flags/usage.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "absl/strings/str_split.h"
#include "services/common/flags_usage.h"
#include "services/haptic/core/haptic_classifier.h"
#include "services/haptic/core/haptic_net.h"
#include "services/haptic/model_loading.h"
#include "services/haptic/training/haptic_net_weights.h"
#include "services/haptic/training/haptic_trainer.h"
#include "services/haptic/training/labelled_traces.h"

ABSL_FLAG(std::string, out, "hapticnet.onnx", "Where to write the model.");
ABSL_FLAG(std::string, traces, "",
          "Recorded traces in the CSV format of docs/haptic.md (a meal's "
          "--record_traces directory holds them as traces.csv), trained on "
          "together with --stories. Traces labelled \"unknown\" are "
          "skipped and counted.");
ABSL_FLAG(std::string, labels, "",
          "A recording's bites.csv (or any CSV with the columns trace and "
          "label): its labels replace those of --traces, trace by trace.");
ABSL_FLAG(int, traces_repeat, 1,
          "Each recorded training trace counts this many times (so a few "
          "hundred recordings are not drowned by the stories).");
ABSL_FLAG(std::string, stories,
          "world,piecewise,mechanics,compliant,puncture,poroelastic",
          "Simulated trace stories to train on, comma-separated: world (the "
          "simulated world's force-trace model, augmented), piecewise, "
          "mechanics, compliant, puncture, poroelastic, lattice "
          "(services/sim/trace_stories.h); \"none\" to train on --traces "
          "alone. The default is the shipped model's six (since 2026-12-06; "
          "world and piecewise before); it holds lattice out for its "
          "evaluation.");
ABSL_FLAG(std::string, write_traces, "",
          "Also write the traces used (simulated or read) to this CSV file.");
ABSL_FLAG(bool, write_traces_only, false,
          "With --write_traces: write the traces and stop, without training "
          "(to make a recording-format file from a story, for example).");
ABSL_FLAG(bool, augment, false,
          "Augment every training and validation trace (of every story and "
          "recording) with TraceAugmentation's defaults (labelled_traces.h): "
          "clock and amplitude scale, fork angle and lever, sensor lag, "
          "a slower rate, drift and coloured noise.");
ABSL_FLAG(double, slow_approach, 1.0,
          "Stretch the clock of every training and validation trace (of "
          "every story and recording) by a factor drawn log-uniform in [1, "
          "this]: the fork meeting the food more slowly (a slower "
          "controller or a compliant wrist), so the force rises more slowly "
          "and less of it fits the window. 1 (the default) is off.");
ABSL_FLAG(double, compliant_arm, 0.0,
          "Share of training and validation traces (of every story and "
          "recording) felt through a compliant arm (ArmCompliance, "
          "labelled_traces.h: the wrist a spring of 1-20 N/mm in series "
          "with the food at 5 cm/s, so each force arrives F / (k v) later and "
          "stiff items rise slowly). 0 (the default) is off.");
ABSL_FLAG(std::string, ensemble_of, "",
          "Instead of training: assemble these HapticNet files (comma-"
          "separated, each written by this trainer) into one ensemble model "
          "(the mean of their probabilities, docs/haptic.md), score it on "
          "every story and write it to --out.");
ABSL_FLAG(int, traces_per_class, 3000,
          "Simulated traces per class and story (when --traces is empty).");
ABSL_FLAG(uint64_t, seed, 1,
          "Seed of the simulated traces, the split, the initial weights and "
          "the batch order.");
ABSL_FLAG(double, validation_fraction, 0.15,
          "Share of traces for early stopping and temperature calibration.");
ABSL_FLAG(double, test_fraction, 0.15,
          "Share of traces held out for the reported accuracy.");
ABSL_FLAG(int, batch_size, 64, "Windows per Adam step.");
ABSL_FLAG(double, learning_rate, 1e-3, "Adam step size.");
ABSL_FLAG(double, weight_decay, 1e-4, "L2 penalty on the weights.");
ABSL_FLAG(int, max_epochs, 60, "Most passes over the training set.");
ABSL_FLAG(double, label_smoothing, 0.04,
          "Share of each training target spread evenly over the 4 classes.");
ABSL_FLAG(double, min_temperature, 1.0,
          "Floor of the softmax temperature fitted on the validation split "
          "(1: the fit may soften the model, never sharpen it).");
ABSL_FLAG(int, held_out_per_class, 500,
          "Traces per class of each simulated story not trained on, scored "
          "after training (0: none).");
ABSL_FLAG(bool, familiarity, true,
          "Also fit the familiarity model (services/haptic/core/"
          "familiarity.h) on the training windows, calibrate it on the "
          "validation windows and write it to <out>.familiarity.");
ABSL_FLAG(bool, familiarity_only, false,
          "Fit, report and write the familiarity model, then stop without "
          "training the network (the leave-one-story-out study of the "
          "score).");
ABSL_FLAG(double, familiarity_threshold, 0.05,
          "Familiarity below which a trace is unfamiliar: the share of the "
          "validation windows flagged (0.05: 5% of familiar traces).");
ABSL_FLAG(std::string, familiarity_gaussians, "class_and_story",
          "The familiarity density: \"class\", one Gaussian per class over "
          "every training source; \"class_and_story\", one per class and "
          "source (each story, the recordings; docs/haptic.md, "
          "\"Familiarity\").");
ABSL_FLAG(double, familiarity_shrinkage, 0.1,
          "Shrinkage of each familiarity Gaussian's feature covariance "
          "towards its diagonal.");
ABSL_FLAG(double, window_s, 0.05,
          "HapticNet window after contact (s), recorded in the model as "
          "bitewise.window_s, which the service and the evaluator then use.");
ABSL_FLAG(std::string, conv_channels, "",
          "Output channels of a convolutional front end before the MLP, "
          "comma-separated (e.g. 16,32: two layers of kernel 5, each with "
          "ReLU and max-pooling by 2); empty: the plain MLP.");
ABSL_FLAG(int, patience, 8,
          "Stop after this many epochs without a better validation loss.");

namespace {

using namespace bitewise::haptic;  // NOLINT: a main over one namespace

int Die(const std::string& what) {
  std::fprintf(stderr, "bitewise-haptic-train: %s\n", what.c_str());
  return 1;
}

// Reads a whole file.
absl::StatusOr<std::string> ReadFile(const std::string& path) {
  std::FILE* file = std::fopen(path.c_str(), "rb");
  if (file == nullptr) {
    return absl::NotFoundError(absl::StrCat("cannot open ", path));
  }
  std::string bytes;
  char buffer[65536];
  size_t n;
  while ((n = std::fread(buffer, 1, sizeof buffer, file)) > 0) {
    bytes.append(buffer, n);
  }
  std::fclose(file);
  return bytes;
}

// Outputs are written beside their final name ("<path>.tmp"), flushed to
// disk and checked, and only then renamed over it: a failed write (a full
// disk), a failed check or a killed run leaves the model that was there,
// and its familiarity file, as they were.
std::string Staged(const std::string& path) { return path + ".tmp"; }

int StageFile(const std::string& path, const std::string& bytes) {
  const std::string staged = Staged(path);
  const int fd =
      open(staged.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  bool ok = fd >= 0;
  for (size_t done = 0; ok && done < bytes.size();) {
    const ssize_t n = write(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    ok = n > 0;
    if (ok) done += static_cast<size_t>(n);
  }
  const int error = ok ? 0 : errno;
  ok = ok && fsync(fd) == 0;
  if (fd >= 0 && close(fd) != 0) ok = false;
  if (!ok) {
    std::remove(staged.c_str());
    return Die(absl::StrCat("cannot write ", staged, ": ",
                            std::strerror(error != 0 ? error : errno),
                            "; nothing at ", path, " was changed"));
  }
  return 0;
}

// Renames the staged file over `path` and flushes the directory entry.
int CommitFile(const std::string& path) {
  if (std::rename(Staged(path).c_str(), path.c_str()) != 0) {
    return Die(absl::StrCat("cannot rename ", Staged(path), " to ", path, ": ",
                            std::strerror(errno)));
  }
  const std::string dir = std::filesystem::path(path).parent_path().string();
  const int fd = open(dir.empty() ? "." : dir.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd >= 0) {
    fsync(fd);
    close(fd);
  }
  return 0;
}

// Gives up on the staged model at `out`: removes it, says why.
int Abandon(const std::string& out, const absl::Status& why) {
  std::remove(Staged(out).c_str());
  return Die(why.ToString());
}

// Stages the model `bytes` for `out` and loads the staged file as the
// service will (nullptr after Die, the staged file removed, on failure).
std::unique_ptr<HapticNet> StageModel(const std::string& out,
                                      const std::string& bytes) {
  if (StageFile(out, bytes) != 0) return nullptr;
  absl::StatusOr<std::unique_ptr<HapticNet>> net =
      HapticNet::FromOnnxFile(Staged(out));
  if (!net.ok()) {
    Abandon(out, net.status());
    return nullptr;
  }
  return *std::move(net);
}

// What a run does with "<model>.familiarity" once its model is in place.
struct FamiliarityOutput {
  enum { kLeave, kWrite, kRemove } action = kLeave;
  std::string text;  // kWrite
};

// The staged model checked (OpenCV DNN on the file against the trainer's
// reference pass, `on` naming the windows; a difference over 1e-5 fails
// and removes it), then the familiarity file and the model put in place.
int CheckAndCommit(const std::string& out, size_t size, const HapticNet& net,
                   double max_difference, const char* on,
                   const FamiliarityOutput& familiarity) {
  std::printf(
      "\nwrote %s (%zu bytes, %s); OpenCV DNN vs reference%s: max |dp| = "
      "%.2e\n",
      out.c_str(), size, net.fingerprint().c_str(), on, max_difference);
  if (max_difference > 1e-5) {
    std::remove(Staged(out).c_str());
    return Die(absl::StrCat("the exported model disagrees with the trainer; ",
                            "nothing at ", out, " was changed"));
  }
  // The old model's familiarity file is set aside first, then the model
  // renamed, then the new file: a run killed between two steps leaves a
  // model without a familiarity file (served without the score, saying
  // so), never a model with another model's score. A failed step puts the
  // old file back.
  const std::string familiarity_path = FamiliarityPathFor(out);
  const std::string aside = familiarity_path + ".old";
  auto give_up = [&](int failed) {
    std::remove(Staged(out).c_str());
    std::remove(Staged(familiarity_path).c_str());
    return failed;
  };
  if (familiarity.action == FamiliarityOutput::kWrite) {
    if (int failed = StageFile(familiarity_path, familiarity.text);
        failed != 0) {
      return give_up(failed);
    }
  }
  std::error_code error;
  bool set_aside = false;
  if (familiarity.action != FamiliarityOutput::kLeave &&
      std::filesystem::exists(familiarity_path, error)) {
    std::filesystem::rename(familiarity_path, aside, error);
    if (error) {
      return give_up(Die(absl::StrCat("cannot move ", familiarity_path,
                                      " aside: ", error.message(),
                                      "; nothing at ", out, " was changed")));
    }
    set_aside = true;
  }
  if (int failed = CommitFile(out); failed != 0) {
    if (set_aside) std::filesystem::rename(aside, familiarity_path, error);
    return give_up(failed);
  }
  if (familiarity.action == FamiliarityOutput::kWrite) {
    if (int failed = CommitFile(familiarity_path); failed != 0) {
      std::remove(Staged(familiarity_path).c_str());
      return failed;  // the model is in place, without a score
    }
    std::printf("wrote %s (%zu bytes)\n", familiarity_path.c_str(),
                familiarity.text.size());
  } else if (set_aside) {
    std::printf("removed %s (it belonged to the model replaced)\n",
                familiarity_path.c_str());
  }
  if (set_aside) std::filesystem::remove(aside, error);
  return 0;
}

// --ensemble_of: the members' weights, one ensemble file, its score on
// fresh items of every story (reference pass), and OpenCV's agreement.
int AssembleEnsemble() {
  const uint64_t seed = absl::GetFlag(FLAGS_seed);
  std::vector<HapticNetWeights> members;
  std::vector<std::string> names;
  for (absl::string_view path : absl::StrSplit(absl::GetFlag(FLAGS_ensemble_of),
                                               ',', absl::SkipEmpty())) {
    absl::StatusOr<std::string> bytes = ReadFile(std::string(path));
    if (!bytes.ok()) return Die(bytes.status().ToString());
    absl::StatusOr<std::unique_ptr<HapticNet>> net =
        HapticNet::FromOnnxBytes(*bytes, std::string(path));
    if (!net.ok()) return Die(net.status().ToString());
    // The window the service would run this member on by default.
    absl::StatusOr<double> member_window_s =
        ModelWindow(**net, 0.0, std::string(path));
    if (!member_window_s.ok()) return Die(member_window_s.status().ToString());
    if (std::abs(*member_window_s - absl::GetFlag(FLAGS_window_s)) > 1e-9) {
      return Die(absl::StrCat(
          path, " was trained on a ", *member_window_s,
          " s window, but --window_s=", absl::GetFlag(FLAGS_window_s),
          ": an ensemble's members share one window"));
    }
    absl::StatusOr<HapticNetWeights> weights =
        HapticNetWeightsFromOnnx(*bytes, std::string(path));
    if (!weights.ok()) return Die(weights.status().ToString());
    members.push_back(*weights);
    names.push_back(absl::StrCat(path, " (", (*net)->fingerprint(), ")"));
  }
  if (members.size() < 2) return Die("--ensemble_of needs two or more models");
  const std::map<std::string, std::string> metadata = {
      {"bitewise.classes", "hard,medium,soft,hard_skin"},
      {"bitewise.ensemble", absl::StrJoin(names, "; ")},
      {kHapticNetWindowKey, absl::StrCat(absl::GetFlag(FLAGS_window_s))},
  };
  const std::string bytes = HapticEnsembleToOnnx(members, metadata);
  const std::string out = absl::GetFlag(FLAGS_out);
  const std::unique_ptr<HapticNet> net = StageModel(out, bytes);
  if (net == nullptr) return 1;
  std::printf("ensemble of %zu members:\n  %s\n", members.size(),
              absl::StrJoin(names, "\n  ").c_str());
  HapticPipelineOptions pipeline;
  pipeline.window.window_s = absl::GetFlag(FLAGS_window_s);
  double max_difference = 0.0;
  for (int i = 0; i < kTraceStories; ++i) {
    const auto story = static_cast<TraceStory>(i);
    const int per_class = absl::GetFlag(FLAGS_held_out_per_class);
    if (per_class <= 0) break;
    int skipped = 0;
    const LabelledWindows windows = WindowsFromTraces(
        StoryTraces(story, per_class, seed + 1000), pipeline, &skipped);
    std::vector<std::array<double, kHapticClasses>> probabilities;
    for (size_t w = 0; w < windows.inputs.size(); ++w) {
      probabilities.push_back(
          ReferenceEnsembleProbabilities(members, windows.inputs[w]));
      absl::StatusOr<HapticNetOutput> output = net->Run(windows.inputs[w]);
      if (!output.ok()) return Abandon(out, output.status());
      for (int k = 0; k < kHapticClasses; ++k) {
        max_difference = std::max(
            max_difference,
            std::abs(output->probabilities[k] - probabilities.back()[k]));
      }
    }
    const ProbabilisticScore score =
        ScorePredictions(probabilities, windows.labels);
    std::printf(
        "\nstory %s (fresh items: %d per class, seed %lu, %d without "
        "contact): accuracy %.2f%%, calibration error %.4f, over-confidence "
        "%+.3f/%+.3f/%+.3f/%+.3f\n%s",
        TraceStoryName(story), per_class,
        static_cast<unsigned long>(seed + 1000), skipped,
        100.0 * score.confusion.Accuracy(), score.expected_calibration_error,
        score.overconfidence[0], score.overconfidence[1],
        score.overconfidence[2], score.overconfidence[3],
        score.confusion.ToString().c_str());
  }
  // An ensemble has no familiarity score of its own (fit one for it with
  // --familiarity_only): an earlier model's at this path goes.
  FamiliarityOutput no_score;
  no_score.action = FamiliarityOutput::kRemove;
  return CheckAndCommit(out, bytes.size(), *net, max_difference, "", no_score);
}

std::vector<FamiliarityVector> FamiliarityOf(const LabelledWindows& windows) {
  std::vector<FamiliarityVector> features;
  features.reserve(windows.inputs.size());
  for (const auto& window : windows.inputs) {
    features.push_back(FamiliarityFeatures(window));
  }
  return features;
}

// One line of the familiarity report: flagged share, quantiles of the
// familiarity and, against `familiar` distances, the AUROC.
std::string FamiliarityLine(const FamiliarityModel& model,
                            const LabelledWindows& windows,
                            const std::vector<double>* familiar_distances,
                            std::vector<double>* distances_out) {
  std::vector<double> distances, familiarity;
  std::array<int, kHapticClasses> flagged_by_class{}, count_by_class{};
  int flagged = 0;
  for (size_t i = 0; i < windows.inputs.size(); ++i) {
    const FamiliarityScore score =
        model.Score(FamiliarityFeatures(windows.inputs[i]));
    distances.push_back(score.distance);
    familiarity.push_back(score.familiarity);
    flagged += score.unfamiliar;
    ++count_by_class[windows.labels[i]];
    flagged_by_class[windows.labels[i]] += score.unfamiliar;
  }
  std::sort(familiarity.begin(), familiarity.end());
  auto quantile = [&](double q) {
    return familiarity.empty()
               ? 0.0
               : familiarity[static_cast<size_t>(
                     q * static_cast<double>(familiarity.size() - 1))];
  };
  std::string line = absl::StrFormat(
      "%zu windows, flagged unfamiliar %.1f%% (hard %.1f, medium %.1f, soft "
      "%.1f, hard-skin %.1f); familiarity quantiles 10/25/50/75/90%%: "
      "%.3f %.3f %.3f %.3f %.3f",
      distances.size(), 100.0 * flagged / std::max<size_t>(1, distances.size()),
      100.0 * flagged_by_class[0] / std::max(1, count_by_class[0]),
      100.0 * flagged_by_class[1] / std::max(1, count_by_class[1]),
      100.0 * flagged_by_class[2] / std::max(1, count_by_class[2]),
      100.0 * flagged_by_class[3] / std::max(1, count_by_class[3]),
      quantile(0.1), quantile(0.25), quantile(0.5), quantile(0.75),
      quantile(0.9));
  if (familiar_distances != nullptr) {
    absl::StrAppendFormat(&line, "; AUROC against the test split %.3f",
                          Auroc(distances, *familiar_distances));
  }
  if (distances_out != nullptr) *distances_out = std::move(distances);
  return line;
}

// Fits the familiarity model on `train`, calibrates it on `validation`,
// reports it on `test` and on every story in `held_out` (fresh items, seed
// `held_out_seed`) and writes it to `path`. Nonzero on failure.
int FitFamiliarity(const LabelledWindows& train,
                   const LabelledWindows& validation,
                   const LabelledWindows& test,
                   const std::vector<TraceStory>& held_out,
                   uint64_t held_out_seed,
                   const HapticPipelineOptions& pipeline,
                   const std::string& trained_on, const std::string& path,
                   FamiliarityOutput* output) {
  const std::vector<FamiliarityVector> train_features = FamiliarityOf(train);
  const std::vector<FamiliarityVector> validation_features =
      FamiliarityOf(validation);
  const std::string gaussians = absl::GetFlag(FLAGS_familiarity_gaussians);
  absl::StatusOr<FamiliarityModel> model;
  if (gaussians == "class") {
    model = FamiliarityModel::Fit(
        train_features, train.labels, validation_features,
        absl::GetFlag(FLAGS_familiarity_threshold),
        absl::GetFlag(FLAGS_familiarity_shrinkage), trained_on);
  } else {  // "class_and_story", checked at the start
    std::vector<std::string> sources;
    sources.reserve(train.sources.size());
    for (int source : train.sources) {
      sources.push_back(
          source >= 0 && source < kTraceStories
              ? std::string(TraceStoryName(static_cast<TraceStory>(source)))
              : std::string("recordings"));
    }
    model = FamiliarityModel::FitPerSource(
        train_features, train.labels, sources, validation_features,
        absl::GetFlag(FLAGS_familiarity_threshold),
        absl::GetFlag(FLAGS_familiarity_shrinkage), trained_on);
  }
  if (!model.ok()) {
    if (absl::GetFlag(FLAGS_familiarity_only)) {
      return Die(model.status().ToString());
    }
    // Too few windows to fit a score is no reason not to train the network:
    // the model is served without one (the service says so at start-up).
    // A file left from an earlier run at this path would not belong to it:
    // it is removed when the new model is put in place.
    output->action = FamiliarityOutput::kRemove;
    std::printf(
        "\nfamiliarity: not fitted (%s); no %s is written, so the service "
        "will serve this model without a familiarity score\n",
        std::string(model.status().message()).c_str(), path.c_str());
    std::fflush(stdout);
    return 0;
  }
  std::printf(
      "\nfamiliarity (%zu Gaussians, %s, on %d trace summaries, fitted on "
      "%zu training windows%s, threshold %.3f = the share of the %zu "
      "validation windows flagged)\n",
      model->components().size(),
      gaussians == "class" ? "one per class" : "one per class and source",
      kFamiliarityFeatures, train_features.size(),
      model->left_out() > 0
          ? absl::StrCat(" (", model->left_out(),
                         " left out: too few of their class and source)")
                .c_str()
          : "",
      model->threshold(), validation_features.size());
  std::vector<double> test_distances;
  std::printf("  test split (familiar): %s\n",
              FamiliarityLine(*model, test, nullptr, &test_distances).c_str());
  const int per_class = absl::GetFlag(FLAGS_held_out_per_class);
  for (TraceStory story : held_out) {
    if (per_class <= 0) break;
    int skipped = 0;
    const LabelledWindows windows = WindowsFromTraces(
        StoryTraces(story, per_class, held_out_seed), pipeline, &skipped);
    std::printf(
        "  held-out story %s (seed %lu): %s\n", TraceStoryName(story),
        static_cast<unsigned long>(held_out_seed),
        FamiliarityLine(*model, windows, &test_distances, nullptr).c_str());
  }
  // Written with the model, once it is trained and checked.
  output->action = FamiliarityOutput::kWrite;
  output->text = model->ToText();
  std::fflush(stdout);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  absl::SetProgramUsageMessage(
      "Trains HapticNet and writes it as ONNX. With no flags: 3000 simulated "
      "traces per class from each story of --stories (world, piecewise, "
      "mechanics, compliant, puncture, poroelastic), seed 1, model to "
      "./hapticnet.onnx.");
  bitewise::ShowOwnFlagsInHelp();
  bitewise::ParseFlagsOnly(argc, argv);
  if (!absl::GetFlag(FLAGS_ensemble_of).empty()) return AssembleEnsemble();
  const uint64_t seed = absl::GetFlag(FLAGS_seed);
  if (absl::GetFlag(FLAGS_traces_repeat) < 1) {
    return Die(absl::StrCat("--traces_repeat must be at least 1; got ",
                            absl::GetFlag(FLAGS_traces_repeat)));
  }
  // Checked before any trace is drawn.
  if (const std::string g = absl::GetFlag(FLAGS_familiarity_gaussians);
      g != "class" && g != "class_and_story") {
    return Die(absl::StrCat(
        "--familiarity_gaussians must be class or class_and_story; got \"", g,
        "\""));
  }
  std::vector<int> conv_channels;
  for (absl::string_view part : absl::StrSplit(
           absl::GetFlag(FLAGS_conv_channels), ',', absl::SkipEmpty())) {
    int channels = 0;
    if (!absl::SimpleAtoi(part, &channels)) {
      return Die(absl::StrCat("--conv_channels: \"", part,
                              "\" is not a number of channels"));
    }
    conv_channels.push_back(channels);
  }
  if (absl::Status s = WeightsWithFrontEnd(conv_channels).status(); !s.ok()) {
    return Die(absl::StrCat("--conv_channels: ", s.message()));
  }

  std::vector<LabelledTrace> traces;
  std::vector<int> story_of;  // per simulated trace: its story
  std::string source;
  std::vector<TraceStory> held_out;  // stories not trained on
  std::vector<TraceStory> stories;
  if (absl::GetFlag(FLAGS_stories) != "none") {
    absl::StatusOr<std::vector<TraceStory>> parsed =
        ParseTraceStories(absl::GetFlag(FLAGS_stories));
    if (!parsed.ok()) return Die(parsed.status().ToString());
    stories = std::move(parsed).value();
  }
  if (stories.empty() && absl::GetFlag(FLAGS_traces).empty()) {
    return Die("--stories=none needs --traces");
  }
  std::vector<std::string> names;
  for (TraceStory story : stories) {
    std::vector<LabelledTrace> drawn =
        StoryTraces(story, absl::GetFlag(FLAGS_traces_per_class), seed);
    story_of.insert(story_of.end(), drawn.size(), static_cast<int>(story));
    std::move(drawn.begin(), drawn.end(), std::back_inserter(traces));
    names.push_back(TraceStoryName(story));
  }
  for (int i = 0; i < kTraceStories; ++i) {
    const auto story = static_cast<TraceStory>(i);
    if (std::find(stories.begin(), stories.end(), story) == stories.end()) {
      held_out.push_back(story);
    }
  }
  if (!stories.empty()) {
    source = absl::StrCat("simulated stories ", absl::StrJoin(names, "+"), " (",
                          absl::GetFlag(FLAGS_traces_per_class),
                          " per class and story, seed ", seed,
                          "; world augmented: amplitude, time scale, noise, "
                          "bias, rate, lateral, touch)");
  }
  // Recorded traces: their own split, so that their held-out part is
  // reported on its own.
  std::vector<LabelledTrace> recorded;
  if (!absl::GetFlag(FLAGS_traces).empty()) {
    absl::StatusOr<std::vector<RecordedTrace>> read =
        ReadRecordedTraces(absl::GetFlag(FLAGS_traces));
    if (!read.ok()) return Die(read.status().ToString());
    if (!absl::GetFlag(FLAGS_labels).empty()) {
      absl::StatusOr<std::map<std::string, std::optional<HapticClass>>> labels =
          ReadTraceLabels(absl::GetFlag(FLAGS_labels));
      if (!labels.ok()) return Die(labels.status().ToString());
      int without_row = 0;
      std::set<std::string> matched;
      for (RecordedTrace& trace : *read) {
        const auto it = labels->find(trace.id);
        if (it != labels->end()) {
          trace.label = it->second;
          matched.insert(trace.id);
        } else {
          ++without_row;
        }
      }
      std::printf(
          "--labels %s: %zu of its %zu rows match a trace; %d traces have "
          "no row there and keep their own label\n",
          absl::GetFlag(FLAGS_labels).c_str(), matched.size(), labels->size(),
          without_row);
    }
    // A recorded trace is trained on only if the HapticService would
    // classify it as it stands: its checks (finite values, time order, a
    // rate of 90 Hz-7.7 kHz) and its contact rules, the free stretch
    // before contact that the sensor's offset is taken from included.
    HapticPipelineOptions service_rules;
    service_rules.window.window_s = absl::GetFlag(FLAGS_window_s);
    service_rules.contact.require_free_tare = true;
    int unlabelled = 0, refused = 0;
    std::string first_refusal;
    for (RecordedTrace& trace : *read) {
      if (!trace.label.has_value()) {
        ++unlabelled;
        continue;
      }
      if (absl::StatusOr<HapticFeatures> usable =
              ExtractHapticFeatures(trace.samples, service_rules);
          !usable.ok()) {
        if (refused++ == 0) {
          first_refusal =
              absl::StrCat("trace ", trace.id, ": ", usable.status().message());
        }
        continue;
      }
      recorded.push_back(
          {*trace.label, std::move(trace.samples), kRecordedSource});
    }
    std::printf(
        "recorded traces: %zu labelled, %d unknown (skipped) in %s; %d of "
        "the labelled the HapticService would refuse (skipped%s%s)\n",
        recorded.size() + refused, unlabelled,
        absl::GetFlag(FLAGS_traces).c_str(), refused,
        refused > 0 ? "; the first, " : "", first_refusal.c_str());
    if (recorded.empty()) return Die("no labelled recorded traces to train on");
    absl::StrAppend(&source, source.empty() ? "" : " + ", "recorded ",
                    absl::GetFlag(FLAGS_traces), " (", recorded.size(),
                    " labelled traces, each x",
                    absl::GetFlag(FLAGS_traces_repeat), ")");
  }
  if (!absl::GetFlag(FLAGS_write_traces).empty()) {
    std::vector<LabelledTrace> all = traces;
    all.insert(all.end(), recorded.begin(), recorded.end());
    absl::Status written =
        WriteTraceCsv(absl::GetFlag(FLAGS_write_traces), all);
    if (!written.ok()) return Die(written.ToString());
    if (absl::GetFlag(FLAGS_write_traces_only)) {
      std::printf("wrote %zu traces to %s\n", all.size(),
                  absl::GetFlag(FLAGS_write_traces).c_str());
      return 0;
    }
  }

  // Split by trace, so no food item is in two sets.
  const double validation_fraction = absl::GetFlag(FLAGS_validation_fraction);
  const double test_fraction = absl::GetFlag(FLAGS_test_fraction);
  if (!(validation_fraction > 0.0) || !(test_fraction > 0.0) ||
      !(validation_fraction + test_fraction < 1.0)) {
    return Die(
        "--validation_fraction and --test_fraction must be > 0 with a sum "
        "below 1");
  }
  if (const double slow = absl::GetFlag(FLAGS_slow_approach);
      !(slow >= 1.0 && slow <= 10.0)) {
    return Die(absl::StrCat("--slow_approach must be in [1, 10]; got ", slow));
  }
  if (const double share = absl::GetFlag(FLAGS_compliant_arm);
      !(share >= 0.0 && share <= 1.0)) {
    return Die(absl::StrCat("--compliant_arm must be in [0, 1]; got ", share));
  }
  if (const double window = absl::GetFlag(FLAGS_window_s);
      !(window > 0.0 && window <= 1.0)) {
    // The range HapticNet accepts in a model's bitewise.window_s.
    return Die(absl::StrCat("--window_s must be in (0, 1] s; got ", window));
  }
  // Shuffles `set` into test, validation and train parts (in that order of
  // the shuffled list), tagging each trace with `tags[i]` when given.
  std::vector<LabelledTrace> test, validation, train;
  std::vector<int> test_tag;  // story of each test trace, -1 recorded
  std::vector<LabelledTrace> recorded_test;
  auto split = [&](std::vector<LabelledTrace>& set,
                   const std::vector<int>* tags, uint64_t split_seed,
                   std::vector<LabelledTrace>* test_part, int repeat) {
    std::vector<int> order(set.size());
    std::iota(order.begin(), order.end(), 0);
    std::mt19937_64 split_rng(split_seed);
    for (int i = static_cast<int>(order.size()) - 1; i > 0; --i) {
      std::swap(order[i], order[split_rng() % static_cast<uint64_t>(i + 1)]);
    }
    const size_t test_count =
        static_cast<size_t>(std::round(test_fraction * set.size()));
    const size_t validation_count =
        static_cast<size_t>(std::round(validation_fraction * set.size()));
    for (size_t i = 0; i < order.size(); ++i) {
      if (i < test_count) {
        if (tags != nullptr) test_tag.push_back((*tags)[order[i]]);
        test_part->push_back(std::move(set[order[i]]));
      } else if (i < test_count + validation_count) {
        validation.push_back(std::move(set[order[i]]));
      } else {
        for (int r = 1; r < repeat; ++r) train.push_back(set[order[i]]);
        train.push_back(std::move(set[order[i]]));
      }
    }
  };
  split(traces, &story_of, seed ^ 0x5eed5eed5eed5eedull, &test, 1);
  split(recorded, nullptr, seed ^ 0x7ecd7ecd7ecd7ecdull, &recorded_test,
        std::max(1, absl::GetFlag(FLAGS_traces_repeat)));
  // Each training and validation trace, changed by `change` with a random
  // stream of its own; the test split is never changed.
  auto change_training_traces = [&](uint64_t stream, const auto& change) {
    std::mt19937_64 rng(seed ^ stream);
    for (auto* set : {&train, &validation}) {
      for (LabelledTrace& trace : *set) {
        trace.samples = change(trace.samples, rng);
      }
    }
  };
  if (absl::GetFlag(FLAGS_augment)) {
    const TraceAugmentation augmentation;
    change_training_traces(0xa095e47a095e47aull,
                           [&](const auto& samples, std::mt19937_64& rng) {
                             return AugmentTrace(samples, augmentation, rng);
                           });
    absl::StrAppend(&source, "; augmented (--augment)");
  }
  if (const double slow = absl::GetFlag(FLAGS_slow_approach); slow != 1.0) {
    change_training_traces(0x510a510a510a510aull,
                           [&](const auto& samples, std::mt19937_64& rng) {
                             return SlowApproach(samples, slow, rng);
                           });
    absl::StrAppend(&source, "; slow approach up to x", slow,
                    " (--slow_approach)");
  }
  if (const double share = absl::GetFlag(FLAGS_compliant_arm); share > 0.0) {
    ArmCompliance arm;
    arm.probability = share;
    change_training_traces(0xa4a4c0a1a4a4c0a1ull,
                           [&](const auto& samples, std::mt19937_64& rng) {
                             return CompliantArm(samples, arm, rng);
                           });
    absl::StrAppend(&source, "; ", share,
                    " of them through a compliant arm (--compliant_arm)");
  }
  if (test.empty()) {  // trained on recordings alone
    test = std::move(recorded_test);
    recorded_test.clear();
  }

  HapticPipelineOptions pipeline;
  pipeline.window.window_s = absl::GetFlag(FLAGS_window_s);
  int skipped_train = 0, skipped_validation = 0, skipped_test = 0;
  const LabelledWindows train_windows =
      WindowsFromTraces(train, pipeline, &skipped_train);
  const LabelledWindows validation_windows =
      WindowsFromTraces(validation, pipeline, &skipped_validation);
  const LabelledWindows test_windows =
      WindowsFromTraces(test, pipeline, &skipped_test);
  std::printf(
      "traces: %s\nwindows: train %zu, validation %zu, test %zu (no contact "
      "or too short, skipped: %d, %d, %d)\n",
      source.c_str(), train_windows.inputs.size(),
      validation_windows.inputs.size(), test_windows.inputs.size(),
      skipped_train, skipped_validation, skipped_test);
  // Without a score of its own, the new model must not be served with the
  // old one's (--familiarity=false, or too few windows to fit one).
  FamiliarityOutput familiarity;
  familiarity.action = FamiliarityOutput::kRemove;
  if (absl::GetFlag(FLAGS_familiarity) ||
      absl::GetFlag(FLAGS_familiarity_only)) {
    const std::string path = FamiliarityPathFor(absl::GetFlag(FLAGS_out));
    // A score for the model already at --out is fitted on that model's
    // windows: the service computes it on them.
    if (absl::GetFlag(FLAGS_familiarity_only) &&
        std::filesystem::exists(absl::GetFlag(FLAGS_out))) {
      absl::StatusOr<std::unique_ptr<HapticNet>> net =
          HapticNet::FromOnnxFile(absl::GetFlag(FLAGS_out));
      if (!net.ok()) return Die(net.status().ToString());
      const std::optional<double> declared = (*net)->window_s();
      const double window_s = absl::GetFlag(FLAGS_window_s);
      if (std::abs(declared.value_or(WindowOptions().window_s) - window_s) >
          1e-9) {
        return Die(absl::StrCat(
            absl::GetFlag(FLAGS_out), " was trained on a ",
            declared.value_or(WindowOptions().window_s),
            " s window, but --window_s=", window_s,
            ": its familiarity score must be fitted on the windows the "
            "service computes it on; give --window_s=",
            declared.value_or(WindowOptions().window_s)));
      }
    }
    if (int failed =
            FitFamiliarity(train_windows, validation_windows, test_windows,
                           held_out, seed + 1000, pipeline,
                           names.empty() ? std::string("recordings")
                                         : absl::StrJoin(names, ","),
                           path, &familiarity);
        failed != 0) {
      return failed;
    }
    if (absl::GetFlag(FLAGS_familiarity_only)) {
      // For the model already at --out: written now.
      if (int failed = StageFile(path, familiarity.text); failed != 0) {
        return failed;
      }
      if (int failed = CommitFile(path); failed != 0) return failed;
      std::printf("wrote %s (%zu bytes)\n", path.c_str(),
                  familiarity.text.size());
      return 0;
    }
  }

  TrainerOptions options;
  options.seed = seed;
  options.batch_size = absl::GetFlag(FLAGS_batch_size);
  options.learning_rate = absl::GetFlag(FLAGS_learning_rate);
  options.weight_decay = absl::GetFlag(FLAGS_weight_decay);
  options.max_epochs = absl::GetFlag(FLAGS_max_epochs);
  options.patience = absl::GetFlag(FLAGS_patience);
  options.label_smoothing = absl::GetFlag(FLAGS_label_smoothing);
  options.min_temperature = absl::GetFlag(FLAGS_min_temperature);
  options.conv_channels = conv_channels;
  absl::StatusOr<TrainingResult> result = TrainHapticNet(
      train_windows, validation_windows, options, [](const EpochLog& log) {
        std::printf(
            "epoch %3d  train loss %.4f  validation loss %.4f  accuracy "
            "%.2f%%\n",
            log.epoch, log.train_loss, log.validation_loss,
            100.0 * log.validation_accuracy);
        std::fflush(stdout);
      });
  if (!result.ok()) return Die(result.status().ToString());
  std::printf("best epoch %d, softmax temperature %.2f (folded into fc3)\n",
              result->best_epoch, result->temperature);

  // The trainer's reference pass over `windows`, scored.
  auto score_windows =
      [&](const LabelledWindows& windows,
          std::vector<std::array<double, kHapticClasses>>* probabilities) {
        for (const auto& window : windows.inputs) {
          probabilities->push_back(
              ReferenceProbabilities(result->weights, window));
        }
        return ScorePredictions(*probabilities, windows.labels);
      };
  std::vector<std::array<double, kHapticClasses>> reference;
  const ProbabilisticScore score = score_windows(test_windows, &reference);
  std::printf(
      "\nheld-out test set (trainer's reference pass): accuracy %.2f%%, log "
      "loss %.4f, calibration error %.4f\n%s",
      100.0 * score.confusion.Accuracy(), score.mean_log_loss,
      score.expected_calibration_error, score.confusion.ToString().c_str());

  // Each source's part of the held-out test split, when there are several.
  std::string recorded_summary;
  if (stories.size() > 1 || (!stories.empty() && !recorded_test.empty())) {
    for (TraceStory story : stories) {
      std::vector<LabelledTrace> part;
      for (size_t i = 0; i < test.size(); ++i) {
        if (test_tag[i] == static_cast<int>(story)) part.push_back(test[i]);
      }
      std::vector<std::array<double, kHapticClasses>> probabilities;
      const ProbabilisticScore part_score = score_windows(
          WindowsFromTraces(part, pipeline, nullptr), &probabilities);
      std::printf(
          "  story %s (trained on): accuracy %.2f%%, calibration "
          "error %.4f, per class %s\n",
          TraceStoryName(story), 100.0 * part_score.confusion.Accuracy(),
          part_score.expected_calibration_error,
          absl::StrJoin(
              {absl::StrFormat("%.1f", 100 * part_score.confusion.Recall(0)),
               absl::StrFormat("%.1f", 100 * part_score.confusion.Recall(1)),
               absl::StrFormat("%.1f", 100 * part_score.confusion.Recall(2)),
               absl::StrFormat("%.1f", 100 * part_score.confusion.Recall(3))},
              "/")
              .c_str());
    }
  }
  if (!recorded_test.empty()) {
    int skipped = 0;
    const LabelledWindows windows =
        WindowsFromTraces(recorded_test, pipeline, &skipped);
    std::vector<std::array<double, kHapticClasses>> probabilities;
    const ProbabilisticScore held = score_windows(windows, &probabilities);
    std::printf(
        "\nheld-out recorded traces (%zu never trained on, %d without "
        "contact): accuracy %.2f%%, log loss %.4f, calibration error "
        "%.4f\n%s",
        recorded_test.size(), skipped, 100.0 * held.confusion.Accuracy(),
        held.mean_log_loss, held.expected_calibration_error,
        held.confusion.ToString().c_str());
    recorded_summary = absl::StrFormat("%.4f", held.confusion.Accuracy());
  }

  // Stories the model never saw: fresh items from another seed's stream.
  std::string held_out_summary;
  for (TraceStory story : held_out) {
    const int per_class = absl::GetFlag(FLAGS_held_out_per_class);
    if (per_class <= 0) break;
    int skipped = 0;
    const LabelledWindows windows = WindowsFromTraces(
        StoryTraces(story, per_class, seed + 1000), pipeline, &skipped);
    std::vector<std::array<double, kHapticClasses>> probabilities;
    const ProbabilisticScore held = score_windows(windows, &probabilities);
    std::printf(
        "\nheld-out story %s (never trained on; %d per class, seed %lu, %d "
        "without contact): accuracy %.2f%%, log loss %.4f, calibration error "
        "%.4f\n%s",
        TraceStoryName(story), per_class,
        static_cast<unsigned long>(seed + 1000), skipped,
        100.0 * held.confusion.Accuracy(), held.mean_log_loss,
        held.expected_calibration_error, held.confusion.ToString().c_str());
    absl::StrAppend(&held_out_summary, held_out_summary.empty() ? "" : ";",
                    TraceStoryName(story), ":",
                    absl::StrFormat("%.4f", held.confusion.Accuracy()));
  }

  std::map<std::string, std::string> metadata = {
      {"bitewise.classes", "hard,medium,soft,hard_skin"},
      {"bitewise.input",
       "tared fx,fy,fz (N), tx,ty,tz (N m) from first contact, each "
       "resampled to 64 points over the window; channel-major"},
      {kHapticNetWindowKey, absl::StrCat(pipeline.window.window_s)},
      {"bitewise.traces", source},
      {"bitewise.seed", absl::StrCat(seed)},
      {"bitewise.best_epoch", absl::StrCat(result->best_epoch)},
      {"bitewise.label_smoothing",
       absl::StrFormat("%.3f", options.label_smoothing)},
      {"bitewise.temperature", absl::StrFormat("%.2f", result->temperature)},
      {"bitewise.test_accuracy",
       absl::StrFormat("%.4f", score.confusion.Accuracy())},
      {"bitewise.held_out_accuracy",
       held_out_summary.empty() ? "none" : held_out_summary},
  };
  if (!options.conv_channels.empty()) {
    metadata["bitewise.conv_channels"] =
        absl::StrJoin(options.conv_channels, ",");
  }
  if (!recorded_summary.empty()) {
    metadata["bitewise.recorded_test_accuracy"] = recorded_summary;
  }
  const std::string bytes = HapticNetToOnnx(result->weights, metadata);
  const std::string out = absl::GetFlag(FLAGS_out);
  // The file as the service will load it: OpenCV must agree with the
  // trainer on every held-out window.
  const std::unique_ptr<HapticNet> net = StageModel(out, bytes);
  if (net == nullptr) return 1;
  double max_difference = 0.0;
  for (size_t i = 0; i < test_windows.inputs.size(); ++i) {
    absl::StatusOr<HapticNetOutput> output = net->Run(test_windows.inputs[i]);
    if (!output.ok()) return Abandon(out, output.status());
    for (int k = 0; k < kHapticClasses; ++k) {
      max_difference = std::max(
          max_difference, std::abs(output->probabilities[k] - reference[i][k]));
    }
  }
  return CheckAndCommit(out, bytes.size(), *net, max_difference,
                        " on the test set", familiarity);
}
