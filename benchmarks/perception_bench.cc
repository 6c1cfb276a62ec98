// Cost of the PerceptionService's core work on a rendered 640x480 D415
// frame of eight touching unseen foods: DetectFood, the default featurizer
// and SPANet through OpenCV DNN (the generated, seeded model), and
// SPANet's preprocessing alone. Numbers and
// how to rerun them are in docs/benchmarks.md.
#include <cstdlib>
#include <iostream>
#include <memory>
#include <optional>
#include <random>
#include <vector>

#include "benchmark/benchmark.h"
#include "services/perception/default_featurizer.h"
#include "services/perception/food_detector.h"
#include "services/perception/food_detector_stages.h"
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

// DetectFood's stages one at a time (range(0): 0 MeasureHeight, 1
// FindPlate, 2 FindEvidence, 3 PlantSeeds, 4 GrowRegions, 5 MergeSplitItems,
// 6 SplitAtWaists, 7 DescribeItems), each on its inputs from the stages before
// it, computed once outside the timing; 3-7 on the food's box, as in Detect.
void BM_DetectStage(benchmark::State& state) {
  using namespace detection;  // NOLINT: the stages, in order
  const Scene& scene = RenderedScene();
  const DecodedFrame& frame = scene.frame;
  const FoodDetectorOptions options;
  const std::optional<HeightMap> heights =
      MeasureHeight(frame.depth_mm, frame.intrinsics, options);
  const std::optional<PlateRegion> plate =
      heights ? FindPlate(*heights, options) : std::nullopt;
  if (!plate) {
    state.SkipWithError("no plate");
    return;
  }
  const cv::Rect& roi = plate->roi;
  const cv::Mat rgb = frame.rgb(roi);
  const cv::Mat height_mm = heights->height_mm(roi);
  const cv::Mat valid = heights->valid(roi);
  const FoodEvidence evidence =
      FindEvidence(rgb, height_mm, valid, *plate, options);
  // The later stages on the food's box, as Detect runs them.
  const cv::Rect box = FoodBox(evidence, options);
  const FoodEvidence food = CropEvidence(evidence, box);
  const cv::Mat food_rgb = rgb(box);
  const cv::Mat food_height = height_mm(box);
  const cv::Mat food_valid = valid(box);
  const cv::Mat food_plate = plate->plate(box);
  const cv::Rect in_frame = box + roi.tl();
  const std::optional<Regions> seeds = PlantSeeds(food, food_height, options);
  Regions grown = *seeds;
  grown.markers = seeds->markers.clone();
  GrowRegions(food_rgb, food, food_plate, grown);
  Regions merged = grown;
  merged.markers = grown.markers.clone();
  MergeSplitItems(food, food_height, food_valid, options, merged);
  Regions split = merged;
  split.markers = merged.markers.clone();
  SplitAtWaists(options, split);
  static constexpr const char* kNames[] = {
      "MeasureHeight", "FindPlate",       "FindEvidence",  "PlantSeeds",
      "GrowRegions",   "MergeSplitItems", "SplitAtWaists", "DescribeItems"};
  const int stage = static_cast<int>(state.range(0));
  for (auto _ : state) {
    switch (stage) {
      case 0:
        benchmark::DoNotOptimize(
            MeasureHeight(frame.depth_mm, frame.intrinsics, options));
        break;
      case 1:
        benchmark::DoNotOptimize(FindPlate(*heights, options));
        break;
      case 2:
        benchmark::DoNotOptimize(
            FindEvidence(rgb, height_mm, valid, *plate, options));
        break;
      case 3:
        benchmark::DoNotOptimize(PlantSeeds(food, food_height, options));
        break;
      case 4: {
        Regions regions = *seeds;
        regions.markers = seeds->markers.clone();
        GrowRegions(food_rgb, food, food_plate, regions);
        benchmark::DoNotOptimize(regions);
        break;
      }
      case 5: {
        Regions regions = grown;
        regions.markers = grown.markers.clone();
        MergeSplitItems(food, food_height, food_valid, options, regions);
        benchmark::DoNotOptimize(regions);
        break;
      }
      case 6: {
        Regions regions = merged;
        regions.markers = merged.markers.clone();
        SplitAtWaists(options, regions);
        benchmark::DoNotOptimize(regions);
        break;
      }
      default:
        benchmark::DoNotOptimize(
            DescribeItems(split, food, frame.depth_mm(in_frame), in_frame,
                          heights->plane, frame.intrinsics, options));
    }
  }
  state.SetLabel(kNames[stage]);
}
BENCHMARK(BM_DetectStage)->DenseRange(0, 7)->Unit(benchmark::kMillisecond);

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
