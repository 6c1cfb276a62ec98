// A lab's PyTorch SPANet, end to end: a checkpoint exported by
// scripts/spanet/export_onnx.py (the ctest fixture spanet_export made one
// from a seeded random SPANet) is loaded by the PerceptionService and fed
// crops of rendered plates through Featurize over gRPC. Features, action
// scores and skewer points must equal PyTorch's (eval mode) within 1e-4
// relative, and the service's 144x144 input canvas must equal the reference
// preprocessing (PIL) pixel for pixel, on crops of odd and even sizes,
// portrait and landscape, shrunk and enlarged. PyTorch's numbers come from
// scripts/spanet/reference.py run on the same crops.
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "gtest/gtest.h"
#include "opencv2/imgcodecs.hpp"
#include "opencv2/imgproc.hpp"
#include "services/common/channel.h"
#include "services/common/server.h"
#include "services/perception/food_detector.h"
#include "services/perception/perception_service.h"
#include "services/perception/spanet_featurizer.h"
#include "tests/perception/test_frames.h"

namespace bitewise::perception {
namespace {

constexpr char kService[] = "bitewise.v1.PerceptionService";
const char* const kLocationNames[] = {"isolated", "wall", "lettuce"};

struct Crop {
  PixelBox box;
  FoodLocation location;
};

// Boxes on one rendered 640x480 plate: every item's true box, then boxes
// chosen for their sizes (odd/even, portrait/landscape, larger and smaller
// than SPANet's 144).
std::vector<Crop> CropsOf(const sim::RenderedFrame& rendered) {
  std::vector<Crop> crops;
  int i = 0;
  for (const sim::ItemTruth& t : rendered.truth) {
    crops.push_back(
        {{t.x, t.y, t.width, t.height}, static_cast<FoodLocation>(i++ % 3)});
  }
  const PixelBox sized[] = {{200, 150, 203, 57},  {260, 120, 100, 200},
                            {250, 170, 145, 143}, {300, 200, 18, 31},
                            {280, 180, 96, 96},   {180, 140, 301, 77},
                            {290, 160, 63, 151},  {230, 150, 145, 144}};
  for (const PixelBox& b : sized) {
    crops.push_back({b, static_cast<FoodLocation>(i++ % 3)});
  }
  return crops;
}

std::map<std::string, std::vector<double>> ReadValues(const std::string& path) {
  std::map<std::string, std::vector<double>> values;
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream words(line);
    std::string name;
    words >> name;
    double v;
    while (words >> v) values[name].push_back(v);
  }
  return values;
}

// max |got - want| / max |want|, as the export tool measures it.
double RelativeError(const std::vector<double>& got,
                     const std::vector<double>& want) {
  double diff = 0.0, scale = 1e-12;
  for (size_t i = 0; i < want.size(); ++i) {
    diff = std::max(diff, std::abs(got[i] - want[i]));
    scale = std::max(scale, std::abs(want[i]));
  }
  return diff / scale;
}

TEST(SpanetFromPytorchTest, ServiceFeaturizeEqualsPytorchOnRenderedCrops) {
  const std::string dir = BITEWISE_SPANET_TEST_DIR;
  auto loaded = SpanetFeaturizer::Load(dir + "/test_spanet.onnx");
  ASSERT_TRUE(loaded.ok()) << loaded.status()
                           << " (made by the ctest fixture spanet_export)";
  const std::unique_ptr<SpanetFeaturizer> spanet = *std::move(loaded);
  const FoodDetector detector;
  RpcEnvironment env;
  PerceptionServiceImpl service(&env, &detector, spanet.get());
  auto server =
      ServiceServer::Start(ServerOptions(), &env, {&service}, {kService});
  ASSERT_TRUE(server.ok()) << server.status();
  (*server)->SetServing(true);
  auto channel = MakeChannel((*server)->address(), ChannelOptions());
  ASSERT_TRUE(channel.ok());
  auto stub = v1::PerceptionService::NewStub(*channel);

  const std::string work = ::testing::TempDir() + "/spanet_pytorch";
  std::filesystem::create_directories(work + "/reference");
  std::vector<testing::TestScene> scenes;
  for (uint64_t seed : {11, 12}) {
    scenes.push_back(testing::RenderTestScene(seed, 4, true));
  }
  // Write every crop (the frame's own RGB) for the reference.
  std::vector<std::pair<int, Crop>> all;
  std::vector<std::string> specs;
  for (int s = 0; s < static_cast<int>(scenes.size()); ++s) {
    const DecodedFrame frame = testing::ToDecoded(scenes[s].rendered);
    for (const Crop& c : CropsOf(scenes[s].rendered)) {
      cv::Mat bgr;
      cv::cvtColor(
          frame.rgb(cv::Rect(c.box.x, c.box.y, c.box.width, c.box.height)), bgr,
          cv::COLOR_RGB2BGR);
      const std::string path = absl::StrCat(work, "/crop", all.size(), ".png");
      ASSERT_TRUE(cv::imwrite(path, bgr));
      specs.push_back(absl::StrCat(
          path, ":", kLocationNames[static_cast<int>(c.location)]));
      all.push_back({s, c});
    }
  }
  const std::string command =
      absl::StrCat(BITEWISE_PYTHON3, " ", BITEWISE_SOURCE_DIR,
                   "/scripts/spanet/reference.py --checkpoint=", dir,
                   "/test_spanet.pth --crops=", absl::StrJoin(specs, ","),
                   " --out=", work, "/reference");
  ASSERT_EQ(std::system(command.c_str()), 0) << command;

  for (size_t i = 0; i < all.size(); ++i) {
    const auto& [s, c] = all[i];
    SCOPED_TRACE(absl::StrCat("crop ", i, ": ", c.box.width, "x", c.box.height,
                              " at ", c.box.x, ",", c.box.y));
    const std::string stem = absl::StrCat(work, "/reference/crop", i);
    // Preprocessing, pixel for pixel.
    cv::Mat want_bgr = cv::imread(stem + ".canvas.png", cv::IMREAD_COLOR);
    ASSERT_FALSE(want_bgr.empty());
    cv::Mat want;
    cv::cvtColor(want_bgr, want, cv::COLOR_BGR2RGB);
    const DecodedFrame frame = testing::ToDecoded(scenes[s].rendered);
    const cv::Mat got = SpanetCanvas8u(
        frame.rgb(cv::Rect(c.box.x, c.box.y, c.box.width, c.box.height)));
    cv::Mat differ;
    cv::compare(got.reshape(1), want.reshape(1), differ, cv::CMP_NE);
    EXPECT_EQ(cv::countNonZero(differ), 0);

    // Featurize over gRPC on the whole frame (PNG) with the box.
    v1::FeaturizeRequest request;
    *request.mutable_frame() =
        testing::ToProto(scenes[s].rendered, v1::IMAGE_ENCODING_PNG);
    request.mutable_bbox()->set_x(c.box.x);
    request.mutable_bbox()->set_y(c.box.y);
    request.mutable_bbox()->set_width(c.box.width);
    request.mutable_bbox()->set_height(c.box.height);
    request.set_location(
        static_cast<v1::FoodLocation>(static_cast<int>(c.location) + 1));
    v1::FeaturizeResponse response;
    grpc::ClientContext context;
    grpc::Status status = stub->Featurize(&context, request, &response);
    ASSERT_TRUE(status.ok()) << status.error_message();
    const auto reference = ReadValues(stem + ".txt");
    const std::vector<double> context_values(response.context().begin(),
                                             response.context().end());
    const std::vector<double> scores(response.action_scores().begin(),
                                     response.action_scores().end());
    std::vector<double> points;
    for (const v1::Pixel& p : response.skewer_points()) {
      points.push_back(p.u());
      points.push_back(p.v());
    }
    ASSERT_EQ(context_values.size(), 2048u);
    ASSERT_EQ(reference.at("context").size(), 2048u);
    EXPECT_LT(RelativeError(context_values, reference.at("context")), 1e-4);
    EXPECT_LT(RelativeError(scores, reference.at("action_scores")), 1e-4);
    EXPECT_LT(RelativeError(points, reference.at("skewer_points")), 1e-4);
  }
  (*server)->Shutdown();
}

}  // namespace
}  // namespace bitewise::perception
