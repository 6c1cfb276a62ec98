// ConsoleServer: bitewise-console's HTTP(S) server (cpp-httplib, from
// Debian). It serves the bundled web app and the JSON API of docs/console.md
// over the MealHost (the meal at the table) and the research queries, and
// keeps who may do what:
//  - it binds 127.0.0.1 by default; any other address needs TLS and an
//    access file (Start refuses otherwise);
//  - with an access file every request needs HTTP Basic credentials from it
//    (401 and no data otherwise) and the role its endpoint needs (403);
//    STOP is open to every authenticated user;
//  - every POST must carry "X-Bitewise-Request: 1" and, when the browser
//    sends an Origin or Sec-Fetch-Site, come from the console's own origin
//    (403 otherwise), so another site cannot make a browser act here.
//
// Thread-safe; requests are served by a pool of threads.
#ifndef BITEWISE_CLIENTS_CONSOLE_CONSOLE_SERVER_H_
#define BITEWISE_CLIENTS_CONSOLE_CONSOLE_SERVER_H_

#include <grpcpp/channel.h>

#include <atomic>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "clients/console/access_list.h"
#include "clients/console/meal_host.h"
#include "clients/meal/service_clients.h"

namespace httplib {
class Server;
}

namespace bitewise::console {

struct ConsoleServerOptions {
  // Host (IPv4 or IPv6 literal, or "localhost") and port; port 0 picks one.
  std::string host = "127.0.0.1";
  int port = 8080;
  // PEM certificate chain and key: HTTPS. Both or neither.
  std::string tls_cert_file;
  std::string tls_key_file;
  // Credentials and roles (access_list.h); required off loopback.
  std::shared_ptr<const AccessList> access;
  // The services, for the health view: name, address, channel.
  struct Service {
    std::string name;
    std::string address;
    std::shared_ptr<grpc::Channel> channel;
  };
  std::vector<Service> services;
  // The BanditService client of the researcher's calls (people, events,
  // models), when the console has a second identity for them (the robot
  // role may not list people or events); null: the meal's client.
  meals::BanditClient* research_bandit = nullptr;
};

// True for 127.0.0.0/8, ::1 and "localhost".
bool IsLoopback(const std::string& host);

// Whether an HTTP Host header ("name", "name:port", "[v6]:port") names a
// loopback host (IsLoopback). Without an access file only such requests are
// answered: a page served by another name may have re-pointed that name at
// 127.0.0.1 (DNS rebinding).
bool HostIsLoopback(absl::string_view host_header);

class ConsoleServer {
 public:
  // Errors: FAILED_PRECONDITION off loopback without TLS or without an
  // access file, or when a TLS file cannot be loaded; INVALID_ARGUMENT for
  // only one of the two TLS files; UNAVAILABLE when the address cannot be
  // bound.
  static absl::StatusOr<std::unique_ptr<ConsoleServer>> Start(
      ConsoleServerOptions options, MealHost* host,
      meals::ServiceClients* clients);
  ~ConsoleServer();

  // Event streams (/api/meal/stream) open at once; more are refused (503),
  // so that watching pages cannot hold every request thread.
  static constexpr int kMaxEventStreams = 32;
  // Request threads: each open connection holds one, an event stream for as
  // long as its page watches, an idle keep-alive connection for up to 5 s.
  static constexpr int kRequestThreads = 256;

  int port() const { return port_; }
  // "http://127.0.0.1:8080/" or https.
  std::string url() const;
  // Stops accepting, ends the event streams, waits for the server thread.
  void Shutdown();

 private:
  ConsoleServer() = default;
  void Route();

  ConsoleServerOptions options_;
  MealHost* host_ = nullptr;
  meals::ServiceClients* clients_ = nullptr;
  meals::BanditClient* research_ = nullptr;
  std::unique_ptr<httplib::Server> server_;
  std::thread thread_;
  int port_ = 0;
  std::shared_ptr<std::atomic<int>> event_streams_ =
      std::make_shared<std::atomic<int>>(0);
};

}  // namespace bitewise::console

#endif  // BITEWISE_CLIENTS_CONSOLE_CONSOLE_SERVER_H_
