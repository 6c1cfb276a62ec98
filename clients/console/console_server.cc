#include "clients/console/console_server.h"

#include <arpa/inet.h>
#include <google/protobuf/util/json_util.h>
#include <httplib.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <sys/socket.h>

#include <cstdio>
#include <functional>
#include <memory>
#include <utility>

#include "absl/strings/ascii.h"
#include "absl/strings/escaping.h"
#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/strip.h"
#include "absl/time/clock.h"
#include "bitewise/console/v1/console.pb.h"
#include "clients/console/research.h"
#include "clients/console/web_assets.h"
#include "services/common/channel.h"
#include "services/common/status_macros.h"
#include "services/common/tls_files.h"
#include "services/domain/user_id.h"

namespace bitewise::console {
namespace {

namespace consolepb = ::bitewise::webapi::v1;

// Who may call an endpoint. kAny: every authenticated user.
enum class Need { kAny, kCaregiver, kResearcher };

int HttpStatus(const absl::Status& status) {
  switch (status.code()) {
    case absl::StatusCode::kOk:
      return 200;
    case absl::StatusCode::kInvalidArgument:
    case absl::StatusCode::kOutOfRange:
      return 400;
    case absl::StatusCode::kUnauthenticated:
      return 401;
    case absl::StatusCode::kPermissionDenied:
      return 403;
    case absl::StatusCode::kNotFound:
      return 404;
    case absl::StatusCode::kAlreadyExists:
    case absl::StatusCode::kFailedPrecondition:
    case absl::StatusCode::kAborted:
      return 409;
    case absl::StatusCode::kResourceExhausted:
      return 429;
    case absl::StatusCode::kUnavailable:
      return 503;
    case absl::StatusCode::kDeadlineExceeded:
      return 504;
    default:
      return 500;
  }
}

void Security(httplib::Response& res) {
  res.set_header("X-Content-Type-Options", "nosniff");
  res.set_header("X-Frame-Options", "DENY");
  res.set_header("Referrer-Policy", "no-referrer");
  res.set_header("Content-Security-Policy",
                 "default-src 'self'; img-src 'self' data:; style-src 'self' "
                 "'unsafe-inline'; connect-src 'self'; frame-ancestors "
                 "'none'; base-uri 'none'; form-action 'self'");
}

void Json(httplib::Response& res, const google::protobuf::Message& message,
          int status = 200) {
  res.status = status;
  res.set_header("Cache-Control", "no-store");
  res.set_content(ToJson(message), "application/json");
}

void Error(httplib::Response& res, const absl::Status& status) {
  consolepb::ErrorReply reply;
  reply.set_error(std::string(status.message()));
  Json(res, reply, HttpStatus(status));
}

// The request body into `message`; INVALID_ARGUMENT naming the problem.
absl::Status Parse(const httplib::Request& req,
                   google::protobuf::Message* message) {
  if (req.body.size() > 64 * 1024) {
    return absl::InvalidArgumentError("the request body is over 64 KiB");
  }
  google::protobuf::util::JsonParseOptions options;
  options.ignore_unknown_fields = false;
  const auto parsed = google::protobuf::util::JsonStringToMessage(
      req.body.empty() ? "{}" : req.body, message, options);
  if (!parsed.ok()) {
    return absl::InvalidArgumentError(
        absl::StrCat("the request body is not the expected JSON: ",
                     std::string(parsed.message())));
  }
  return absl::OkStatus();
}

bool Permits(Role role, Need need) {
  if (role == Role::kLocal || need == Need::kAny) return true;
  return need == Need::kCaregiver ? role == Role::kCaregiver
                                  : role == Role::kResearcher;
}

}  // namespace

bool IsLoopback(const std::string& host) {
  if (host == "localhost" || host == "::1" || host == "[::1]") return true;
  in_addr v4;
  if (inet_pton(AF_INET, host.c_str(), &v4) == 1) {
    return (ntohl(v4.s_addr) >> 24) == 127;
  }
  return false;
}

bool HostIsLoopback(absl::string_view host_header) {
  std::string host(host_header);
  if (absl::StartsWith(host, "[")) {
    host = host.substr(0, host.find(']') + 1);  // "[::1]:8080" -> "[::1]"
  } else if (const size_t colon = host.rfind(':'); colon != std::string::npos) {
    host = host.substr(0, colon);
  }
  return !host.empty() && IsLoopback(host);
}

absl::StatusOr<std::unique_ptr<ConsoleServer>> ConsoleServer::Start(
    ConsoleServerOptions options, MealHost* host,
    meals::ServiceClients* clients) {
  const bool tls = !options.tls_cert_file.empty();
  if (tls != !options.tls_key_file.empty()) {
    return absl::InvalidArgumentError(
        "--tls_cert and --tls_key go together: give both or neither");
  }
  if (!IsLoopback(options.host) && (!tls || options.access == nullptr)) {
    return absl::FailedPreconditionError(absl::StrCat(
        "listening on ", options.host,
        " (not loopback) needs HTTPS (--tls_cert, --tls_key) and an access "
        "file (--access_file): the console drives a robot arm"));
  }
  std::unique_ptr<ConsoleServer> server(new ConsoleServer());
  server->options_ = std::move(options);
  server->host_ = host;
  server->clients_ = clients;
  server->research_ = server->options_.research_bandit != nullptr
                          ? server->options_.research_bandit
                          : &clients->bandit;
  if (tls) {
    RETURN_IF_ERROR(bitewise::CheckPrivateKeyMode(server->options_.tls_key_file,
                                                  "HTTPS key"));
    auto ssl = std::make_unique<httplib::SSLServer>(
        server->options_.tls_cert_file.c_str(),
        server->options_.tls_key_file.c_str());
    if (!ssl->is_valid()) {
      return absl::FailedPreconditionError(absl::StrCat(
          "cannot load the TLS certificate ", server->options_.tls_cert_file,
          " and key ", server->options_.tls_key_file));
    }
    server->server_ = std::move(ssl);
  } else {
    server->server_ = std::make_unique<httplib::Server>();
  }
  // A STOP must find a free thread: event streams are capped
  // (kMaxEventStreams), so are password checks (AccessList), and the rest
  // are browsers' connections, a few per page.
  server->server_->new_task_queue = [] {
    return new httplib::ThreadPool(kRequestThreads);
  };
  // A page that vanishes without a reset (Wi-Fi gone) leaves its pings
  // unacknowledged: after 10 s the kernel gives up on the connection (not
  // after its default of about 15 minutes), the next ping fails, and the
  // stream's place and thread are freed. Accepted connections inherit it.
  server->server_->set_socket_options([](socket_t sock) {
    httplib::default_socket_options(sock);
    const unsigned int user_timeout_ms = 10000;
    setsockopt(sock, IPPROTO_TCP, TCP_USER_TIMEOUT, &user_timeout_ms,
               sizeof(user_timeout_ms));
  });
  server->server_->set_payload_max_length(64 * 1024);
  // Small replies (STOP's above all) go out at once, not after a delayed
  // ACK.
  server->server_->set_tcp_nodelay(true);
  server->Route();
  const std::string& bind_host = server->options_.host;
  if (server->options_.port == 0) {
    server->port_ = server->server_->bind_to_any_port(bind_host);
  } else if (server->server_->bind_to_port(bind_host, server->options_.port)) {
    server->port_ = server->options_.port;
  }
  if (server->port_ <= 0) {
    return absl::UnavailableError(absl::StrCat("cannot listen on ", bind_host,
                                               ":", server->options_.port));
  }
  httplib::Server* http = server->server_.get();
  server->thread_ = std::thread([http] { http->listen_after_bind(); });
  return server;
}

ConsoleServer::~ConsoleServer() { Shutdown(); }

std::string ConsoleServer::url() const {
  const std::string host = absl::StrContains(options_.host, ':')
                               ? absl::StrCat("[", options_.host, "]")
                               : options_.host;
  return absl::StrCat(options_.tls_cert_file.empty() ? "http" : "https", "://",
                      host, ":", port_, "/");
}

void ConsoleServer::Shutdown() {
  if (server_ == nullptr) return;
  host_->CloseSubscriptions();
  server_->stop();
  if (thread_.joinable()) thread_.join();
}

void ConsoleServer::Route() {
  httplib::Server& http = *server_;
  const AccessList* access = options_.access.get();
  const bool tls = !options_.tls_cert_file.empty();

  // The caller's role, or a reply already written (401).
  auto authenticate = [access](const httplib::Request& req,
                               httplib::Response& res) -> std::optional<Role> {
    if (access == nullptr) {
      // Every caller is `local` here, and a page from another site could be
      // one: its name re-pointed at 127.0.0.1 (DNS rebinding), its Origin
      // and the Host it sends agree. That Host names the site, not a
      // loopback address, so only loopback names are answered.
      if (!HostIsLoopback(req.get_header_value("Host"))) {
        Error(res, absl::PermissionDeniedError(absl::StrCat(
                       "without an access file the console answers only "
                       "requests addressed to localhost, 127.x.x.x or [::1] "
                       "(Host: \"",
                       req.get_header_value("Host").substr(0, 100), "\")")));
        return std::nullopt;
      }
      return Role::kLocal;
    }
    const std::string header = req.get_header_value("Authorization");
    std::string decoded;
    absl::string_view encoded = header;
    if (absl::ConsumePrefix(&encoded, "Basic ") &&
        absl::Base64Unescape(encoded, &decoded)) {
      const size_t colon = decoded.find(':');
      if (colon != std::string::npos) {
        absl::StatusOr<Role> role =
            access->Check(decoded.substr(0, colon), decoded.substr(colon + 1));
        if (role.ok()) return *role;
        if (!absl::IsUnauthenticated(role.status())) {  // 429: checks queued
          Error(res, role.status());
          return std::nullopt;
        }
      }
    }
    res.set_header("WWW-Authenticate",
                   "Basic realm=\"bitewise-console\", charset=\"UTF-8\"");
    Error(res, absl::UnauthenticatedError(
                   "credentials from the console's access file are needed"));
    return std::nullopt;
  };

  // A state-changing request must come from the console's own page.
  auto same_origin = [tls](const httplib::Request& req) -> absl::Status {
    if (req.get_header_value("X-Bitewise-Request") != "1") {
      return absl::PermissionDeniedError(
          "a state-changing request needs the header X-Bitewise-Request: 1");
    }
    const std::string site = req.get_header_value("Sec-Fetch-Site");
    if (!site.empty() && site != "same-origin" && site != "none") {
      return absl::PermissionDeniedError(absl::StrCat(
          "cross-site request refused (Sec-Fetch-Site: ", site, ")"));
    }
    const std::string origin = req.get_header_value("Origin");
    const std::string own = absl::StrCat(tls ? "https://" : "http://",
                                         req.get_header_value("Host"));
    if (!origin.empty() && origin != own) {
      return absl::PermissionDeniedError(
          absl::StrCat("cross-origin request refused (Origin ", origin, ")"));
    }
    return absl::OkStatus();
  };

  using Handler =
      std::function<void(const httplib::Request&, httplib::Response&, Role)>;
  auto guard = [authenticate, same_origin](Need need, bool mutates,
                                           Handler handler) {
    return [=](const httplib::Request& req, httplib::Response& res) {
      Security(res);
      const std::optional<Role> role = authenticate(req, res);
      if (!role.has_value()) return;
      if (!Permits(*role, need)) {
        Error(res, absl::PermissionDeniedError(absl::StrCat(
                       "the ", RoleName(*role), " role may not do this")));
        return;
      }
      if (mutates) {
        if (absl::Status ok = same_origin(req); !ok.ok()) {
          Error(res, ok);
          return;
        }
      }
      handler(req, res, *role);
    };
  };

  // A meal action's reply: its error, or the meal's state.
  auto reply_state = [this](httplib::Response& res, const absl::Status& done,
                            int status) {
    if (!done.ok()) return Error(res, done);
    Json(res, host_->State(), status);
  };

  http.Get("/api/session",
           guard(Need::kAny, false,
                 [access](const httplib::Request& req, httplib::Response& res,
                          Role role) {
                   consolepb::SessionReply reply;
                   reply.set_role(RoleName(role));
                   if (access != nullptr) {
                     std::string decoded;
                     absl::string_view h =
                         req.get_header_value("Authorization");
                     absl::ConsumePrefix(&h, "Basic ");
                     if (absl::Base64Unescape(h, &decoded)) {
                       reply.set_name(decoded.substr(0, decoded.find(':')));
                     }
                   }
                   Json(res, reply);
                 }));

  http.Get("/api/people",
           guard(Need::kAny, false,
                 [this](const httplib::Request&, httplib::Response& res, Role) {
                   absl::StatusOr<v1::ListUsersResponse> users =
                       AllUsers(*research_);
                   if (!users.ok()) return Error(res, users.status());
                   Json(res, *users);
                 }));

  http.Get("/api/meal",
           guard(Need::kAny, false,
                 [this](const httplib::Request&, httplib::Response& res, Role) {
                   Json(res, host_->State());
                 }));

  http.Get("/api/robot",
           guard(Need::kAny, false,
                 [this](const httplib::Request&, httplib::Response& res, Role) {
                   absl::StatusOr<v1::RobotStatus> status =
                       clients_->robot.GetStatus();
                   if (!status.ok()) return Error(res, status.status());
                   Json(res, *status);
                 }));

  http.Get("/api/meal/stream",
           guard(Need::kAny, false,
                 [this](const httplib::Request&, httplib::Response& res, Role) {
                   // Counts this stream until its reply is destroyed.
                   std::shared_ptr<void> ticket(
                       event_streams_.get(),
                       [streams = event_streams_](std::atomic<int>*) {
                         streams->fetch_sub(1);
                       });
                   if (event_streams_->fetch_add(1) >= kMaxEventStreams) {
                     return Error(
                         res, absl::UnavailableError(absl::StrCat(
                                  kMaxEventStreams,
                                  " pages already watch the meal; close one "
                                  "(each holds a connection to the console)")));
                   }
                   std::shared_ptr<Subscription> subscription =
                       host_->Subscribe();
                   res.set_header("Cache-Control", "no-store");
                   res.set_header("X-Accel-Buffering", "no");
                   res.set_chunked_content_provider(
                       "text/event-stream",
                       [subscription, ticket](size_t, httplib::DataSink& sink) {
                         if (subscription->closed()) return false;
                         std::optional<std::string> frame =
                             subscription->Next(absl::Seconds(2));
                         // A ping every 2 s keeps an idle stream open, tells
                         // the page it still hears the console (it says the
                         // connection is lost after 6 s without a word), and
                         // finds a page that has gone (its write fails),
                         // freeing its place.
                         const std::string data =
                             frame.has_value() ? *frame
                                               : "event: ping\ndata: {}\n\n";
                         if (subscription->closed() && !frame.has_value()) {
                           return false;
                         }
                         return sink.is_writable() &&
                                sink.write(data.data(), data.size());
                       },
                       [subscription](bool) { subscription->Close(); });
                 }));

  http.Get("/api/meal/plate.jpg",
           guard(Need::kAny, false,
                 [this](const httplib::Request&, httplib::Response& res, Role) {
                   absl::StatusOr<std::pair<int, std::string>> jpeg =
                       host_->PlateJpeg();
                   if (!jpeg.ok()) return Error(res, jpeg.status());
                   res.set_header("Cache-Control", "no-store");
                   res.set_header("X-Plate-Version",
                                  std::to_string(jpeg->first));
                   res.set_content(jpeg->second, "image/jpeg");
                 }));

  http.Post(
      "/api/meals",
      guard(Need::kCaregiver, true,
            [this](const httplib::Request& req, httplib::Response& res, Role) {
              consolepb::StartMealRequest request;
              if (absl::Status ok = Parse(req, &request); !ok.ok()) {
                return Error(res, ok);
              }
              absl::StatusOr<mealpb::MealState> state =
                  host_->StartMeal(request.user_id(), request.meal_id());
              if (!state.ok()) return Error(res, state.status());
              Json(res, *state, 201);
            }));

  http.Post("/api/meal/bite",
            guard(Need::kCaregiver, true,
                  [this, reply_state](const httplib::Request& req,
                                      httplib::Response& res, Role) {
                    consolepb::BiteRequest request;
                    if (absl::Status ok = Parse(req, &request); !ok.ok()) {
                      return Error(res, ok);
                    }
                    if (!request.has_item_index()) {
                      return Error(res, absl::InvalidArgumentError(
                                            "item_index: required (-1 for the "
                                            "robot's choice)"));
                    }
                    std::optional<int> item;
                    if (request.item_index() != -1) item = request.item_index();
                    std::optional<int> version;
                    if (request.has_plate_version()) {
                      version = request.plate_version();
                    }
                    reply_state(res, host_->Bite(item, version), 202);
                  }));

  http.Post("/api/meal/look",
            guard(Need::kCaregiver, true,
                  [this, reply_state](const httplib::Request&,
                                      httplib::Response& res, Role) {
                    reply_state(res, host_->Look(), 202);
                  }));

  http.Post("/api/meal/answer",
            guard(Need::kCaregiver, true,
                  [this, reply_state](const httplib::Request& req,
                                      httplib::Response& res, Role) {
                    consolepb::AnswerRequest request;
                    if (absl::Status ok = Parse(req, &request); !ok.ok()) {
                      return Error(res, ok);
                    }
                    if (!request.has_success()) {
                      return Error(res, absl::InvalidArgumentError(
                                            "success: required (true or "
                                            "false)"));
                    }
                    reply_state(
                        res,
                        host_->Answer(request.event_id(), request.success()),
                        200);
                  }));

  http.Post("/api/meal/end",
            guard(Need::kCaregiver, true,
                  [this, reply_state](const httplib::Request&,
                                      httplib::Response& res, Role) {
                    reply_state(res, host_->EndMeal(), 202);
                  }));

  // STOP: every authenticated user, and no body to parse.
  http.Post(
      "/api/stop",
      guard(Need::kAny, true,
            [this](const httplib::Request&, httplib::Response& res, Role) {
              const absl::Time start = absl::Now();
              absl::StatusOr<v1::StopResponse> stopped = host_->Stop();
              if (!stopped.ok()) return Error(res, stopped.status());
              consolepb::StopReply reply;
              reply.set_was_moving(stopped->was_moving());
              reply.set_reply_ms(
                  absl::ToDoubleMilliseconds(absl::Now() - start));
              Json(res, reply);
            }));

  http.Get(
      "/api/health",
      guard(Need::kResearcher, false,
            [this](const httplib::Request&, httplib::Response& res, Role) {
              consolepb::HealthReply reply;
              for (const auto& service : options_.services) {
                consolepb::ServiceHealth* health = reply.add_services();
                health->set_service(service.name);
                health->set_address(service.address);
                absl::StatusOr<ServingStatus> status = CheckHealth(
                    service.channel, service.name, absl::Seconds(2));
                if (status.ok()) {
                  health->set_status(ServingStatusName(*status));
                } else if (absl::IsNotFound(status.status())) {
                  // The server answered: it hosts no service of that name
                  // (an address pointing at another service).
                  health->set_status("SERVICE_UNKNOWN");
                  health->set_detail(std::string(status.status().message()));
                } else {
                  health->set_status("UNREACHABLE");
                  health->set_detail(std::string(status.status().message()));
                }
              }
              absl::StatusOr<v1::RobotStatus> robot =
                  clients_->robot.GetStatus();
              if (robot.ok()) {
                *reply.mutable_robot() = *robot;
              } else {
                reply.set_robot_error(std::string(robot.status().message()));
              }
              Json(res, reply);
            }));

  // /api/people/{user}/...: researcher routes; the user is checked as the
  // BanditService checks it.
  const std::string person = "/api/people/([^/]+)";
  using PersonHandler = std::function<void(
      const httplib::Request&, httplib::Response&, const std::string& user)>;
  auto person_route = [guard](PersonHandler handler) {
    return guard(
        Need::kResearcher, false,
        [handler](const httplib::Request& req, httplib::Response& res, Role) {
          const std::string user = req.matches[1];
          if (absl::Status ok = domain::ValidateUserId(user); !ok.ok()) {
            return Error(res, ok);
          }
          handler(req, res, user);
        });
  };
  auto flag = [](const httplib::Request& req, const char* name) {
    return req.has_param(name) && req.get_param_value(name) == "1";
  };

  http.Get(person + "/meals",
           person_route([this](const httplib::Request&, httplib::Response& res,
                               const std::string& user) {
             absl::StatusOr<std::vector<v1::Event>> events =
                 AllEvents(*research_, user, "", false, nullptr);
             if (!events.ok()) return Error(res, events.status());
             Json(res, MealsOf(user, *events));
           }));

  http.Get(
      person + "/events", person_route([this, flag](const httplib::Request& req,
                                                    httplib::Response& res,
                                                    const std::string& user) {
        v1::ListEventsRequest request;
        request.set_user_id(user);
        request.set_meal_id(req.get_param_value("meal_id"));
        request.set_page_token(req.get_param_value("page_token"));
        if (req.has_param("page_size")) {
          int size = 0;
          if (!absl::SimpleAtoi(req.get_param_value("page_size"), &size) ||
              size < 0 || size > 1000) {
            return Error(
                res, absl::InvalidArgumentError("page_size: expected 0-1000"));
          }
          request.set_page_size(size);
        }
        absl::StatusOr<v1::ListEventsResponse> page =
            research_->ListEvents(request);
        if (!page.ok()) return Error(res, page.status());
        if (!flag(req, "contexts")) {
          for (v1::Event& e : *page->mutable_events()) e.clear_context();
        }
        Json(res, *page);
      }));

  http.Get(
      person + "/events.csv",
      person_route([this, flag](const httplib::Request& req,
                                httplib::Response& res,
                                const std::string& user) {
        const std::string meal = req.get_param_value("meal_id");
        const bool contexts = flag(req, "contexts");
        absl::StatusOr<std::unique_ptr<EventsCsvStream>> started =
            EventsCsvStream::Start(*research_, user, meal, contexts);
        if (!started.ok()) return Error(res, started.status());
        std::shared_ptr<EventsCsvStream> stream = *std::move(started);
        res.set_header("Cache-Control", "no-store");
        if (stream->contexts_withheld()) {
          res.set_header("X-Bitewise-Contexts-Withheld", "true");
        }
        // The file's name from the ids, with anything but letters,
        // digits, '.', '_' and '-' (a quote would end the name) as '_'.
        std::string name =
            absl::StrCat(user, meal.empty() ? "" : "-", meal, "-events.csv");
        for (char& c : name) {
          if (!absl::ascii_isalnum(static_cast<unsigned char>(c)) && c != '.' &&
              c != '_' && c != '-') {
            c = '_';
          }
        }
        res.set_header("Content-Disposition",
                       absl::StrCat("attachment; filename=\"", name, "\""));
        // A page of events at a time (chunked): a long history is never
        // held whole. A page that fails later cuts the download off (the
        // browser reports it failed) and is logged.
        res.set_chunked_content_provider(
            "text/csv; charset=utf-8",
            [stream, user](size_t, httplib::DataSink& sink) {
              absl::StatusOr<std::string> piece = stream->Next();
              if (!piece.ok()) {
                std::fprintf(stderr,
                             "bitewise-console: events.csv of %s cut off: "
                             "%s\n",
                             user.c_str(), piece.status().ToString().c_str());
                return false;
              }
              if (piece->empty()) {
                sink.done();
                return true;
              }
              return sink.write(piece->data(), piece->size());
            });
      }));

  http.Get(person + "/model",
           person_route([this](const httplib::Request&, httplib::Response& res,
                               const std::string& user) {
             absl::StatusOr<v1::Model> model = research_->GetModel(user);
             if (!model.ok()) return Error(res, model.status());
             Json(res, *model);
           }));

  http.Get(
      person + "/estimates",
      person_route([this](const httplib::Request& req, httplib::Response& res,
                          const std::string& user) {
        absl::StatusOr<consolepb::EstimatesReply> reply =
            EstimatesFor(*research_, user, req.get_param_value("event_id"));
        if (!reply.ok()) return Error(res, reply.status());
        Json(res, *reply);
      }));

  // The web app itself; any other path is 404 (after authentication, so an
  // unauthenticated caller learns nothing).
  http.Get(".*",
           guard(Need::kAny, false,
                 [](const httplib::Request& req, httplib::Response& res, Role) {
                   const WebAsset* asset = FindWebAsset(req.path.c_str());
                   if (asset == nullptr) {
                     return Error(
                         res, absl::NotFoundError(absl::StrCat(
                                  "no such page: ", req.path.substr(0, 200))));
                   }
                   res.set_header(
                       "Cache-Control",
                       absl::StrCat(req.path == "/" ||
                                            absl::EndsWith(req.path, ".html")
                                        ? "no-cache"
                                        : "max-age=86400"));
                   res.set_content(reinterpret_cast<const char*>(asset->data),
                                   asset->size, asset->content_type);
                 }));
}

}  // namespace bitewise::console
