// The method table of the bitewise.v1 services, derived once from the
// generated service descriptors: every RPC's name ("BanditService/Select")
// and its access option (proto/bitewise/v1/access.proto: which roles may
// call it, whether anyone with a lab certificate may, whether it is
// audited). Handlers name their method through it (RpcMethod), and the
// authorization, the audit trail and the metrics read it, so no method name
// is typed anywhere else.
//
// Thread-safe: the table is built on first use and never changes.
#ifndef BITEWISE_SERVICES_COMMON_RPC_METHODS_H_
#define BITEWISE_SERVICES_COMMON_RPC_METHODS_H_

#include <map>
#include <string>

#include "absl/strings/string_view.h"

namespace bitewise {

struct RpcMethodInfo {
  std::string name;  // "Service/Method"
  bool robot = false;
  bool researcher = false;
  bool any_identity = false;
  bool audited = false;
};

// Every RPC of the bitewise.v1 services, keyed by "Service/Method".
const std::map<std::string, RpcMethodInfo>& RpcMethodTable();

// The entry of `service`'s `method` ("BanditService" or
// "bitewise.v1.BanditService", and "Select"). A name the descriptors do not
// have is a programming error: it aborts, naming it.
const RpcMethodInfo& RpcMethod(absl::string_view service,
                               absl::string_view method);

// The entry for "Service/Method", or null.
const RpcMethodInfo* FindRpcMethod(absl::string_view name);

}  // namespace bitewise

// In a handler of the generated service `Service` (v1::BanditService): the
// name of the RPC it handles, "BanditService/Select", from the table.
// __func__ is the handler's name, which is the RPC's: the generated base
// class declares one virtual function per RPC under the RPC's name.
#define BITEWISE_RPC_METHOD(Service) \
  ::bitewise::RpcMethod(Service::service_full_name(), __func__).name.c_str()

#endif  // BITEWISE_SERVICES_COMMON_RPC_METHODS_H_
