// HapticService latency: Classify on a 1 s trace at 1 kHz with the shipped
// model, in-process (target < 1 ms) and over loopback gRPC, plus its
// stages, so a regression points at the stage that caused it.
#include <chrono>
#include <cmath>
#include <memory>
#include <random>
#include <vector>

#include "benchmark/benchmark.h"
#include "bitewise/v1/haptic.grpc.pb.h"
#include "services/common/channel.h"
#include "services/common/server.h"
#include "services/haptic/converters.h"
#include "services/haptic/core/contact_detector.h"
#include "services/haptic/core/familiarity.h"
#include "services/haptic/core/haptic_classifier.h"
#include "services/haptic/default_model.h"
#include "services/haptic/haptic_service.h"
#include "services/haptic/training/haptic_net_weights.h"
#include "services/haptic/training/labelled_traces.h"
#include "tests/haptic/haptic_test_traces.h"

namespace bitewise::haptic {
namespace {

// One second at `rate_hz` of a hard-skin item (the shape with the most
// structure), contact at 0.4 s.
std::vector<TimedWrench> OneSecondTrace(double rate_hz) {
  SimulationConditions conditions;
  conditions.min_rate_hz = conditions.max_rate_hz = rate_hz;
  conditions.min_contact_s = conditions.max_contact_s = 0.4;
  conditions.after_contact_s = 0.6;
  return SimulateLabelledTraces(1, conditions, 42)[3].samples;
}

std::unique_ptr<HapticClassifier> DefaultClassifier() {
  auto net =
      HapticNet::FromOnnxBytes(DefaultHapticNetOnnx(), kDefaultHapticNetSource);
  if (!net.ok()) std::abort();
  return std::make_unique<HapticClassifier>(std::move(net).value(),
                                            HapticPipelineOptions());
}

void BM_Classify(benchmark::State& state) {
  const auto trace = OneSecondTrace(static_cast<double>(state.range(0)));
  const auto classifier = DefaultClassifier();
  for (auto _ : state) {
    auto result = classifier->Classify(trace);
    if (!result.ok()) state.SkipWithError("classify failed");
    benchmark::DoNotOptimize(result);
  }
  state.counters["samples"] = static_cast<double>(trace.size());
}
BENCHMARK(BM_Classify)
    ->ArgName("rate_hz")
    ->Arg(1000)
    ->Arg(100)
    ->Arg(7000)
    ->Unit(benchmark::kMicrosecond);

// Classify as the service runs it by default: with the compiled-in
// familiarity model (24 Gaussians since the eleventh session of 2026-12-06).
void BM_ClassifyWithFamiliarity(benchmark::State& state) {
  auto net =
      HapticNet::FromOnnxBytes(DefaultHapticNetOnnx(), kDefaultHapticNetSource);
  auto familiarity = FamiliarityModel::FromText(
      DefaultHapticFamiliarity(), kDefaultHapticFamiliaritySource);
  if (!net.ok() || !familiarity.ok()) std::abort();
  const HapticClassifier classifier(
      std::move(net).value(), HapticPipelineOptions(),
      std::make_unique<FamiliarityModel>(*std::move(familiarity)));
  const auto trace = OneSecondTrace(1000.0);
  for (auto _ : state) {
    auto result = classifier.Classify(trace);
    if (!result.ok() || !result->has_familiarity) {
      state.SkipWithError("classify failed");
    }
    benchmark::DoNotOptimize(result);
  }
}
BENCHMARK(BM_ClassifyWithFamiliarity)->Unit(benchmark::kMicrosecond);

// The familiarity score alone: the ten summaries of the window and the
// distances to every Gaussian of the compiled-in model.
void BM_FamiliarityScore(benchmark::State& state) {
  auto familiarity = FamiliarityModel::FromText(
      DefaultHapticFamiliarity(), kDefaultHapticFamiliaritySource);
  if (!familiarity.ok()) std::abort();
  const auto features =
      ExtractHapticFeatures(OneSecondTrace(1000.0), HapticPipelineOptions());
  for (auto _ : state) {
    auto score =
        familiarity->Score(FamiliarityFeatures(features->window.inputs));
    benchmark::DoNotOptimize(score);
  }
  state.counters["gaussians"] =
      static_cast<double>(familiarity->components().size());
}
BENCHMARK(BM_FamiliarityScore)->Unit(benchmark::kMicrosecond);

void BM_ContactAndWindow(benchmark::State& state) {
  const auto trace = OneSecondTrace(1000.0);
  const HapticPipelineOptions options;
  for (auto _ : state) {
    auto features = ExtractHapticFeatures(trace, options);
    benchmark::DoNotOptimize(features);
  }
}
BENCHMARK(BM_ContactAndWindow)->Unit(benchmark::kMicrosecond);

// The contact detector on PackedTrace (tests/haptic/haptic_test_traces.h):
// 150,000 samples in 0.15 ms under a force its rising edge walks back
// through; the edge's smoothing window is found by binary search
// (docs/benchmarks.md).
void BM_ContactOnAPackedTrace(benchmark::State& state) {
  const std::vector<TimedWrench> trace = PackedTrace();
  const ContactDetector detector{ContactDetectorOptions()};
  for (auto _ : state) {
    auto contact = detector.Detect(trace);
    benchmark::DoNotOptimize(contact);
  }
}
BENCHMARK(BM_ContactOnAPackedTrace)->Unit(benchmark::kMillisecond);

void BM_HapticNetForward(benchmark::State& state) {
  const auto classifier = DefaultClassifier();
  const auto features =
      ExtractHapticFeatures(OneSecondTrace(1000.0), HapticPipelineOptions());
  for (auto _ : state) {
    auto output = classifier->net().Run(features->window.inputs);
    benchmark::DoNotOptimize(output);
  }
}
BENCHMARK(BM_HapticNetForward)->Unit(benchmark::kMicrosecond);

// The same forward pass through a model with the trainer's convolutional
// front end (--conv_channels=16,32). Latency does not depend on the weights'
// values, so seeded He-scaled weights stand in for trained ones.
void BM_HapticNetForwardConv(benchmark::State& state) {
  absl::StatusOr<HapticNetWeights> weights = WeightsWithFrontEnd({16, 32});
  if (!weights.ok()) std::abort();
  std::mt19937_64 rng(7);
  std::normal_distribution<double> normal(0.0, 1.0);
  auto fill = [&](double* values, size_t count, double fan_in) {
    for (size_t i = 0; i < count; ++i) {
      values[i] = std::sqrt(2.0 / fan_in) * normal(rng);
    }
  };
  for (ConvLayer& layer : weights->conv) {
    fill(layer.weight.data(), layer.weight.size(),
         layer.in_channels * kConvKernel);
  }
  fill(weights->w1.data(), weights->w1.size(), weights->w1.rows());
  fill(weights->w2.data(), weights->w2.size(), weights->w2.rows());
  fill(weights->w3.data(), weights->w3.size(), weights->w3.rows());
  auto net = HapticNet::FromOnnxBytes(HapticNetToOnnx(*weights, {}), "conv");
  if (!net.ok()) std::abort();
  const auto features =
      ExtractHapticFeatures(OneSecondTrace(1000.0), HapticPipelineOptions());
  for (auto _ : state) {
    auto output = (*net)->Run(features->window.inputs);
    benchmark::DoNotOptimize(output);
  }
}
BENCHMARK(BM_HapticNetForwardConv)->Unit(benchmark::kMicrosecond);

// The whole call over loopback gRPC: proto encoding of 1,000 samples, the
// HTTP/2 round trip and the handler.
void BM_ClassifyOverGrpc(benchmark::State& state) {
  const auto classifier = DefaultClassifier();
  RpcEnvironment env;
  HapticServiceImpl service(&env, classifier.get());
  auto server = ServiceServer::Start(ServerOptions(), &env, {&service},
                                     {kHapticServiceName});
  if (!server.ok()) std::abort();
  auto channel = MakeChannel((*server)->address(), ChannelOptions());
  auto stub = v1::HapticService::NewStub(*channel);
  v1::ClassifyRequest request;
  TraceToProto(OneSecondTrace(1000.0), &request);
  for (auto _ : state) {
    grpc::ClientContext context;
    context.set_deadline(std::chrono::system_clock::now() +
                         std::chrono::seconds(10));
    v1::ClassifyResponse response;
    if (!stub->Classify(&context, request, &response).ok()) {
      state.SkipWithError("rpc failed");
    }
  }
  (*server)->Shutdown();
}
BENCHMARK(BM_ClassifyOverGrpc)->Unit(benchmark::kMicrosecond)->UseRealTime();

}  // namespace
}  // namespace bitewise::haptic

BENCHMARK_MAIN();
