// The meal's trace recording: files the trainer reads back exactly, ids that
// continue across runs, a row cut short by a crash repaired, a directory of
// an earlier release (no familiarity columns) kept in its format, and bad
// directories and traces refused by name.
#include "clients/meal/trace_recording.h"

#include <signal.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cstdlib>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "services/domain/trace_csv.h"
#include "services/haptic/training/labelled_traces.h"
#include "tests/common/status_matchers.h"

namespace bitewise::meals {
namespace {

using ::bitewise::testing::IsOk;
using ::bitewise::testing::StatusIs;
using ::testing::HasSubstr;

std::string TempDir() {
  std::string dir = ::testing::TempDir() + "/recording_XXXXXX";
  EXPECT_NE(mkdtemp(dir.data()), nullptr);
  return dir;
}

google::protobuf::RepeatedPtrField<v1::WrenchSample> Trace(int n,
                                                           double scale) {
  google::protobuf::RepeatedPtrField<v1::WrenchSample> trace;
  for (int i = 0; i < n; ++i) {
    v1::WrenchSample* s = trace.Add();
    s->set_t_s(0.001 * i);
    s->set_fx_n(0.1 * scale * i);
    s->set_fy_n(-0.2 * scale);
    s->set_fz_n(scale * i / 3.0);  // not exact in decimal
    s->set_tx_nm(1e-3 * i);
    s->set_ty_nm(-2e-3);
    s->set_tz_nm(3e-4 * scale);
  }
  return trace;
}

RecordedBite Bite(const std::string& event, bool labelled) {
  RecordedBite bite;
  bite.user_id = "alice";
  bite.meal_id = "m1";
  bite.event_id = event;
  bite.food = labelled ? "grape" : "";
  if (labelled) bite.label = domain::HapticClass::kHardSkin;
  bite.action = "TV0";
  bite.outcome = "success";
  bite.haptic = domain::HapticClass::kMedium;
  bite.probabilities = {0.1, 0.6, 0.1, 0.2};
  bite.familiarity = 0.7 / 24.0;  // 0.029166..., below the 0.05 threshold
  bite.unfamiliar = true;
  return bite;
}

// bites.csv as the release before the familiarity columns wrote it, and
// the one before the force-limit column.
constexpr char kHeaderBeforeFamiliarity[] =
    "trace,time_utc,user,meal,event_id,food,label,action,outcome,haptic,"
    "p_hard,p_medium,p_soft,p_hard_skin";
constexpr char kHeaderBeforeForceLimit[] =
    "trace,time_utc,user,meal,event_id,food,label,action,outcome,haptic,"
    "p_hard,p_medium,p_soft,p_hard_skin,familiarity,unfamiliar";

std::vector<std::string> Lines(const std::string& path) {
  std::ifstream in(path);
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

TEST(TraceRecordingTest, WritesWhatTheTrainerReadsBackExactly) {
  const std::string dir = TempDir() + "/new";  // created by Open
  auto recording = TraceRecording::Open(dir);
  ASSERT_THAT(recording.status(), IsOk());
  EXPECT_TRUE((*recording)->records_familiarity());
  EXPECT_TRUE((*recording)->records_force_limit());
  EXPECT_EQ((*recording)->note(), "");
  const auto first = Trace(50, 1.0);
  const auto second = Trace(30, 2.5);
  RecordedBite cut = Bite("e1", true);  // stopped at the force limit
  cut.force_limit_reached = true;
  ASSERT_THAT((*recording)->Record(cut, first).status(), IsOk());
  RecordedBite no_score = Bite("e2", false);  // a service without the model
  no_score.familiarity.reset();
  absl::StatusOr<std::string> id = (*recording)->Record(no_score, second);
  ASSERT_THAT(id.status(), IsOk());
  EXPECT_EQ(*id, "1");
  EXPECT_EQ((*recording)->recorded(), 2);

  auto traces = haptic::ReadRecordedTraces(dir + "/traces.csv");
  ASSERT_THAT(traces.status(), IsOk());
  ASSERT_EQ(traces->size(), 2u);
  EXPECT_EQ((*traces)[0].id, "0");
  EXPECT_EQ((*traces)[0].label, domain::HapticClass::kHardSkin);
  EXPECT_FALSE((*traces)[1].label.has_value());  // "unknown"
  ASSERT_EQ((*traces)[0].samples.size(), 50u);
  for (int i = 0; i < 50; ++i) {  // bit for bit
    const domain::TimedWrench& s = (*traces)[0].samples[i];
    EXPECT_EQ(s.t_s, first[i].t_s());
    EXPECT_EQ(s.wrench.force_n[2], first[i].fz_n());
    EXPECT_EQ(s.wrench.torque_nm[2], first[i].tz_nm());
  }
  // The strict reader of story files refuses "unknown", naming the line.
  EXPECT_THAT(haptic::ReadTraceCsv(dir + "/traces.csv").status(),
              StatusIs(absl::StatusCode::kInvalidArgument,
                       HasSubstr("traces.csv:52: unknown label \"unknown\"")));

  const std::vector<std::string> bites = Lines(dir + "/bites.csv");
  ASSERT_EQ(bites.size(), 3u);
  EXPECT_EQ(bites[0],
            absl::StrCat(kHeaderBeforeForceLimit, ",force_limit_reached"));
  const std::vector<std::string> row = absl::StrSplit(bites[1], ',');
  ASSERT_EQ(row.size(), 17u);
  EXPECT_EQ(row[0], "0");
  EXPECT_THAT(row[1],
              ::testing::MatchesRegex("[0-9]{4}-[0-9]{2}-[0-9]{2}T[0-9:.]+Z"));
  EXPECT_EQ(row[2], "alice");
  EXPECT_EQ(row[4], "e1");
  EXPECT_EQ(row[5], "grape");
  EXPECT_EQ(row[6], "hard_skin");
  EXPECT_EQ(row[7], "TV0");
  EXPECT_EQ(row[9], "medium");
  EXPECT_EQ(row[11], "0.600000");
  EXPECT_EQ(row[14], "0.029167");
  EXPECT_EQ(row[15], "1");
  EXPECT_EQ(row[16], "1");  // cut short at the force limit
  const std::vector<std::string> unscored = absl::StrSplit(bites[2], ',');
  ASSERT_EQ(unscored.size(), 17u);
  EXPECT_EQ(unscored[16], "0");
  EXPECT_EQ(unscored[13], "0.200000");  // HapticNet answered
  EXPECT_EQ(unscored[14], "");          // but gave no familiarity
  EXPECT_EQ(unscored[15], "");

  // A lab labels the unknown bite in bites.csv; the labels file says so.
  auto labels = haptic::ReadTraceLabels(dir + "/bites.csv");
  ASSERT_THAT(labels.status(), IsOk());
  EXPECT_EQ(labels->at("0"), domain::HapticClass::kHardSkin);
  EXPECT_FALSE(labels->at("1").has_value());
}

TEST(TraceRecordingTest, IdsContinueAcrossRunsAndACutRowIsDropped) {
  const std::string dir = TempDir();
  {
    auto recording = TraceRecording::Open(dir);
    ASSERT_THAT(recording.status(), IsOk());
    ASSERT_THAT((*recording)->Record(Bite("e1", true), Trace(20, 1)).status(),
                IsOk());
    ASSERT_THAT((*recording)->Record(Bite("e2", true), Trace(20, 1)).status(),
                IsOk());
  }
  // A power loss left half a row at the end of traces.csv.
  { std::ofstream(dir + "/traces.csv", std::ios::app) << "2,hard,0.01,1.5"; }
  auto recording = TraceRecording::Open(dir);
  ASSERT_THAT(recording.status(), IsOk());
  absl::StatusOr<std::string> id =
      (*recording)->Record(Bite("e3", true), Trace(20, 1));
  ASSERT_THAT(id.status(), IsOk());
  EXPECT_EQ(*id, "2");
  auto traces = haptic::ReadRecordedTraces(dir + "/traces.csv");
  ASSERT_THAT(traces.status(), IsOk());
  ASSERT_EQ(traces->size(), 3u);
  EXPECT_EQ((*traces)[2].id, "2");
  EXPECT_EQ((*traces)[2].samples.size(), 20u);
  EXPECT_EQ(Lines(dir + "/bites.csv").size(), 4u);
}

std::string FileText(const std::string& path) {
  std::ifstream in(path);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

// A crash between a bite's two writes leaves whole rows of a trace in
// traces.csv and no row in bites.csv: no outcome, no label, and maybe half
// the trace. The next open cuts them off (here 5,000 rows, about 150 KB:
// three 64 KiB blocks read backwards), says so, and the id is used again.
// Before, the trainer read them as a whole labelled trace. bites.csv is
// read whole (a spreadsheet may sort it, add empty rows, or save it without
// the last newline); one missing bites is refused, not repaired by
// cutting traces off.
TEST(TraceRecordingTest, ATraceWithoutItsBiteRowIsCutOffAtOpen) {
  const std::string dir = TempDir();
  {
    auto recording = TraceRecording::Open(dir);
    ASSERT_THAT(recording.status(), IsOk());
    ASSERT_THAT((*recording)->Record(Bite("e1", true), Trace(3000, 1)).status(),
                IsOk());
    ASSERT_THAT((*recording)->Record(Bite("e2", true), Trace(3000, 2)).status(),
                IsOk());
  }
  const std::string whole = FileText(dir + "/traces.csv");
  {
    std::ofstream out(dir + "/traces.csv", std::ios::app);
    for (int i = 0; i < 5000; ++i)
      out << "2,hard_skin," << 0.001 * i << ",1,2,3,4,5,6\n";
  }
  ASSERT_GT(FileText(dir + "/traces.csv").size(), whole.size() + 2 * 65536);
  // bites.csv as a spreadsheet may leave it: bite 1's row dropped. Not
  // repaired by cutting traces off (trace 1 has its rows): refused.
  const std::string bites = FileText(dir + "/bites.csv");
  const size_t last_row = bites.rfind('\n', bites.size() - 2) + 1;
  std::ofstream(dir + "/bites.csv", std::ios::trunc)
      << bites.substr(0, last_row);
  EXPECT_THAT(TraceRecording::Open(dir).status(),
              StatusIs(absl::StatusCode::kFailedPrecondition,
                       HasSubstr("traces.csv ends with trace 2 but")));
  EXPECT_GT(FileText(dir + "/traces.csv").size(), whole.size());  // untouched
  // Sorted with bite 1 first, a row of empty cells added, and saved without
  // the last newline: still bites 0 and 1, so only trace 2 is cut.
  const std::string header = bites.substr(0, bites.find('\n') + 1);
  const std::string row0 =
      bites.substr(header.size(), last_row - header.size());
  const std::string row1 = bites.substr(last_row);
  std::ofstream(dir + "/bites.csv", std::ios::trunc)
      << header << row1 << ",,,,,,,,,\n"
      << row0.substr(0, row0.size() - 1);
  auto recording = TraceRecording::Open(dir);
  ASSERT_THAT(recording.status(), IsOk());
  EXPECT_EQ(FileText(dir + "/traces.csv"), whole);
  EXPECT_THAT((*recording)->note(), HasSubstr("cut off trace 2's rows"));
  // The row saved without its newline was ended, not dropped.
  EXPECT_THAT(FileText(dir + "/bites.csv"), HasSubstr(row0));
  absl::StatusOr<std::string> id =
      (*recording)->Record(Bite("e3", true), Trace(20, 3));
  ASSERT_THAT(id.status(), IsOk());
  EXPECT_EQ(*id, "2");
  auto traces = haptic::ReadRecordedTraces(dir + "/traces.csv");
  ASSERT_THAT(traces.status(), IsOk());
  ASSERT_EQ(traces->size(), 3u);
  EXPECT_EQ((*traces)[2].samples.size(), 20u);
}

// A write that fails part way (the file size limit here, as a full disk)
// leaves neither file with part of the bite, and says so.
TEST(TraceRecordingTest,
     AWriteThatFailsPartWayLeavesNeitherFileWithPartOfTheBite) {
  const std::string dir = TempDir();
  auto recording = TraceRecording::Open(dir);
  ASSERT_THAT(recording.status(), IsOk());
  ASSERT_THAT((*recording)->Record(Bite("e1", true), Trace(20, 1)).status(),
              IsOk());
  const std::string traces_before = FileText(dir + "/traces.csv");
  const std::string bites_before = FileText(dir + "/bites.csv");
  signal(SIGXFSZ, SIG_IGN);
  rlimit old_limit{};
  ASSERT_EQ(getrlimit(RLIMIT_FSIZE, &old_limit), 0);
  rlimit limit = old_limit;
  limit.rlim_cur = traces_before.size() + 4096;
  ASSERT_EQ(setrlimit(RLIMIT_FSIZE, &limit), 0);
  const absl::StatusOr<std::string> failed =
      (*recording)->Record(Bite("e2", true), Trace(3000, 1));
  ASSERT_EQ(setrlimit(RLIMIT_FSIZE, &old_limit), 0);
  signal(SIGXFSZ, SIG_DFL);
  EXPECT_THAT(failed.status(),
              StatusIs(absl::StatusCode::kInternal,
                       HasSubstr("this bite's rows were cut off again")));
  EXPECT_EQ(FileText(dir + "/traces.csv"), traces_before);
  EXPECT_EQ(FileText(dir + "/bites.csv"), bites_before);
}

// One process records into a directory at a time: a second open is
// refused before it reads or repairs anything, and the directory is free
// once the first closes. A bites.csv a spreadsheet saved with CRLF line
// ends is still this recording.
TEST(TraceRecordingTest, OneProcessAtATimeAndACrlfHeaderIsKept) {
  const std::string dir = TempDir();
  {
    auto first = TraceRecording::Open(dir);
    ASSERT_THAT(first.status(), IsOk());
    EXPECT_THAT(TraceRecording::Open(dir).status(),
                StatusIs(absl::StatusCode::kFailedPrecondition,
                         HasSubstr("is open in another process")));
    ASSERT_THAT((*first)->Record(Bite("e1", true), Trace(20, 1)).status(),
                IsOk());
  }
  std::string bites = FileText(dir + "/bites.csv");
  std::string crlf;
  for (char c : bites) {
    if (c == '\n') crlf += '\r';
    crlf += c;
  }
  std::ofstream(dir + "/bites.csv", std::ios::trunc) << crlf;
  auto again = TraceRecording::Open(dir);
  ASSERT_THAT(again.status(), IsOk());
  absl::StatusOr<std::string> id =
      (*again)->Record(Bite("e2", true), Trace(20, 1));
  ASSERT_THAT(id.status(), IsOk());
  EXPECT_EQ(*id, "1");
}

// A lab's directory from the release before the familiarity columns: the
// new orchestrator keeps appending to it in its own format (one table for
// the spreadsheet and --labels), says once that familiarity is not recorded
// there, and the trainer reads its labels.
TEST(TraceRecordingTest, AnOlderDirectoryKeepsItsFormatAndSaysSo) {
  const std::string dir = TempDir();
  {
    std::string traces = absl::StrCat(domain::kTraceCsvHeader, "\n");
    for (int i = 0; i < 20; ++i) {
      domain::AppendTraceCsvRow(&traces, "0", "hard", 0.001 * i,
                                {0, 0, 0.5 * i, 0, 0, 0});
    }
    std::ofstream(dir + "/traces.csv") << traces;
    std::ofstream(dir + "/bites.csv")
        << kHeaderBeforeFamiliarity << "\n"
        << "0,2026-11-30T10:00:00.000Z,alice,m0,e0,carrot,hard,VS0,success,"
           "hard,0.970000,0.010000,0.010000,0.010000\n";
  }
  for (int run = 1; run <= 2; ++run) {  // and again: still the old format
    auto recording = TraceRecording::Open(dir);
    ASSERT_THAT(recording.status(), IsOk());
    EXPECT_FALSE((*recording)->records_familiarity());
    EXPECT_EQ((*recording)->note(),
              absl::StrCat(dir,
                           "/bites.csv predates the familiarity columns (an "
                           "earlier release started it), so familiarity and "
                           "the force limit are not recorded in this "
                           "directory; record into a new directory to have "
                           "them"));
    absl::StatusOr<std::string> id =
        (*recording)
            ->Record(Bite(absl::StrCat("e", run), run == 1), Trace(20, 1));
    ASSERT_THAT(id.status(), IsOk());
    EXPECT_EQ(*id, absl::StrCat(run));
  }
  const std::vector<std::string> bites = Lines(dir + "/bites.csv");
  ASSERT_EQ(bites.size(), 4u);
  EXPECT_EQ(bites[0], kHeaderBeforeFamiliarity);
  for (size_t i = 1; i < bites.size(); ++i) {
    const std::vector<std::string> row = absl::StrSplit(bites[i], ',');
    ASSERT_EQ(row.size(), 14u) << bites[i];
    EXPECT_EQ(row[0], absl::StrCat(i - 1));
  }
  EXPECT_THAT(bites[2], HasSubstr(",hard_skin,TV0,success,medium,0.100000,"
                                  "0.600000,0.100000,0.200000"));

  auto labels = haptic::ReadTraceLabels(dir + "/bites.csv");
  ASSERT_THAT(labels.status(), IsOk());
  ASSERT_EQ(labels->size(), 3u);
  EXPECT_EQ(labels->at("0"), domain::HapticClass::kHard);
  EXPECT_EQ(labels->at("1"), domain::HapticClass::kHardSkin);
  EXPECT_FALSE(labels->at("2").has_value());
  auto traces = haptic::ReadRecordedTraces(dir + "/traces.csv");
  ASSERT_THAT(traces.status(), IsOk());
  EXPECT_EQ(traces->size(), 3u);
}

// A directory from the release before the force-limit column keeps its
// sixteen columns, familiarity included, and says once what it lacks.
TEST(TraceRecordingTest, ADirectoryBeforeTheForceLimitColumnKeepsItsFormat) {
  const std::string dir = TempDir();
  std::ofstream(dir + "/bites.csv") << kHeaderBeforeForceLimit << "\n";
  auto recording = TraceRecording::Open(dir);
  ASSERT_THAT(recording.status(), IsOk());
  EXPECT_TRUE((*recording)->records_familiarity());
  EXPECT_FALSE((*recording)->records_force_limit());
  EXPECT_EQ((*recording)->note(),
            absl::StrCat(dir,
                         "/bites.csv predates the force_limit_reached column "
                         "(an earlier release started it), so whether the "
                         "force limit cut a trace short is not recorded in "
                         "this directory; record into a new directory to "
                         "have it"));
  RecordedBite cut = Bite("e1", true);
  cut.force_limit_reached = true;
  ASSERT_THAT((*recording)->Record(cut, Trace(20, 1)).status(), IsOk());
  const std::vector<std::string> bites = Lines(dir + "/bites.csv");
  ASSERT_EQ(bites.size(), 2u);
  EXPECT_EQ(bites[0], kHeaderBeforeForceLimit);
  const std::vector<std::string> row = absl::StrSplit(bites[1], ',');
  ASSERT_EQ(row.size(), 16u) << bites[1];
  EXPECT_EQ(row[14], "0.029167");
  EXPECT_EQ(row[15], "1");
}

TEST(TraceRecordingTest, RefusesForeignFilesEmptyTracesAndUnwritableDirs) {
  const std::string dir = TempDir();
  { std::ofstream(dir + "/traces.csv") << "time,fz\n0,1\n"; }
  EXPECT_THAT(TraceRecording::Open(dir).status(),
              StatusIs(absl::StatusCode::kInvalidArgument,
                       HasSubstr("traces.csv is not a bitewise recording")));
  // A bites.csv whose first line is neither this release's header nor the
  // one before is refused, naming the file: another CSV, a header cut short
  // or extended, and this release's header without its newline.
  const std::string current =
      absl::StrCat(kHeaderBeforeForceLimit, ",force_limit_reached");
  for (const std::string& text :
       {std::string("trace,label\n0,hard\n"),
        absl::StrCat(kHeaderBeforeFamiliarity, ",familiarity\n"),
        absl::StrCat(current, ",x\n"), absl::StrCat("#", current, "\n"),
        current}) {
    const std::string foreign = TempDir();
    { std::ofstream(foreign + "/bites.csv") << text; }
    EXPECT_THAT(
        TraceRecording::Open(foreign).status(),
        StatusIs(absl::StatusCode::kInvalidArgument,
                 HasSubstr(absl::StrCat(foreign,
                                        "/bites.csv is not a bitewise "
                                        "recording: its first line is not"))))
        << text;
  }

  const std::string good = TempDir();
  auto recording = TraceRecording::Open(good);
  ASSERT_THAT(recording.status(), IsOk());
  EXPECT_THAT((*recording)->Record(Bite("e9", true), Trace(0, 1)).status(),
              StatusIs(absl::StatusCode::kInvalidArgument,
                       HasSubstr("event e9: the trace is empty")));
  EXPECT_EQ(Lines(good + "/bites.csv").size(), 1u);  // header only

  EXPECT_THAT(TraceRecording::Open("/proc/bitewise-no-such/recording").status(),
              StatusIs(absl::StatusCode::kInternal,
                       HasSubstr("cannot create the directory")));
}

TEST(TraceRecordingTest, LabelFilesAreCheckedByLine) {
  const std::string dir = TempDir();
  { std::ofstream(dir + "/a.csv") << "trace,label\n0,hard\n1,crunchy\n"; }
  EXPECT_THAT(haptic::ReadTraceLabels(dir + "/a.csv").status(),
              StatusIs(absl::StatusCode::kInvalidArgument,
                       HasSubstr("a.csv:3: unknown label \"crunchy\"")));
  { std::ofstream(dir + "/b.csv") << "trace,food\n0,grape\n"; }
  EXPECT_THAT(haptic::ReadTraceLabels(dir + "/b.csv").status(),
              StatusIs(absl::StatusCode::kInvalidArgument,
                       HasSubstr("needs the columns \"trace\" and \"label\"")));
  { std::ofstream(dir + "/c.csv") << "label,trace\nsoft,4\nhard,4\n"; }
  EXPECT_THAT(haptic::ReadTraceLabels(dir + "/c.csv").status(),
              StatusIs(absl::StatusCode::kInvalidArgument,
                       HasSubstr("c.csv:3: trace 4 is listed twice")));
  EXPECT_THAT(haptic::ReadTraceLabels(dir + "/none.csv").status(),
              StatusIs(absl::StatusCode::kNotFound, HasSubstr("none.csv")));
}

}  // namespace
}  // namespace bitewise::meals
