// Authorization: who may call what. With mutual TLS each client presents a
// certificate of the lab's CA; its identities (subject CN and SAN entries)
// map to one role in a roles file the service reads at start and again on
// SIGHUP:
//
//   # identity        role
//   robot-computer    robot
//   lab-laptop        researcher
//   ops               admin
//
// Which roles may call each RPC is an option on the rpc in its .proto
// (proto/bitewise/v1/access.proto), read through the method table
// (rpc_methods.h):
//   robot: the meal's calls (Select, Update, CreateUser, GetUser, GetModel,
//     DetectFood, Featurize, Classify, Acquire, CaptureFrame, Tare,
//     GetStatus, ListActions, GetFrame);
//   researcher: read only (GetUser, ListUsers, GetModel, Estimate, ListEvents,
//     and the stateless DetectFood, Featurize, Classify, GetStatus,
//     ListActions);
//   admin: everything, including ResetUser, SetLearner, DeleteUser,
//     BuildPopulationPrior.
// RobotService/Stop stays callable by every client with a valid lab
// certificate, role or not: anyone must be able to stop the arm.
//
// Before every handler RunRpc (rpc_handler.h) consults the Authorizer that
// ServiceServer loads from its options and installs in the services'
// RpcEnvironment (rpc_environment.h); a refused call is PERMISSION_DENIED
// naming the identity, the role and the method, and nothing runs.
// Administrative and destructive calls (CreateUser, ResetUser, SetLearner,
// DeleteUser,
// BuildPopulationPrior, Tare) are written to the audit trail (audit.h: stderr,
// and the BanditService's store).
//
// Thread-safe.
#ifndef BITEWISE_SERVICES_COMMON_AUTHZ_H_
#define BITEWISE_SERVICES_COMMON_AUTHZ_H_

#include <map>
#include <memory>
#include <string>
#include <vector>

#include "absl/base/thread_annotations.h"
#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/synchronization/mutex.h"

namespace bitewise {

enum class Role { kRobot, kResearcher, kAdmin };
const char* RoleName(Role role);

// Whether `role` may call `method` ("Service/Method"). Unknown methods are
// admin-only.
bool RoleAllows(Role role, const std::string& method);
// Methods any authenticated client may call (RobotService/Stop).
bool OpenToEveryIdentity(const std::string& method);
// Methods whose calls are written to the audit log.
bool Audited(const std::string& method);

class Authorizer {
 public:
  // Reads the roles file: "<identity> <role>" per line, or "<identity>
  // researcher without_contexts". INVALID_ARGUMENT naming the line of a
  // malformed entry or an unknown role; NOT_FOUND when the file cannot be
  // read.
  static absl::StatusOr<std::unique_ptr<Authorizer>> Load(
      const std::string& path);

  // Reads the file again; on error keeps the roles it had.
  absl::Status Reload();

  // OK when one of `identities` has a role that allows `method`; else
  // PERMISSION_DENIED naming the identities, the role (if any), the method
  // and the peer. `withhold_contexts`, if given, says whether that grant is
  // "researcher without_contexts" (events without their raw context and
  // post hoc vectors).
  absl::Status Check(const std::string& method,
                     const std::vector<std::string>& identities,
                     const std::string& peer, std::string* role_out,
                     bool* withhold_contexts = nullptr) const;

  const std::string& path() const { return path_; }

 private:
  struct Grant {
    Role role;
    bool withhold_contexts;
  };
  explicit Authorizer(std::string path) : path_(std::move(path)) {}
  static absl::StatusOr<std::map<std::string, Grant>> Parse(
      const std::string& path);

  const std::string path_;
  mutable absl::Mutex mu_;
  std::map<std::string, Grant> roles_ ABSL_GUARDED_BY(mu_);
};

}  // namespace bitewise

#endif  // BITEWISE_SERVICES_COMMON_AUTHZ_H_
