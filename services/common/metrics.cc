#include "services/common/metrics.h"

#include <prometheus/collectable.h>
#include <prometheus/counter.h>
#include <prometheus/exposer.h>
#include <prometheus/family.h>
#include <prometheus/histogram.h>
#include <prometheus/metric_family.h>
#include <prometheus/registry.h>

#include <exception>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "absl/base/thread_annotations.h"
#include "absl/strings/str_cat.h"
#include "absl/synchronization/mutex.h"

namespace bitewise {
namespace {

// Families whose samples are read at scrape time.
class ScrapeCollectable final : public prometheus::Collectable {
 public:
  void Add(std::string name, std::string help, ScrapeType type,
           std::function<std::vector<ScrapeValue>()> read) {
    absl::MutexLock lock(&mu_);
    families_.push_back(
        {std::move(name), std::move(help), type, std::move(read)});
  }

  std::vector<prometheus::MetricFamily> Collect() const override {
    absl::MutexLock lock(&mu_);
    std::vector<prometheus::MetricFamily> out;
    for (const Family& family : families_) {
      prometheus::MetricFamily metrics;
      metrics.name = family.name;
      metrics.help = family.help;
      metrics.type = family.type == ScrapeType::kGauge
                         ? prometheus::MetricType::Gauge
                         : prometheus::MetricType::Counter;
      for (const ScrapeValue& value : family.read()) {
        prometheus::ClientMetric metric;
        for (const auto& [name, label] : value.labels) {
          metric.label.push_back({name, label});
        }
        if (family.type == ScrapeType::kGauge) {
          metric.gauge.value = value.value;
        } else {
          metric.counter.value = value.value;
        }
        metrics.metric.push_back(std::move(metric));
      }
      out.push_back(std::move(metrics));
    }
    return out;
  }

 private:
  struct Family {
    std::string name;
    std::string help;
    ScrapeType type;
    std::function<std::vector<ScrapeValue>()> read;
  };
  mutable absl::Mutex mu_;
  std::vector<Family> families_ ABSL_GUARDED_BY(mu_);
};

}  // namespace

struct Metrics::Families {
  std::shared_ptr<prometheus::Registry> registry =
      std::make_shared<prometheus::Registry>();
  std::shared_ptr<ScrapeCollectable> scraped =
      std::make_shared<ScrapeCollectable>();
  prometheus::Family<prometheus::Counter>& requests =
      prometheus::BuildCounter()
          .Name("bitewise_rpc_requests_total")
          .Help("RPCs handled, by method and status code")
          .Register(*registry);
  prometheus::Family<prometheus::Histogram>& latency =
      prometheus::BuildHistogram()
          .Name("bitewise_rpc_latency_seconds")
          .Help(
              "RPC handling time (deadline checks to reply), by method "
              "and status code")
          .Register(*registry);
  const prometheus::Histogram::BucketBoundaries latency_buckets = {
      0.0005, 0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1,
      0.25,   0.5,   1,      2.5,   5,    10,    30,   60};
  // The histograms made by ObserveHistogram, by name.
  absl::Mutex histograms_mu;
  std::map<std::string, prometheus::Histogram*> histograms
      ABSL_GUARDED_BY(histograms_mu);
};

Metrics::Metrics() : families_(std::make_unique<Families>()) {}

Metrics::~Metrics() = default;

void Metrics::RecordRpc(const std::string& method, absl::StatusCode code,
                        double seconds) {
  const std::string code_name = absl::StatusCodeToString(code);
  families_->requests.Add({{"method", method}, {"code", code_name}})
      .Increment();
  families_->latency
      .Add({{"method", method}, {"code", code_name}},
           families_->latency_buckets)
      .Observe(seconds);
}

void Metrics::ObserveHistogram(const std::string& name, const std::string& help,
                               const std::vector<double>& bounds,
                               double value) {
  prometheus::Histogram* histogram = nullptr;
  {
    absl::MutexLock lock(&families_->histograms_mu);
    prometheus::Histogram*& found = families_->histograms[name];
    if (found == nullptr) {
      found = &prometheus::BuildHistogram()
                   .Name(name)
                   .Help(help)
                   .Register(*families_->registry)
                   .Add({}, prometheus::Histogram::BucketBoundaries(
                                bounds.begin(), bounds.end()));
    }
    histogram = found;
  }
  histogram->Observe(value);
}

void Metrics::AddScrapeValues(const std::string& name, const std::string& help,
                              ScrapeType type,
                              std::function<std::vector<ScrapeValue>()> read) {
  families_->scraped->Add(name, help, type, std::move(read));
}

absl::StatusOr<std::unique_ptr<MetricsServer>> MetricsServer::Start(
    const std::string& address, const Metrics& metrics) {
  std::unique_ptr<prometheus::Exposer> exposer;
  try {
    exposer = std::make_unique<prometheus::Exposer>(address);
  } catch (const std::exception& e) {
    return absl::UnavailableError(
        absl::StrCat("cannot serve metrics on ", address, ": ", e.what()));
  }
  exposer->RegisterCollectable(metrics.families_->registry);
  exposer->RegisterCollectable(metrics.families_->scraped);
  const std::vector<int> ports = exposer->GetListeningPorts();
  if (ports.empty()) {
    return absl::UnavailableError(
        absl::StrCat("cannot serve metrics on ", address, ": not listening"));
  }
  return std::unique_ptr<MetricsServer>(
      new MetricsServer(std::move(exposer), ports.front()));
}

MetricsServer::MetricsServer(std::unique_ptr<prometheus::Exposer> exposer,
                             int port)
    : exposer_(std::move(exposer)), port_(port) {}

MetricsServer::~MetricsServer() = default;

}  // namespace bitewise
