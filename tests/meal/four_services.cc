#include "tests/meal/four_services.h"

#include <grpcpp/create_channel.h>
#include <grpcpp/security/credentials.h>
#include <grpcpp/support/client_interceptor.h>
#include <stdlib.h>

#include <utility>

#include "absl/strings/str_cat.h"
#include "gtest/gtest.h"
#include "services/bandit/bandit_service.h"
#include "services/bandit/engine.h"
#include "services/bandit/store/sqlite_event_store.h"
#include "services/common/channel.h"
#include "services/common/grpc_status.h"
#include "services/common/rpc_environment.h"
#include "services/common/server.h"
#include "services/common/status_macros.h"
#include "services/haptic/core/haptic_classifier.h"
#include "services/haptic/default_model.h"
#include "services/haptic/haptic_service.h"
#include "services/perception/default_featurizer.h"
#include "services/perception/food_detector.h"
#include "services/perception/perception_service.h"
#include "services/robot/backend.h"
#include "services/robot/robot_service.h"

namespace bitewise::testing {
namespace {

namespace gx = ::grpc::experimental;

// Answers the injected status for a faulty method without sending anything
// (gRPC's hijacking interceptor): the call never reaches its server.
class FaultInterceptor : public gx::Interceptor {
 public:
  FaultInterceptor(gx::ClientRpcInfo* info, const FaultInjector* faults)
      : fault_(faults->For(info->method())) {}

  void Intercept(gx::InterceptorBatchMethods* methods) override {
    if (fault_.ok()) {
      methods->Proceed();
      return;
    }
    bool hijack = false;
    if (methods->QueryInterceptionHookPoint(
            gx::InterceptionHookPoints::PRE_SEND_INITIAL_METADATA)) {
      hijack = true;
    }
    if (methods->QueryInterceptionHookPoint(
            gx::InterceptionHookPoints::PRE_RECV_MESSAGE)) {
      methods->FailHijackedRecvMessage();
    }
    if (methods->QueryInterceptionHookPoint(
            gx::InterceptionHookPoints::PRE_RECV_STATUS)) {
      *methods->GetRecvStatus() = ToGrpcStatus(fault_);
    }
    if (hijack) {
      methods->Hijack();
    } else {
      methods->Proceed();
    }
  }

 private:
  const absl::Status fault_;
};

class FaultInterceptorFactory : public gx::ClientInterceptorFactoryInterface {
 public:
  explicit FaultInterceptorFactory(const FaultInjector* faults)
      : faults_(faults) {}
  gx::Interceptor* CreateClientInterceptor(gx::ClientRpcInfo* info) override {
    return new FaultInterceptor(info, faults_);
  }

