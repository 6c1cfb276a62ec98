// Prometheus metrics an operator can watch (Debian's prometheus-cpp). A
// Metrics object holds one process's metrics: each main makes one (inside
// its RpcEnvironment, rpc_environment.h) and ServiceServer serves it on a
// port of its own when --metrics_listen is set (off by default; on in
// deploy/). Every service exports, from RunRpc (RecordRpc):
//   bitewise_rpc_requests_total{method, code}     counter
//   bitewise_rpc_latency_seconds{method, code}    histogram
// and each main adds its own values read at scrape time (AddScrapeValues):
// the bandit's model cache, the robot's F/T stream and force-limit trips,
// and its own histograms (ObserveHistogram): the bandit store's commits.
// docs/operations.md lists them with the alert rules worth setting.
// Thread-safe.
#ifndef BITEWISE_SERVICES_COMMON_METRICS_H_
#define BITEWISE_SERVICES_COMMON_METRICS_H_

#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"

namespace prometheus {
class Exposer;
}  // namespace prometheus

namespace bitewise {

// One sample read at scrape time: labels and value.
struct ScrapeValue {
  std::map<std::string, std::string> labels;
  double value = 0.0;
};
enum class ScrapeType { kGauge, kCounter };

// The metric families of one process (or of one test), nothing shared
// with any other Metrics object.
class Metrics {
 public:
  Metrics();
  ~Metrics();
  Metrics(const Metrics&) = delete;
  Metrics& operator=(const Metrics&) = delete;

  // Counts one call of `method` ("Service/Method") ending with `code` after
  // `seconds`.
  void RecordRpc(const std::string& method, absl::StatusCode code,
                 double seconds);

  // Observes `value` in the unlabelled histogram `name`, made at its first
  // observation with `help` and the bucket upper bounds `bounds` (later
  // calls' help and bounds are not looked at).
  void ObserveHistogram(const std::string& name, const std::string& help,
                        const std::vector<double>& bounds, double value);

  // Adds a metric family whose samples `read` returns at every scrape (it
  // must stay callable while this object is served, and be thread-safe).
  void AddScrapeValues(const std::string& name, const std::string& help,
                       ScrapeType type,
                       std::function<std::vector<ScrapeValue>()> read);

 private:
  friend class MetricsServer;
  struct Families;
  const std::unique_ptr<Families> families_;
};

// The HTTP endpoint (/metrics) over one Metrics object.
class MetricsServer {
 public:
  // Serves `metrics` on `address` ("host:port"; port 0 picks one).
  // `metrics` should outlive the server (once it is gone, scrapes answer
  // without its families). UNAVAILABLE naming the address if it cannot
  // listen.
  static absl::StatusOr<std::unique_ptr<MetricsServer>> Start(
      const std::string& address, const Metrics& metrics);
  ~MetricsServer();
  int port() const { return port_; }

 private:
  MetricsServer(std::unique_ptr<prometheus::Exposer> exposer, int port);
  std::unique_ptr<prometheus::Exposer> exposer_;
  int port_;
};

}  // namespace bitewise

#endif  // BITEWISE_SERVICES_COMMON_METRICS_H_
