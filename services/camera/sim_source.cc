#include "services/camera/sim_source.h"

#include <algorithm>
#include <random>
#include <utility>

#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "absl/time/time.h"
#include "services/sim/food_catalog.h"

namespace bitewise::camera {

absl::StatusOr<std::unique_ptr<SimSource>> SimSource::Create(
    const SimSourceOptions& options) {
  if (!(options.rate_hz > 0.0)) {
    return absl::InvalidArgumentError(
        absl::StrCat("rate_hz must be > 0 (got ", options.rate_hz, ")"));
  }
  std::vector<const sim::FoodType*> foods;
  for (const std::string& name : options.foods) {
    const sim::FoodType* food = sim::FindFood(name);
    if (food == nullptr) {
      return absl::InvalidArgumentError(
          absl::StrCat("unknown food \"", name, "\" for the simulated plate"));
    }
    foods.push_back(food);
  }
  if (foods.empty()) foods = sim::UnseenFoods();
  std::mt19937_64 rng(options.seed);
  return std::unique_ptr<SimSource>(new SimSource(
      sim::RandomPlate(foods, options.allow_touching, rng), options));
}

SimSource::SimSource(sim::PlateScene scene, const SimSourceOptions& options)
    : scene_(std::move(scene)), options_(options) {}

std::string SimSource::name() const {
  return absl::StrCat("sim:seed=", options_.seed);
}

absl::StatusOr<domain::RgbdFrame> SimSource::Next() {
  const double now = CameraNowS();
  if (next_s_ > now) absl::SleepFor(absl::Seconds(next_s_ - now));
  next_s_ = std::max(now, next_s_) + 1.0 / options_.rate_hz;
  sim::RenderedFrame rendered = sim::RenderPlate(
      scene_, sim::D415Intrinsics(), options_.seed * 1000003ULL + sequence_);
  domain::RgbdFrame frame;
  frame.intrinsics = rendered.intrinsics;
  frame.rgb = std::move(rendered.rgb);
  frame.depth_mm = std::move(rendered.depth_mm);
  frame.sequence = sequence_++;
  frame.capture_s = CameraNowS();
  return frame;
}

}  // namespace bitewise::camera
