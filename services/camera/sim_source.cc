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
    : scene_(std::move(scene)), options_(options), pacer_(options.rate_hz) {}

std::string SimSource::name() const {
  return absl::StrCat("sim:seed=", options_.seed);
}

absl::StatusOr<domain::RgbdFrame> SimSource::Next() {
  pacer_.Wait();
  const uint64_t sequence = sequence_++;
  return sim::ToRgbdFrame(
      sim::RenderPlate(scene_, sim::D415Intrinsics(),
                       options_.seed * 1000003ULL + sequence),
      sequence, SteadyNowS());
}

}  // namespace bitewise::camera
