// The roles file and its checks (services/common/authz.h), without a
// server: comments and blank lines are skipped, each role allows what the
// method table says, any one of a client's identities may grant, refusals
// name the client, role, method and peer, malformed files are refused
// naming the line, and a failed reload keeps the roles in force.
#include "services/common/authz.h"

#include <stdlib.h>
#include <unistd.h>

#include <fstream>
#include <memory>
#include <string>

#include "absl/strings/str_cat.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace bitewise {
namespace {

using ::testing::HasSubstr;

std::string WriteFile(const std::string& text) {
  std::string dir = absl::StrCat(::testing::TempDir(), "/authz_XXXXXX");
  EXPECT_NE(mkdtemp(dir.data()), nullptr);
  const std::string path = dir + "/roles.txt";
  std::ofstream(path) << text;
  return path;
}

constexpr char kRoles[] =
    "# lab roles\n"
    "robot-1 robot   # the arm's computer\n"
    "\n"
    "  \t\n"
    "alice\tresearcher\n"
    "bob researcher without_contexts\n"
    "carol admin\n";

constexpr char kPeer[] = "ipv4:10.0.0.7:5555";

TEST(AuthorizerTest, EachRoleAllowsWhatTheMethodTableSays) {
  const absl::StatusOr<std::unique_ptr<Authorizer>> authz =
      Authorizer::Load(WriteFile(kRoles));
  ASSERT_TRUE(authz.ok()) << authz.status();
  std::string role;
  bool withhold = true;
  EXPECT_TRUE(
      (*authz)
          ->Check("RobotService/Acquire", {"robot-1"}, kPeer, &role, &withhold)
          .ok());
  EXPECT_EQ(role, "robot");
  EXPECT_FALSE(withhold);
  EXPECT_TRUE((*authz)
                  ->Check("BanditService/ListEvents", {"alice"}, kPeer, &role,
                          &withhold)
                  .ok());
  EXPECT_EQ(role, "researcher");
  EXPECT_FALSE(withhold);
  EXPECT_TRUE(
      (*authz)
          ->Check("BanditService/ListEvents", {"bob"}, kPeer, &role, &withhold)
          .ok());
  EXPECT_EQ(role, "researcher");
  EXPECT_TRUE(withhold);  // without_contexts
  EXPECT_TRUE((*authz)
                  ->Check("BanditService/DeleteUser", {"carol"}, kPeer, &role)
                  .ok());
  EXPECT_EQ(role, "admin");

  const absl::Status denied =
      (*authz)->Check("BanditService/ListEvents", {"robot-1"}, kPeer, &role);
  EXPECT_EQ(denied.code(), absl::StatusCode::kPermissionDenied);
  EXPECT_THAT(denied.message(),
              HasSubstr(absl::StrCat("client \"robot-1\" from ", kPeer,
                                     " has role robot, which may not call "
                                     "BanditService/ListEvents")));
  EXPECT_EQ(
      (*authz)->Check("RobotService/Acquire", {"alice"}, kPeer, &role).code(),
      absl::StatusCode::kPermissionDenied);
}

TEST(AuthorizerTest, StrangersHaveNoRoleButAnyIdentityMayStopTheArm) {
  const std::string path = WriteFile(kRoles);
  const absl::StatusOr<std::unique_ptr<Authorizer>> authz =
      Authorizer::Load(path);
  ASSERT_TRUE(authz.ok()) << authz.status();
  std::string role;
  const absl::Status denied =
      (*authz)->Check("RobotService/GetStatus", {"mallory"}, kPeer, &role);
  EXPECT_EQ(denied.code(), absl::StatusCode::kPermissionDenied);
  EXPECT_THAT(denied.message(),
              HasSubstr(absl::StrCat("client \"mallory\" from ", kPeer,
                                     " has no role in \"", path,
                                     "\"; RobotService/GetStatus refused")));
  // Stop is open to every certificate identity, not to none.
  EXPECT_TRUE(
      (*authz)->Check("RobotService/Stop", {"mallory"}, kPeer, &role).ok());
  EXPECT_EQ(role, "any");
  const absl::Status anonymous =
      (*authz)->Check("RobotService/Stop", {}, kPeer, &role);
  EXPECT_EQ(anonymous.code(), absl::StatusCode::kPermissionDenied);
  EXPECT_THAT(anonymous.message(), HasSubstr("(no certificate identity)"));
}

TEST(AuthorizerTest, AnyOneOfTheClientsIdentitiesMayGrant) {
  const absl::StatusOr<std::unique_ptr<Authorizer>> authz =
      Authorizer::Load(WriteFile(kRoles));
  ASSERT_TRUE(authz.ok()) << authz.status();
  std::string role;
  // A stranger's name and a researcher's; a robot's that may not, then a
  // researcher's that may.
  EXPECT_TRUE((*authz)
                  ->Check("BanditService/ListEvents", {"mallory", "alice"},
                          kPeer, &role)
                  .ok());
  EXPECT_EQ(role, "researcher");
  EXPECT_TRUE((*authz)
                  ->Check("BanditService/ListEvents", {"robot-1", "alice"},
                          kPeer, &role)
                  .ok());
  EXPECT_EQ(role, "researcher");
  const absl::Status denied = (*authz)->Check(
      "BanditService/DeleteUser", {"robot-1", "alice"}, kPeer, &role);
  EXPECT_EQ(denied.code(), absl::StatusCode::kPermissionDenied);
  EXPECT_THAT(denied.message(), HasSubstr("client \"robot-1\", \"alice\""));
}

TEST(AuthorizerTest, MalformedFilesAreRefusedNamingTheLine) {
  struct Case {
    const char* text;
    const char* message;
  };
  for (const Case& c : {
           Case{"alice\n", "line 1: expected \"<identity> <role>\""},
           Case{"# x\nalice researcher extra words\n", "line 2: expected"},
           Case{"alice superuser\n",
                "line 1: unknown role \"superuser\" (robot, researcher or "
                "admin)"},
           Case{"alice admin without_contexts\n",
                "line 1: unknown option \"without_contexts\" for role admin"},
           Case{"alice researcher all_contexts\n",
                "line 1: unknown option \"all_contexts\""},
           Case{"alice robot\n\nalice admin\n",
                "line 3: identity \"alice\" listed twice"},
       }) {
    const std::string path = WriteFile(c.text);
    const absl::Status status = Authorizer::Load(path).status();
    EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument) << c.text;
    EXPECT_THAT(status.message(), HasSubstr(c.message)) << c.text;
    EXPECT_THAT(status.message(),
                HasSubstr(absl::StrCat("roles file \"", path, "\"")));
  }
  const std::string absent = WriteFile("") + ".absent";
  const absl::Status status = Authorizer::Load(absent).status();
  EXPECT_EQ(status.code(), absl::StatusCode::kNotFound);
  EXPECT_THAT(status.message(), HasSubstr(absent));
}

