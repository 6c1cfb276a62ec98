// The method table derived from the service descriptors: every RPC is
// there with the access its .proto declares, the roles and the audit read
// it, and a name the descriptors do not have stops the program.
#include "services/common/rpc_methods.h"

#include <set>
#include <string>

#include "bitewise/v1/bandit.grpc.pb.h"
#include "bitewise/v1/robot.grpc.pb.h"
#include "gtest/gtest.h"
#include "services/common/authz.h"

namespace bitewise {
namespace {

TEST(RpcMethodsTest, EveryRpcOfEveryServiceIsInTheTable) {
  std::set<std::string> names;
  for (const auto& [name, info] : RpcMethodTable()) {
    EXPECT_EQ(name, info.name);
    names.insert(name);
  }
  // The five services' RPC counts, as their .proto files declare them.
  int per_service[5] = {0, 0, 0, 0, 0};
  const char* services[5] = {"BanditService/", "PerceptionService/",
                             "HapticService/", "RobotService/",
                             "CameraService/"};
  for (const std::string& name : names) {
    for (int s = 0; s < 5; ++s) {
      per_service[s] += name.rfind(services[s], 0) == 0;
    }
  }
  EXPECT_EQ(
      per_service[0],
      v1::SelectRequest::descriptor()->file()->service(0)->method_count());
  EXPECT_EQ(per_service[0], 14);
  EXPECT_EQ(per_service[1], 2);
  EXPECT_EQ(per_service[2], 1);
  EXPECT_EQ(per_service[3], 6);
  EXPECT_EQ(per_service[4], 1);
}

TEST(RpcMethodsTest, TheRolesAndTheAuditReadTheProtoOptions) {
  EXPECT_TRUE(RoleAllows(Role::kRobot, "BanditService/Select"));
  EXPECT_FALSE(RoleAllows(Role::kRobot, "BanditService/ListEvents"));
  EXPECT_FALSE(RoleAllows(Role::kRobot, "BanditService/Estimate"));
  EXPECT_TRUE(RoleAllows(Role::kResearcher, "BanditService/Estimate"));
  EXPECT_TRUE(RoleAllows(Role::kResearcher, "BanditService/ListEvents"));
  EXPECT_FALSE(RoleAllows(Role::kResearcher, "BanditService/Update"));
  EXPECT_FALSE(RoleAllows(Role::kResearcher, "RobotService/Acquire"));
  EXPECT_TRUE(RoleAllows(Role::kAdmin, "BanditService/DeleteUser"));
  EXPECT_FALSE(RoleAllows(Role::kRobot, "BanditService/DeleteUser"));
  // Unknown methods are the admin's only.
  EXPECT_FALSE(RoleAllows(Role::kRobot, "BanditService/NoSuchCall"));
  EXPECT_TRUE(OpenToEveryIdentity("RobotService/Stop"));
  EXPECT_FALSE(OpenToEveryIdentity("RobotService/Acquire"));
  EXPECT_TRUE(Audited("BanditService/CreateUser"));
  EXPECT_TRUE(Audited("RobotService/Tare"));
  EXPECT_TRUE(Audited("BanditService/SetLearner"));
  EXPECT_FALSE(RoleAllows(Role::kResearcher, "BanditService/SetLearner"));
  EXPECT_FALSE(Audited("BanditService/Select"));
}

TEST(RpcMethodsTest, HandlersNameTheirMethodFromTheDescriptor) {
  EXPECT_EQ(RpcMethod(v1::BanditService::service_full_name(), "Select").name,
            "BanditService/Select");
  EXPECT_EQ(RpcMethod("RobotService", "Stop").name, "RobotService/Stop");
  EXPECT_DEATH(RpcMethod("BanditService", "Selekt"),
               "BanditService/Selekt is not a method");
}

}  // namespace
}  // namespace bitewise
