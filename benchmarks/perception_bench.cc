// Cost of the PerceptionService's core work on a rendered 640x480 D415
// frame of eight touching unseen foods: DetectFood, the default featurizer
// and SPANet through OpenCV DNN (the generated, seeded model), and
// SPANet's preprocessing alone. Numbers and
// how to rerun them are in docs/benchmarks.md.
#include <cstdlib>
#include <iostream>
#include <memory>
#include <random>
#include <vector>

#include "benchmark/benchmark.h"
#include "services/perception/default_featurizer.h"
#include "services/perception/food_detector.h"
#include "services/perception/frame.h"
#include "services/perception/spanet_featurizer.h"
#include "services/sim/scene.h"

namespace bitewise::perception {
namespace {

struct Scene {
  sim::RenderedFrame rendered;
  DecodedFrame frame;
  PixelBox first_item;
};

const Scene& RenderedScene() {
  static const Scene* const scene = [] {
    auto* s = new Scene;
    std::mt19937_64 rng(7);
    const sim::PlateScene plate =
        sim::RandomPlate(sim::UnseenFoods(), /*allow_touching=*/true, rng);
    s->rendered = sim::RenderPlate(plate, sim::D415Intrinsics(), 7);
    s->frame = ViewFrame(s->rendered.intrinsics, s->rendered.rgb,
                         s->rendered.depth_mm);
    const sim::ItemTruth& t = s->rendered.truth.front();
    s->first_item = {t.x, t.y, t.width, t.height};
    return s;
  }();
  return *scene;
}

void BM_DetectFood(benchmark::State& state) {
  const Scene& scene = RenderedScene();
  const FoodDetector detector;
  size_t items = 0;
  for (auto _ : state) {
    auto detected = detector.Detect(scene.frame);
    if (!detected.ok()) state.SkipWithError("Detect failed");
    items = detected->size();
    benchmark::DoNotOptimize(detected);
  }
  state.counters["items"] = static_cast<double>(items);
}
BENCHMARK(BM_DetectFood)->Unit(benchmark::kMillisecond);

void BM_FeaturizeDefault(benchmark::State& state) {
  const Scene& scene = RenderedScene();
  const DefaultFeaturizer featurizer;
  for (auto _ : state) {
    auto features = featurizer.Featurize(scene.frame, scene.first_item,
                                         FoodLocation::kIsolated);
    if (!features.ok()) state.SkipWithError("Featurize failed");
    benchmark::DoNotOptimize(features);
  }
}
BENCHMARK(BM_FeaturizeDefault)->Unit(benchmark::kMillisecond);

void BM_FeaturizeSpanet(benchmark::State& state) {
  const Scene& scene = RenderedScene();
  static const auto* const spanet = [] {
    auto loaded = SpanetFeaturizer::Load(BITEWISE_SPANET_MODEL);
    if (!loaded.ok()) {
      std::cerr << loaded.status() << "\n";
      std::abort();
    }
    return loaded->release();
  }();
  for (auto _ : state) {
    auto features = spanet->Featurize(scene.frame, scene.first_item,
                                      FoodLocation::kIsolated);
    if (!features.ok()) state.SkipWithError("Featurize failed");
    benchmark::DoNotOptimize(features);
  }
}
BENCHMARK(BM_FeaturizeSpanet)->Unit(benchmark::kMillisecond);

// SPANet's preprocessing alone (PIL-exact Lanczos resize and paste) on a
// square crop of side state.range(0) cut from the frame.
void BM_SpanetCanvas(benchmark::State& state) {
  const Scene& scene = RenderedScene();
  const int side = static_cast<int>(state.range(0));
  const cv::Mat crop = scene.frame.rgb(cv::Rect(100, 50, side, side));
  for (auto _ : state) {
    cv::Mat canvas = SpanetCanvas(crop);
    benchmark::DoNotOptimize(canvas.data);
  }
}
BENCHMARK(BM_SpanetCanvas)->Arg(60)->Arg(300)->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace bitewise::perception

BENCHMARK_MAIN();
