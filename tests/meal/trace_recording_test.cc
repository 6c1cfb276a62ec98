// The meal's trace recording: files the trainer reads back exactly, ids that
// continue across runs, a row cut short by a crash repaired, and bad
// directories and traces refused by name.
#include "clients/meal/trace_recording.h"

#include <sys/stat.h>
#include <unistd.h>

#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
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
  return bite;
}

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
  const auto first = Trace(50, 1.0);
  const auto second = Trace(30, 2.5);
  ASSERT_THAT((*recording)->Record(Bite("e1", true), first).status(), IsOk());
  absl::StatusOr<std::string> id =
      (*recording)->Record(Bite("e2", false), second);
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
  const std::vector<std::string> row = absl::StrSplit(bites[1], ',');
  ASSERT_EQ(row.size(), 14u);
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

TEST(TraceRecordingTest, RefusesForeignFilesEmptyTracesAndUnwritableDirs) {
  const std::string dir = TempDir();
  { std::ofstream(dir + "/traces.csv") << "time,fz\n0,1\n"; }
  EXPECT_THAT(TraceRecording::Open(dir).status(),
              StatusIs(absl::StatusCode::kInvalidArgument,
                       HasSubstr("traces.csv is not a bitewise recording")));

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
