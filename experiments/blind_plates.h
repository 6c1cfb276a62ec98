// Blind plates: an independently written RGB-D plate renderer, used only as
// a test set for DetectFood on plates it was never tuned on. Written blind
// on 2026-12-04 from a physical description of real cut food on a real
// plate seen by the wrist-mounted Intel RealSense D415 (640x480 colour,
// depth aligned to colour): it shares no code, shapes or assumptions with
// the project's own renderer (services/sim), only the output structs.
//
// Everything is in millimetres in a world frame whose origin is the plate
// centre on the well surface, z up. Each piece of food is a solid given by
// a signed distance function (a coin, a stick, a U-shaped celery stick, a
// round cone for a strawberry, a rounded box for melon, an ellipsoid, and
// halves of some of these), placed by a small rigid-body rule (lowest
// centre of mass on the plate, or on a neighbour when shingled) and
// rendered by sphere tracing one ray per pixel. Colour: two area-ish lights
// (room lamp, window) and a sky term with soft shadows, Blinn-Phong
// highlights, white balance, lens blur, sensor noise. Depth: the colour
// camera's z, with active-stereo artefacts (noise growing with z^2, 1 mm
// quantisation, occlusion bands beside raised edges, smeared edges,
// projector glints and scattered holes).
#ifndef BITEWISE_EXPERIMENTS_BLIND_PLATES_H_
#define BITEWISE_EXPERIMENTS_BLIND_PLATES_H_

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "services/sim/scene.h"

namespace bitewise::experiments {

struct BlindPlateOptions {
  int min_items = 2;
  int max_items = 8;
  // Arrangement probabilities, tried in this order for each new item.
  // A flat piece (slice, coin, halved strawberry, celery stick) lies partly
  // on a flat item already there (shingled).
  double overlap_probability = 0.3;
  // Touches a piece of its own food, side by side.
  double same_food_touch_probability = 0.3;
  // Touches any item.
  double touch_probability = 0.3;
  // Depth artefacts of active stereo (noise, holes, bands, smear) and
  // colour sensor noise; off gives the clean geometry (tests).
  bool sensor_artifacts = true;
};

struct BlindPlate {
  // rgb, depth_mm, intrinsics, truth (one ItemTruth per item, id = index).
  sim::RenderedFrame frame;
  // By item index: "carrot", "celery", "strawberry", "cantaloupe",
  // "banana", "kiwi", "cherry_tomato", "grape".
  std::vector<std::string> food;
  // By item index: the item lies partly on another one (shingled).
  std::vector<bool> lies_on_another;
  // By item index: the item it was shingled onto, or -1.
  std::vector<int> lies_on_index;
  // By item index: the piece's own extent (length >= width, height), mm.
  std::vector<std::array<double, 3>> size_mm;
  // Per pixel (row-major): index of the item seen there, -1 = plate/table.
  std::vector<int16_t> label;
  // Distance from the camera to the plate's well along the optical axis.
  double axis_distance_mm = 0.0;
};

// One plate, fully determined by `seed`.
BlindPlate RenderBlindPlate(uint64_t seed, const BlindPlateOptions& options);

// The food names in the order above.
const std::vector<std::string>& BlindPlateFoods();

}  // namespace bitewise::experiments

#endif  // BITEWISE_EXPERIMENTS_BLIND_PLATES_H_
