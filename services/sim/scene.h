// The simulated plate as the wrist camera sees it: a plate on a mat with
// food items, and the RGB-D rendering of it through the RealSense D415's
// intrinsics. The robot's simulated world owns a PlateScene (items leave it
// when acquired); the renderer turns it into frames; perception's tests use
// the per-item ground truth.
//
// Frames: the plate frame has its origin at the plate centre on the plate
// surface, x right, y down (as seen in the image), z up out of the plate.
// The camera looks straight down from `camera_height_m` above the plate
// centre; camera frame x right, y down, z forward (into the plate), so a
// point (x, y, 0) on the plate is at (x, y, camera_height_m) in the camera
// frame.
#ifndef BITEWISE_SERVICES_SIM_SCENE_H_
#define BITEWISE_SERVICES_SIM_SCENE_H_

#include <array>
#include <cstdint>
#include <random>
#include <vector>

#include "services/domain/rgbd_frame.h"
#include "services/sim/food_catalog.h"

namespace bitewise::sim {

struct SceneItem {
  uint32_t id = 0;                 // unique within the scene
  const FoodType* food = nullptr;  // from FoodCatalog()
  double x_m = 0.0;                // centre, plate frame
  double y_m = 0.0;
  double yaw_rad = 0.0;     // major axis angle from +x, in the image
  double length_m = 0.03;   // major axis
  double width_m = 0.02;    // minor axis
  double height_m = 0.015;  // thickness: top above the item's underside
  // Underside above the plate surface: 0 for an item on the plate; an item
  // lying partly on a neighbour rests this high (CrowdedPlate).
  double base_m = 0.0;
  std::array<double, 3> rgb{0.5, 0.5, 0.5};  // this item's colour
  uint64_t texture_seed = 0;                 // per-item texture
};

struct PlateScene {
  double plate_radius_m = 0.12;
  double rim_height_m = 0.012;
  std::array<double, 3> plate_rgb{0.92, 0.92, 0.90};
  std::array<double, 3> mat_rgb{0.20, 0.30, 0.45};
  double camera_height_m = 0.35;  // plate surface to camera, along z
  std::vector<SceneItem> items;
};

// The vocabulary's intrinsics (services/domain/rgbd_frame.h).
using PinholeIntrinsics = domain::CameraIntrinsics;

// The D415's colour-aligned intrinsics at 640x480.
PinholeIntrinsics D415Intrinsics();

// Ground truth of one rendered item.
struct ItemTruth {
  uint32_t id = 0;
  int x = 0, y = 0, width = 0, height = 0;  // bounding box of visible pixels
  int visible_pixels = 0;
  // Pixels the item would cover with nothing else on the plate: the share
  // visible is visible_pixels / footprint_pixels.
  int footprint_pixels = 0;
};

struct RenderedFrame {
  PinholeIntrinsics intrinsics;
  std::vector<uint8_t> rgb;        // width*height*3, row-major RGB8
  std::vector<uint16_t> depth_mm;  // width*height, 0 = no depth
  std::vector<ItemTruth> truth;    // one per item in the scene
};

// The rendered picture as the vocabulary's frame (the truth stays behind).
domain::RgbdFrame ToRgbdFrame(RenderedFrame rendered, uint64_t sequence,
                              double capture_s);

// Renders the scene; `noise_seed` drives sensor noise so frames repeat.
RenderedFrame RenderPlate(const PlateScene& scene,
                          const PinholeIntrinsics& intrinsics,
                          uint64_t noise_seed);

// A plate of `foods` (one item each, in order) with per-item variation in
// size, colour and orientation, placed without overlap; `allow_touching`
// lets neighbours touch.
PlateScene RandomPlate(const std::vector<const FoodType*>& foods,
                       bool allow_touching, std::mt19937_64& rng);

// How crowded a plate is (CrowdedPlate). Each new item, in turn: with
// `overlap_probability`, if it is flat (at most max_overlap_height_m) and a
// flat item is already on the plate, it lies partly on that item (its
// centre 40-80 % of the touching distance away, its underside resting on
// the lower item's top: a slice partly under a neighbour);
// else with `same_food_touch_probability` it touches an item of its own food
// (same colour, side by side); else with `touch_probability` it touches any
// item; else it is placed apart.
struct PlateCrowding {
  double overlap_probability = 0.0;
  double max_overlap_height_m = 0.015;
  double same_food_touch_probability = 0.0;
  double touch_probability = 0.5;
};

// A plate as RandomPlate's (same sizes, colours and orientations), placed
// as `crowding` says. Detector evaluations use it; the simulated world does
// not.
PlateScene CrowdedPlate(const std::vector<const FoodType*>& foods,
                        const PlateCrowding& crowding, std::mt19937_64& rng);

}  // namespace bitewise::sim

#endif  // BITEWISE_SERVICES_SIM_SCENE_H_
