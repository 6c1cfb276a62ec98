#include "services/common/rpc_methods.h"

#include <cstdio>
#include <cstdlib>
#include <utility>

#include "absl/strings/str_cat.h"
#include "bitewise/v1/access.pb.h"
#include "bitewise/v1/bandit.grpc.pb.h"
#include "bitewise/v1/camera.grpc.pb.h"
#include "bitewise/v1/haptic.grpc.pb.h"
#include "bitewise/v1/perception.grpc.pb.h"
#include "bitewise/v1/robot.grpc.pb.h"
#include "google/protobuf/descriptor.h"

namespace bitewise {
namespace {

std::map<std::string, RpcMethodInfo> BuildTable() {
  std::map<std::string, RpcMethodInfo> table;
  // Each service through a message of its own .proto file, so that the
  // file's descriptors are linked in (and registered) wherever this is.
  const std::pair<const google::protobuf::FileDescriptor*, const char*>
      services[] = {
          {v1::SelectRequest::descriptor()->file(),
           v1::BanditService::service_full_name()},
          {v1::DetectFoodRequest::descriptor()->file(),
           v1::PerceptionService::service_full_name()},
          {v1::ClassifyRequest::descriptor()->file(),
           v1::HapticService::service_full_name()},
          {v1::AcquireRequest::descriptor()->file(),
           v1::RobotService::service_full_name()},
          {v1::GetFrameRequest::descriptor()->file(),
           v1::CameraService::service_full_name()},
      };
  for (const auto& [file, full_name] : services) {
    absl::string_view name = full_name;
    name.remove_prefix(name.rfind('.') + 1);
    const google::protobuf::ServiceDescriptor* service =
        file->FindServiceByName(std::string(name));
    if (service == nullptr) {
      std::fprintf(stderr, "no descriptor for service %s\n", full_name);
      std::abort();
    }
    for (int i = 0; i < service->method_count(); ++i) {
      const google::protobuf::MethodDescriptor* method = service->method(i);
      const v1::RpcAccess& access = method->options().GetExtension(v1::access);
      RpcMethodInfo info;
      info.name = absl::StrCat(service->name(), "/", method->name());
      info.robot = access.robot();
      info.researcher = access.researcher();
      info.any_identity = access.any_identity();
      info.audited = access.audited();
      table.emplace(info.name, info);
    }
  }
  return table;
}

}  // namespace

const std::map<std::string, RpcMethodInfo>& RpcMethodTable() {
  static const auto* const table =
      new std::map<std::string, RpcMethodInfo>(BuildTable());
  return *table;
}

const RpcMethodInfo* FindRpcMethod(absl::string_view name) {
  const auto& table = RpcMethodTable();
  const auto it = table.find(std::string(name));
  return it == table.end() ? nullptr : &it->second;
}

const RpcMethodInfo& RpcMethod(absl::string_view service,
                               absl::string_view method) {
  // "bitewise.v1.BanditService" -> "BanditService".
  if (const size_t dot = service.rfind('.'); dot != absl::string_view::npos) {
    service.remove_prefix(dot + 1);
  }
  const RpcMethodInfo* info = FindRpcMethod(absl::StrCat(service, "/", method));
  if (info == nullptr) {
    std::fprintf(stderr,
                 "%s/%s is not a method of the bitewise.v1 service "
                 "descriptors\n",
                 std::string(service).c_str(), std::string(method).c_str());
    std::abort();
  }
  return *info;
}

}  // namespace bitewise
