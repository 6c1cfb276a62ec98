// The featurizer check behind `bitewise-perception --check_model`
// (services/perception/model_check.h): the crop list is parsed or refused
// naming the entry, and each crop's files hold what the featurizer itself
// computes for that PNG and location (SPANet's canvas too); unreadable
// crops and unwritable directories are named.
#include "services/perception/model_check.h"

#include <stdlib.h>
#include <unistd.h>

#include <cmath>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "opencv2/imgcodecs.hpp"
#include "opencv2/imgproc.hpp"
#include "services/perception/default_featurizer.h"
#include "services/perception/spanet_featurizer.h"
#include "tests/perception/test_frames.h"

namespace bitewise::perception {
namespace {

using ::testing::ElementsAre;
using ::testing::HasSubstr;

TEST(ParseCheckCropsTest, ReadsPathsAndLocationsIsolatedByDefault) {
  const absl::StatusOr<std::vector<CheckCrop>> crops =
      ParseCheckCrops("a.png,dir:x/b.png:wall,,c.png:lettuce,d.png:isolated");
  ASSERT_TRUE(crops.ok()) << crops.status();
  ASSERT_EQ(crops->size(), 4u);
  EXPECT_EQ((*crops)[0].png_path, "a.png");
  EXPECT_EQ((*crops)[0].location, FoodLocation::kIsolated);
  EXPECT_EQ((*crops)[1].png_path, "dir:x/b.png");  // the last colon counts
  EXPECT_EQ((*crops)[1].location, FoodLocation::kWall);
  EXPECT_EQ((*crops)[2].png_path, "c.png");
  EXPECT_EQ((*crops)[2].location, FoodLocation::kLettuce);
  EXPECT_EQ((*crops)[3].png_path, "d.png");
  EXPECT_EQ((*crops)[3].location, FoodLocation::kIsolated);
}

TEST(ParseCheckCropsTest, BadEntriesAreInvalidArgumentNamingThem) {
  absl::Status status = ParseCheckCrops("a.png,b.png:kitchen").status();
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(status.message(), HasSubstr("\"b.png:kitchen\""));
  EXPECT_THAT(status.message(), HasSubstr("isolated, wall or lettuce"));

  status = ParseCheckCrops("a.png:").status();
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(status.message(), HasSubstr("\"a.png:\""));

  status = ParseCheckCrops("a.png,:wall").status();
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(status.message(), HasSubstr("an entry has no path"));

  for (const char* empty : {"", ",", ",,"}) {
    status = ParseCheckCrops(empty).status();
    EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument) << empty;
    EXPECT_THAT(status.message(), HasSubstr("no crops given"));
  }
}

// A fresh directory for one test's files.
std::string MakeTempDir() {
  std::string pattern =
      absl::StrCat(::testing::TempDir(), "/model_check_XXXXXX");
  EXPECT_NE(mkdtemp(pattern.data()), nullptr);
  return pattern;
}

// Item `i` of a rendered plate, cut out and written as a PNG. Returns the
// crop as RGB, as the check should read it back.
cv::Mat WriteCrop(const testing::TestScene& scene, int i,
                  const std::string& path) {
  const sim::RenderedFrame& r = scene.rendered;
  const cv::Mat rgb(r.intrinsics.height, r.intrinsics.width, CV_8UC3,
                    const_cast<uint8_t*>(r.rgb.data()));
  const sim::ItemTruth& t = r.truth[i];
  const cv::Mat crop = rgb(cv::Rect(t.x, t.y, t.width, t.height)).clone();
  cv::Mat bgr;
  cv::cvtColor(crop, bgr, cv::COLOR_RGB2BGR);
  EXPECT_TRUE(cv::imwrite(path, bgr));
  return crop;
}

// The numbers on the line of `file` that starts with `key`.
std::vector<double> ReadLine(const std::string& file, const std::string& key) {
  std::ifstream in(file);
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream words(line);
    std::string first;
    words >> first;
    if (first != key) continue;
    std::vector<double> values;
    double v;
    while (words >> v) values.push_back(v);
    return values;
  }
  ADD_FAILURE() << "no line \"" << key << "\" in " << file;
  return {};
}

// %.9g keeps nine significant digits.
void ExpectWritten(const std::vector<double>& written,
                   const std::vector<double>& computed) {
  ASSERT_EQ(written.size(), computed.size());
  for (size_t i = 0; i < computed.size(); ++i) {
    EXPECT_NEAR(written[i], computed[i], 1e-8 * std::abs(computed[i]) + 1e-300)
        << "value " << i;
  }
}

std::vector<double> PointsOf(const Features& features) {
  std::vector<double> points;
  for (const CropPoint& p : features.skewer_points) {
    points.push_back(p.u);
    points.push_back(p.v);
  }
  return points;
}

Features FeaturizeCrop(const Featurizer& featurizer, const cv::Mat& rgb,
                       FoodLocation location) {
  DecodedFrame frame;
  frame.rgb = rgb;
  absl::StatusOr<Features> features =
      featurizer.Featurize(frame, PixelBox{0, 0, rgb.cols, rgb.rows}, location);
  EXPECT_TRUE(features.ok()) << features.status();
  return features.ok() ? *features : Features();
}

