#include "services/common/authz.h"

#include <fstream>
#include <utility>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "absl/strings/str_split.h"
#include "absl/strings/strip.h"
#include "services/common/rpc_methods.h"

namespace bitewise {
const char* RoleName(Role role) {
  switch (role) {
    case Role::kRobot:
      return "robot";
    case Role::kResearcher:
      return "researcher";
    case Role::kAdmin:
      return "admin";
  }
  return "?";
}

bool RoleAllows(Role role, const std::string& method) {
  const RpcMethodInfo* info = FindRpcMethod(method);
  switch (role) {
    case Role::kAdmin:
      return true;
    case Role::kRobot:
      return info != nullptr && info->robot;
    case Role::kResearcher:
      return info != nullptr && info->researcher;
  }
  return false;
}

bool OpenToEveryIdentity(const std::string& method) {
  const RpcMethodInfo* info = FindRpcMethod(method);
  return info != nullptr && info->any_identity;
}

bool Audited(const std::string& method) {
  const RpcMethodInfo* info = FindRpcMethod(method);
  return info != nullptr && info->audited;
}

absl::StatusOr<std::map<std::string, Authorizer::Grant>> Authorizer::Parse(
    const std::string& path) {
  std::ifstream in(path);
  if (!in) {
    return absl::NotFoundError(
        absl::StrCat("roles file \"", path, "\" cannot be read"));
  }
  std::map<std::string, Grant> roles;
  std::string line;
  for (int n = 1; std::getline(in, line); ++n) {
    absl::string_view text = line;
    if (const size_t hash = text.find('#'); hash != text.npos) {
      text = text.substr(0, hash);
    }
    const std::vector<std::string> words =
        absl::StrSplit(text, absl::ByAnyChar(" \t"), absl::SkipWhitespace());
    if (words.empty()) continue;
    const auto bad = [&](absl::string_view why) {
      return absl::InvalidArgumentError(
          absl::StrCat("roles file \"", path, "\" line ", n, ": ", why));
    };
    if (words.size() != 2 && words.size() != 3) {
      return bad(
          "expected \"<identity> <role>\" or \"<identity> researcher "
          "without_contexts\"");
    }
    Role role;
    if (words[1] == "robot") {
      role = Role::kRobot;
    } else if (words[1] == "researcher") {
      role = Role::kResearcher;
    } else if (words[1] == "admin") {
      role = Role::kAdmin;
    } else {
      return bad(absl::StrCat("unknown role \"", words[1],
                              "\" (robot, researcher or admin)"));
    }
    Grant grant{role, false};
    if (words.size() == 3) {
      if (role != Role::kResearcher || words[2] != "without_contexts") {
        return bad(absl::StrCat("unknown option \"", words[2], "\" for role ",
                                words[1],
                                " (only researcher takes without_contexts)"));
      }
      grant.withhold_contexts = true;
    }
    if (!roles.emplace(words[0], grant).second) {
      return bad(absl::StrCat("identity \"", words[0], "\" listed twice"));
    }
  }
  // A read error (a directory opens, then fails to read) is not an empty
  // file.
  if (in.bad()) {
    return absl::NotFoundError(
        absl::StrCat("roles file \"", path, "\" cannot be read"));
  }
  return roles;
}

absl::StatusOr<std::unique_ptr<Authorizer>> Authorizer::Load(
    const std::string& path) {
  auto roles = Parse(path);
  if (!roles.ok()) return roles.status();
  auto authorizer = std::unique_ptr<Authorizer>(new Authorizer(path));
  absl::MutexLock lock(&authorizer->mu_);
  authorizer->roles_ = *std::move(roles);
  return authorizer;
}

absl::Status Authorizer::Reload() {
  auto roles = Parse(path_);
  if (!roles.ok()) return roles.status();
  absl::MutexLock lock(&mu_);
  roles_ = *std::move(roles);
  return absl::OkStatus();
}

absl::Status Authorizer::Check(const std::string& method,
                               const std::vector<std::string>& identities,
                               const std::string& peer, std::string* role_out,
                               bool* withhold_contexts) const {
  if (withhold_contexts != nullptr) *withhold_contexts = false;
  const std::string who =
      identities.empty()
          ? std::string("(no certificate identity)")
          : absl::StrCat("\"", absl::StrJoin(identities, "\", \""), "\"");
  if (OpenToEveryIdentity(method) && !identities.empty()) {
    *role_out = "any";
    return absl::OkStatus();
  }
  absl::MutexLock lock(&mu_);
  const Role* found = nullptr;
  for (const std::string& identity : identities) {
    auto it = roles_.find(identity);
    if (it == roles_.end()) continue;
    if (RoleAllows(it->second.role, method)) {
      *role_out = RoleName(it->second.role);
      if (withhold_contexts != nullptr) {
        *withhold_contexts = it->second.withhold_contexts;
      }
      return absl::OkStatus();
    }
    found = &it->second.role;
  }
  if (found == nullptr) {
    return absl::PermissionDeniedError(
        absl::StrCat("client ", who, " from ", peer, " has no role in \"",
                     path_, "\"; ", method, " refused"));
  }
  return absl::PermissionDeniedError(
      absl::StrCat("client ", who, " from ", peer, " has role ",
                   RoleName(*found), ", which may not call ", method));
}

}  // namespace bitewise