 private:
  const FaultInjector* faults_;
};

std::shared_ptr<grpc::Channel> FaultyChannel(const std::string& address,
                                             const FaultInjector* faults) {
  grpc::ChannelArguments args;
  args.SetMaxReceiveMessageSize(64 << 20);
  args.SetMaxSendMessageSize(64 << 20);
  std::vector<std::unique_ptr<gx::ClientInterceptorFactoryInterface>> factories;
  factories.push_back(std::make_unique<FaultInterceptorFactory>(faults));
  return gx::CreateCustomChannelWithInterceptors(
      address, grpc::InsecureChannelCredentials(), args, std::move(factories));
}

// One service on its own server, reported SERVING.
absl::StatusOr<std::unique_ptr<ServiceServer>> Serve(RpcEnvironment* env,
                                                     grpc::Service* service,
                                                     const char* name) {
  ServerOptions options;
  options.max_message_bytes = 64 << 20;
  options.drain_timeout = absl::Seconds(2);
  ASSIGN_OR_RETURN(std::unique_ptr<ServiceServer> server,
                   ServiceServer::Start(options, env, {service}, {name}));
  server->SetServing(true);
  return server;
}

}  // namespace

void FaultInjector::Fail(const std::string& method, absl::Status status) {
  absl::MutexLock lock(&mu_);
  faults_.emplace_back(method, std::move(status));
}

void FaultInjector::Clear() {
  absl::MutexLock lock(&mu_);
  faults_.clear();
}

absl::Status FaultInjector::For(const std::string& method) const {
  absl::MutexLock lock(&mu_);
  for (const auto& [name, status] : faults_) {
    if (name == method) return status;
  }
  return absl::OkStatus();
}

struct FourServices::Impl {
  // One environment per service, as each runs in a binary of its own.
  RpcEnvironment bandit_env;
  RpcEnvironment perception_env;
  RpcEnvironment haptic_env;
  RpcEnvironment robot_env;
  std::unique_ptr<bandit::SqliteEventStore> store;
  std::unique_ptr<bandit::BanditEngine> engine;
  std::unique_ptr<bandit::BanditServiceImpl> bandit_service;
  perception::FoodDetector detector;
  perception::DefaultFeaturizer featurizer;
  std::unique_ptr<perception::PerceptionServiceImpl> perception_service;
  std::unique_ptr<haptic::HapticClassifier> classifier;
  std::unique_ptr<haptic::HapticServiceImpl> haptic_service;
  std::unique_ptr<robot::RobotBackend> backend;
  std::unique_ptr<robot::RobotServiceImpl> robot_service;
  std::unique_ptr<ServiceServer> bandit_server;
  std::unique_ptr<ServiceServer> perception_server;
  std::unique_ptr<ServiceServer> haptic_server;
  std::unique_ptr<ServiceServer> robot_server;
};

FourServices::FourServices(std::unique_ptr<Impl> impl)
    : impl_(std::move(impl)) {}

FourServices::~FourServices() {
  for (ServiceServer* server :
       {impl_->robot_server.get(), impl_->haptic_server.get(),
        impl_->perception_server.get(), impl_->bandit_server.get()}) {
    if (server != nullptr) server->Shutdown();
  }
}

int FourServices::ItemsLeft() const { return impl_->backend->items_left(); }

absl::StatusOr<std::unique_ptr<FourServices>> FourServices::Start(
    const FourServicesOptions& options) {
  auto impl = std::make_unique<Impl>();
  std::string dir = ::testing::TempDir() + "/meal_XXXXXX";
  if (mkdtemp(dir.data()) == nullptr) {
    return absl::InternalError("cannot make a temporary directory");
  }

  bandit::SqliteStoreOptions store_options;
  store_options.path = dir + "/bandit.db";
  store_options.synchronous_full = false;
  ASSIGN_OR_RETURN(impl->store, bandit::SqliteEventStore::Open(store_options));
  impl->engine = std::make_unique<bandit::BanditEngine>(
      impl->store.get(), bandit::EngineOptions());
  impl->bandit_service = std::make_unique<bandit::BanditServiceImpl>(
      &impl->bandit_env, impl->engine.get(), bandit::BanditConfig());
  ASSIGN_OR_RETURN(impl->bandit_server,
                   Serve(&impl->bandit_env, impl->bandit_service.get(),
                         "bitewise.v1.BanditService"));

  impl->perception_service =
      std::make_unique<perception::PerceptionServiceImpl>(
          &impl->perception_env, &impl->detector, &impl->featurizer);
  ASSIGN_OR_RETURN(impl->perception_server,
                   Serve(&impl->perception_env, impl->perception_service.get(),
                         "bitewise.v1.PerceptionService"));

  ASSIGN_OR_RETURN(
      std::unique_ptr<haptic::HapticNet> net,
      haptic::HapticNet::FromOnnxBytes(haptic::DefaultHapticNetOnnx(),
                                       haptic::kDefaultHapticNetSource));
  std::unique_ptr<haptic::FamiliarityModel> familiarity;
  if (options.familiarity_threshold >= 0.0) {
    // The shipped model with the threshold line replaced.
    std::string text(haptic::DefaultHapticFamiliarity());
    const size_t at = text.find("\nthreshold ");
    const size_t end = text.find('\n', at + 1);
    text.replace(at + 1, end - at - 1,
                 absl::StrCat("threshold ", options.familiarity_threshold));
    ASSIGN_OR_RETURN(haptic::FamiliarityModel model,
                     haptic::FamiliarityModel::FromText(text, "test"));
    familiarity = std::make_unique<haptic::FamiliarityModel>(std::move(model));
  }
  impl->classifier = std::make_unique<haptic::HapticClassifier>(
      std::move(net), haptic::HapticPipelineOptions(), std::move(familiarity));
  impl->haptic_service = std::make_unique<haptic::HapticServiceImpl>(
      &impl->haptic_env, impl->classifier.get());
  ASSIGN_OR_RETURN(impl->haptic_server,
                   Serve(&impl->haptic_env, impl->haptic_service.get(),
                         haptic::kHapticServiceName));

  robot::RobotBackendOptions robot_options;
  robot_options.sim.seed = options.seed;
  robot_options.sim.foods = options.foods;
  robot::AcquisitionConfig& acquisition = robot_options.acquisition;
  acquisition.approach_speed_mps *= options.transit_speedup;
  acquisition.orient_rate_radps *= options.transit_speedup;
  acquisition.extract_speed_mps *= options.transit_speedup;
  ASSIGN_OR_RETURN(impl->backend, robot::RobotBackend::Create(robot_options));
  impl->robot_service = std::make_unique<robot::RobotServiceImpl>(
      &impl->robot_env, impl->backend.get());
  ASSIGN_OR_RETURN(impl->robot_server,
                   Serve(&impl->robot_env, impl->robot_service.get(),
                         "bitewise.v1.RobotService"));

  std::unique_ptr<FourServices> services(new FourServices(std::move(impl)));
  services->dir_ = dir;
  const FaultInjector* faults = &services->faults_;
  services->channels_.bandit =
      FaultyChannel(services->bandit_address(), faults);
  services->channels_.perception =
      FaultyChannel(services->perception_address(), faults);
  services->channels_.haptic =
      FaultyChannel(services->haptic_address(), faults);
  services->channels_.robot = FaultyChannel(services->robot_address(), faults);
  return services;
}

std::string FourServices::bandit_address() const {
  return impl_->bandit_server->address();
}
std::string FourServices::perception_address() const {
  return impl_->perception_server->address();
}
std::string FourServices::haptic_address() const {
  return impl_->haptic_server->address();
}
std::string FourServices::robot_address() const {
  return impl_->robot_server->address();
}

}  // namespace bitewise::testing