// A PNG crop has no depth, which the default featurizer measures size and
// height from: refused, naming it (its features used to sit at their floor
// and pass for an item's).
TEST(RunModelCheckTest, TheDefaultFeaturizerRefusesCropsWithoutDepth) {
  const testing::TestScene scene = testing::RenderTestScene(3, 2, false);
  const std::string dir = MakeTempDir();
  WriteCrop(scene, 0, dir + "/in0.png");
  const DefaultFeaturizer featurizer{DefaultFeaturizerOptions()};
  const absl::Status status = RunModelCheck(
      featurizer, {{dir + "/in0.png", FoodLocation::kIsolated}}, dir);
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(std::string(status.message()),
              ::testing::HasSubstr("frame.depth_mm is empty: the default "
                                   "featurizer measures the item's size"));
}

TEST(RunModelCheckTest, WritesSpanetsOutputsAndItsInputCanvas) {
  absl::StatusOr<std::unique_ptr<SpanetFeaturizer>> spanet =
      SpanetFeaturizer::Load(BITEWISE_SPANET_MODEL);
  ASSERT_TRUE(spanet.ok()) << spanet.status();
  const testing::TestScene scene = testing::RenderTestScene(4, 1, false);
  const std::string dir = MakeTempDir();
  const cv::Mat crop = WriteCrop(scene, 0, dir + "/in.png");

  ASSERT_TRUE(
      RunModelCheck(**spanet, {{dir + "/in.png", FoodLocation::kWall}}, dir)
          .ok());
  const Features wall = FeaturizeCrop(**spanet, crop, FoodLocation::kWall);
  const std::string txt = dir + "/crop0.txt";
  ExpectWritten(ReadLine(txt, "context"), wall.context);
  ExpectWritten(ReadLine(txt, "action_scores"), wall.action_scores);
  ExpectWritten(ReadLine(txt, "skewer_points"), PointsOf(wall));
  EXPECT_EQ(ReadLine(txt, "action_scores").size(), 6u);
  EXPECT_EQ(ReadLine(txt, "skewer_points").size(), 4u);
  // The location given is the one used: isolated differs from the file.
  const Features isolated =
      FeaturizeCrop(**spanet, crop, FoodLocation::kIsolated);
  EXPECT_NE(isolated.context, wall.context);

  const cv::Mat canvas_bgr =
      cv::imread(dir + "/crop0.canvas.png", cv::IMREAD_COLOR);
  ASSERT_FALSE(canvas_bgr.empty());
  cv::Mat canvas;
  cv::cvtColor(canvas_bgr, canvas, cv::COLOR_BGR2RGB);
  const cv::Mat want = SpanetCanvas8u(crop);
  ASSERT_EQ(canvas.size(), cv::Size(144, 144));
  EXPECT_EQ(cv::norm(canvas, want, cv::NORM_INF), 0.0);
}

TEST(RunModelCheckTest, AMissingOrNonImageCropIsNotFoundNamingIt) {
  const std::string dir = MakeTempDir();
  const DefaultFeaturizer featurizer{DefaultFeaturizerOptions()};
  absl::Status status = RunModelCheck(
      featurizer, {{dir + "/absent.png", FoodLocation::kIsolated}}, dir);
  EXPECT_EQ(status.code(), absl::StatusCode::kNotFound);
  EXPECT_THAT(status.message(), HasSubstr(dir + "/absent.png"));

  const std::string text = dir + "/notes.png";
  std::ofstream(text) << "not a PNG at all\n";
  status = RunModelCheck(featurizer, {{text, FoodLocation::kIsolated}}, dir);
  EXPECT_EQ(status.code(), absl::StatusCode::kNotFound);
  EXPECT_THAT(status.message(), HasSubstr("notes.png"));
  EXPECT_THAT(status.message(), HasSubstr("not an image"));
  // Nothing was written for it.
  EXPECT_NE(access((dir + "/crop0.txt").c_str(), F_OK), 0);
}

TEST(RunModelCheckTest, AnUnwritableDirectoryIsFailedPreconditionNamingIt) {
  const testing::TestScene scene = testing::RenderTestScene(3, 1, false);
  const std::string dir = MakeTempDir();
  WriteCrop(scene, 0, dir + "/in.png");
  absl::StatusOr<std::unique_ptr<SpanetFeaturizer>> spanet =
      SpanetFeaturizer::Load(BITEWISE_SPANET_MODEL);
  ASSERT_TRUE(spanet.ok()) << spanet.status();
  const std::string out = dir + "/no/such/dir";
  const absl::Status status = RunModelCheck(
      **spanet, {{dir + "/in.png", FoodLocation::kIsolated}}, out);
  EXPECT_EQ(status.code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(status.message(), HasSubstr(out + "/crop0.txt"));
}

}  // namespace
}  // namespace bitewise::perception
