// In-process tests of the PerceptionService: the real detector and
// featurizers behind a real gRPC server on a loopback port, called through
// a stub with PNG, JPEG and raw frames; bad requests get INVALID_ARGUMENT
// with messages that name the problem.
#include "services/perception/perception_service.h"

#include <chrono>
#include <memory>
#include <string>

#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "services/common/channel.h"
#include "services/common/server.h"
#include "services/perception/default_featurizer.h"
#include "services/perception/spanet_featurizer.h"
#include "tests/perception/test_frames.h"

namespace bitewise::perception {
namespace {

using ::testing::HasSubstr;

constexpr char kService[] = "bitewise.v1.PerceptionService";

class PerceptionServiceTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    auto loaded = SpanetFeaturizer::Load(BITEWISE_SPANET_MODEL);
    ASSERT_TRUE(loaded.ok()) << loaded.status();
    spanet_ = loaded->release();
    scene_ = new testing::TestScene(testing::RenderTestScene(42, 6, true));
  }
  static void TearDownTestSuite() {
    delete spanet_;
    delete scene_;
  }

  void StartWith(const Featurizer* featurizer) {
    service_ =
        std::make_unique<PerceptionServiceImpl>(&env_, &detector_, featurizer);
    auto server = ServiceServer::Start(ServerOptions(), &env_, {service_.get()},
                                       {kService});
    ASSERT_TRUE(server.ok()) << server.status();
    server_ = *std::move(server);
    server_->SetServing(true);
    auto channel = MakeChannel(server_->address(), ChannelOptions());
    ASSERT_TRUE(channel.ok());
    ASSERT_TRUE(WaitForServing(*channel, kService, absl::Seconds(10)).ok());
    stub_ = v1::PerceptionService::NewStub(*channel);
  }

  void TearDown() override {
    if (server_) server_->Shutdown();
  }

  std::unique_ptr<grpc::ClientContext> Ctx() {
    auto context = std::make_unique<grpc::ClientContext>();
    context->set_deadline(std::chrono::system_clock::now() +
                          std::chrono::seconds(20));
    return context;
  }

  v1::Frame Frame(v1::ImageEncoding encoding = v1::IMAGE_ENCODING_PNG) {
    return testing::ToProto(scene_->rendered, encoding);
  }

  static SpanetFeaturizer* spanet_;
  static testing::TestScene* scene_;
  RpcEnvironment env_;
  const FoodDetector detector_;
  const DefaultFeaturizer default_featurizer_;
  std::unique_ptr<PerceptionServiceImpl> service_;
  std::unique_ptr<ServiceServer> server_;
  std::unique_ptr<v1::PerceptionService::Stub> stub_;
};
SpanetFeaturizer* PerceptionServiceTest::spanet_ = nullptr;
testing::TestScene* PerceptionServiceTest::scene_ = nullptr;

TEST_F(PerceptionServiceTest, DetectFoodFindsTheItemsOfAPngFrame) {
  StartWith(&default_featurizer_);
  for (auto encoding : {v1::IMAGE_ENCODING_PNG, v1::IMAGE_ENCODING_RGB8,
                        v1::IMAGE_ENCODING_JPEG}) {
    v1::DetectFoodRequest request;
    *request.mutable_frame() = Frame(encoding);
    v1::DetectFoodResponse response;
    grpc::Status status = stub_->DetectFood(Ctx().get(), request, &response);
    ASSERT_TRUE(status.ok()) << status.error_message();
    ASSERT_EQ(response.items_size(),
              static_cast<int>(scene_->plate.items.size()))
        << "encoding " << encoding;
    for (const sim::ItemTruth& t : scene_->rendered.truth) {
      double best = 0;
      for (const v1::FoodItem& item : response.items()) {
        const v1::BoundingBox& b = item.bbox();
        best =
            std::max(best, testing::BoxIoU(b.x(), b.y(), b.width(), b.height(),
                                           t.x, t.y, t.width, t.height));
      }
      EXPECT_GE(best, 0.7) << "encoding " << encoding;
    }
    for (const v1::FoodItem& item : response.items()) {
      EXPECT_GT(item.depth_m(), 0.3);
      EXPECT_LT(item.depth_m(), 0.35);
      EXPECT_DOUBLE_EQ(item.center_camera_m().z(), item.depth_m());
      EXPECT_GT(item.score(), 0.0);
    }
  }
}