// A directory opens like a file but cannot be read: it is not an empty
// roles file (which would start a server that refuses everyone, saying
// only that each client has no role).
TEST(AuthorizerTest, ADirectoryIsNotReadAsAnEmptyRolesFile) {
  std::string dir = absl::StrCat(::testing::TempDir(), "/authz_dir_XXXXXX");
  ASSERT_NE(mkdtemp(dir.data()), nullptr);
  const absl::Status status = Authorizer::Load(dir).status();
  EXPECT_EQ(status.code(), absl::StatusCode::kNotFound);
  EXPECT_THAT(status.message(), HasSubstr(absl::StrCat("roles file \"", dir,
                                                       "\" cannot be read")));
}

TEST(AuthorizerTest, AReloadTakesTheNewRolesAndAFailedOneKeepsTheOld) {
  const std::string path = WriteFile("alice researcher\n");
  const absl::StatusOr<std::unique_ptr<Authorizer>> authz =
      Authorizer::Load(path);
  ASSERT_TRUE(authz.ok()) << authz.status();
  EXPECT_EQ((*authz)->path(), path);
  std::string role;
  std::ofstream(path, std::ios::trunc) << "alice admin\n";
  ASSERT_TRUE((*authz)->Reload().ok());
  EXPECT_TRUE((*authz)
                  ->Check("BanditService/DeleteUser", {"alice"}, kPeer, &role)
                  .ok());

  std::ofstream(path, std::ios::trunc) << "alice robot\nalice admin\n";
  EXPECT_EQ((*authz)->Reload().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_TRUE((*authz)
                  ->Check("BanditService/DeleteUser", {"alice"}, kPeer, &role)
                  .ok());
  EXPECT_EQ(role, "admin");

  unlink(path.c_str());
  EXPECT_EQ((*authz)->Reload().code(), absl::StatusCode::kNotFound);
  EXPECT_TRUE((*authz)
                  ->Check("BanditService/DeleteUser", {"alice"}, kPeer, &role)
                  .ok());
}

}  // namespace
}  // namespace bitewise
