// In-process tests of the HapticService: the shipped model behind a real
// gRPC server on a loopback port, called through a stub.
#include "services/haptic/haptic_service.h"

#include <chrono>
#include <limits>
#include <memory>
#include <random>

#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "services/common/channel.h"
#include "services/common/server.h"
#include "services/haptic/converters.h"
#include "services/haptic/default_model.h"
#include "tests/haptic/haptic_test_traces.h"

namespace bitewise::haptic {
namespace {

using ::testing::HasSubstr;

class HapticServiceTest : public ::testing::Test {
 protected:
  void SetUp() override {
    auto net = HapticNet::FromOnnxBytes(DefaultHapticNetOnnx(),
                                        kDefaultHapticNetSource);
    ASSERT_TRUE(net.ok()) << net.status();
    classifier_ = std::make_unique<HapticClassifier>(std::move(net).value(),
                                                     HapticPipelineOptions());
    service_ = std::make_unique<HapticServiceImpl>(&env_, classifier_.get());
    auto server = ServiceServer::Start(ServerOptions(), &env_, {service_.get()},
                                       {kHapticServiceName});
    ASSERT_TRUE(server.ok()) << server.status();
    server_ = std::move(server).value();
    server_->SetServing(true);
    auto channel = MakeChannel(server_->address(), ChannelOptions());
    ASSERT_TRUE(channel.ok());
    ASSERT_TRUE(
        WaitForServing(*channel, kHapticServiceName, absl::Seconds(10)).ok());
    stub_ = v1::HapticService::NewStub(*channel);
  }

  void TearDown() override {
    if (server_) server_->Shutdown();
  }

  grpc::Status Classify(const v1::ClassifyRequest& request,
                        v1::ClassifyResponse* response) {
    grpc::ClientContext context;
    context.set_deadline(std::chrono::system_clock::now() +
                         std::chrono::seconds(10));
    return stub_->Classify(&context, request, response);
  }

  RpcEnvironment env_;
  std::unique_ptr<HapticClassifier> classifier_;
  std::unique_ptr<HapticServiceImpl> service_;
  std::unique_ptr<ServiceServer> server_;
  std::unique_ptr<v1::HapticService::Stub> stub_;
};

TEST_F(HapticServiceTest, ClassifiesOverTheWireAsInProcess) {
  std::mt19937_64 rng(5);
  for (int k = 0; k < kHapticClasses; ++k) {
    const auto trace = SimulatedTrace(static_cast<HapticClass>(k), rng);
    v1::ClassifyRequest request;
    TraceToProto(trace, &request);
    v1::ClassifyResponse response;
    grpc::Status status = Classify(request, &response);
    ASSERT_TRUE(status.ok()) << status.error_message();
    auto direct = classifier_->Classify(trace);
    ASSERT_TRUE(direct.ok());
    ASSERT_EQ(response.probabilities_size(), kHapticClasses);
    ASSERT_EQ(response.log_probabilities_size(), kHapticClasses);
    for (int j = 0; j < kHapticClasses; ++j) {
      EXPECT_EQ(response.probabilities(j), direct->probabilities[j]);
      EXPECT_EQ(response.log_probabilities(j), direct->log_probabilities[j]);
    }
    EXPECT_EQ(response.category(), CategoryToProto(static_cast<HapticClass>(k)))
        << HapticClassName(static_cast<HapticClass>(k));
    EXPECT_NEAR(response.contact_time_s(), 0.3, 0.015);
    EXPECT_GT(response.peak_force_n(), 1.0);
    EXPECT_EQ(response.model_fingerprint(), classifier_->net().fingerprint());
  }
}

TEST_F(HapticServiceTest, EmptyRequestIsInvalidArgument) {
  v1::ClassifyResponse response;
  grpc::Status status = Classify(v1::ClassifyRequest(), &response);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(status.error_message(), HasSubstr("0 samples"));
}

TEST_F(HapticServiceTest, BadSamplesAreInvalidArgumentNamingTheSample) {
  std::mt19937_64 rng(6);
  const auto trace = SimulatedTrace(HapticClass::kMedium, rng);
  v1::ClassifyRequest request;
  TraceToProto(trace, &request);
  v1::ClassifyResponse response;

  v1::ClassifyRequest nan = request;
  nan.mutable_samples(12)->set_fz_n(std::numeric_limits<double>::quiet_NaN());
  grpc::Status status = Classify(nan, &response);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(status.error_message(), HasSubstr("samples[12].fz_n"));

  v1::ClassifyRequest backwards = request;
  backwards.mutable_samples(200)->set_t_s(0.0);
  status = Classify(backwards, &response);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(status.error_message(), HasSubstr("samples[200].t_s"));
}

TEST_F(HapticServiceTest, NoContactIsFailedPreconditionWithPeakForce) {
  v1::ClassifyRequest request;
  for (int i = 0; i < 300; ++i) {
    v1::WrenchSample* s = request.add_samples();
    s->set_t_s(0.001 * i);
    s->set_fz_n(i == 150 ? 2.5 : 0.7);  // one 1.8 N spike on a 0.7 N offset
  }
  v1::ClassifyResponse response;
  grpc::Status status = Classify(request, &response);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::FAILED_PRECONDITION);
  EXPECT_THAT(status.error_message(), HasSubstr("peak force 1.800 N"));
}

}  // namespace
}  // namespace bitewise::haptic