TEST_F(PerceptionServiceTest, FeaturizeWithSpanetReturns2048Context) {
  StartWith(spanet_);
  const sim::ItemTruth& t = scene_->rendered.truth[0];
  v1::FeaturizeRequest request;
  *request.mutable_frame() = Frame();
  request.mutable_bbox()->set_x(t.x);
  request.mutable_bbox()->set_y(t.y);
  request.mutable_bbox()->set_width(t.width);
  request.mutable_bbox()->set_height(t.height);
  v1::FeaturizeResponse response;
  grpc::Status status = stub_->Featurize(Ctx().get(), request, &response);
  ASSERT_TRUE(status.ok()) << status.error_message();
  EXPECT_EQ(response.context_size(), 2048);
  EXPECT_EQ(response.skewer_points_size(), 2);
  EXPECT_EQ(response.action_scores_size(), 6);
  EXPECT_EQ(response.featurizer(), "spanet");
  // Same as calling the core directly: the adapter adds nothing.
  const DecodedFrame frame = testing::ToDecoded(scene_->rendered);
  auto direct = spanet_->Featurize(frame, {t.x, t.y, t.width, t.height},
                                   FoodLocation::kIsolated);
  ASSERT_TRUE(direct.ok());
  for (int i = 0; i < 2048; ++i) {
    ASSERT_FLOAT_EQ(static_cast<float>(response.context(i)),
                    static_cast<float>(direct->context[i]));
  }
}

TEST_F(PerceptionServiceTest, FeaturizeWithDefaultReturns64Context) {
  StartWith(&default_featurizer_);
  const sim::ItemTruth& t = scene_->rendered.truth[1];
  v1::FeaturizeRequest request;
  *request.mutable_frame() = Frame(v1::IMAGE_ENCODING_RGB8);
  request.mutable_bbox()->set_x(t.x);
  request.mutable_bbox()->set_y(t.y);
  request.mutable_bbox()->set_width(t.width);
  request.mutable_bbox()->set_height(t.height);
  request.set_location(v1::FOOD_LOCATION_WALL);
  v1::FeaturizeResponse response;
  grpc::Status status = stub_->Featurize(Ctx().get(), request, &response);
  ASSERT_TRUE(status.ok()) << status.error_message();
  EXPECT_EQ(response.context_size(), 64);
  EXPECT_EQ(response.context(61), 1.0);
  EXPECT_EQ(response.featurizer(), "default");
  EXPECT_EQ(response.action_scores_size(), 0);
  // It measures size and height from depth: a frame without is refused.
  request.mutable_frame()->clear_depth_mm();
  status = stub_->Featurize(Ctx().get(), request, &response);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(status.error_message(),
              HasSubstr("frame.depth_mm is empty: the default featurizer"));
}

TEST_F(PerceptionServiceTest, BadRequestsAreInvalidArgument) {
  StartWith(spanet_);
  auto featurize = [&](const v1::FeaturizeRequest& request) {
    v1::FeaturizeResponse response;
    return stub_->Featurize(Ctx().get(), request, &response);
  };
  auto expect_invalid = [](const grpc::Status& status,
                           const std::string& fragment) {
    EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_THAT(status.error_message(), HasSubstr(fragment));
  };
  v1::FeaturizeRequest good;
  *good.mutable_frame() = Frame();
  good.mutable_bbox()->set_x(100);
  good.mutable_bbox()->set_y(100);
  good.mutable_bbox()->set_width(50);
  good.mutable_bbox()->set_height(40);
  ASSERT_TRUE(featurize(good).ok());

  v1::FeaturizeRequest r = good;
  r.mutable_bbox()->set_x(620);
  expect_invalid(featurize(r), "lies outside the 640x480 frame");
  r = good;
  r.mutable_bbox()->set_height(0);
  expect_invalid(featurize(r), "empty crop");
  r = good;
  r.clear_bbox();
  expect_invalid(featurize(r), "bbox is required");
  r = good;
  r.clear_frame();
  expect_invalid(featurize(r), "frame is required");
  r = good;
  r.mutable_frame()->set_depth_mm(std::string(100, '\0'));
  expect_invalid(featurize(r), "frame.depth_mm has 100 bytes");
  r = good;
  r.mutable_frame()->mutable_rgb()->resize(200);
  expect_invalid(featurize(r), "corrupt IMAGE_ENCODING_PNG");
  r = good;
  r.set_location(static_cast<v1::FoodLocation>(17));
  expect_invalid(featurize(r), "location");

  v1::DetectFoodRequest detect;
  *detect.mutable_frame() = Frame(v1::IMAGE_ENCODING_JPEG);
  detect.mutable_frame()->mutable_rgb()->replace(2, 300, std::string(300, 'x'));
  v1::DetectFoodResponse response;
  expect_invalid(stub_->DetectFood(Ctx().get(), detect, &response),
                 "IMAGE_ENCODING_JPEG");
  detect.mutable_frame()->set_rgb(Frame(v1::IMAGE_ENCODING_JPEG).rgb());
  detect.mutable_frame()->clear_depth_mm();
  expect_invalid(stub_->DetectFood(Ctx().get(), detect, &response),
                 "frame.depth_mm is empty");
}

}  // namespace
}  // namespace bitewise::perception
