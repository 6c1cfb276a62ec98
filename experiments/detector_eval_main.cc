// bitewise-detector-eval: DetectFood on rendered plates where neighbours
// touch, the same food may appear twice (two carrot sticks side by side),
// and items are drawn from the unseen foods. Reports, over all items: found
// once (one-to-one match with IoU >= 0.5), merged with a neighbour, missed,
// the items lost (no match with IoU >= 0.5) by how much of them shows (and
// those in full view by food), the mean and worst IoU of matched items, and
// Detect's latency. (Merges are judged on boxes: one detection covering at
// least half of two items' boxes while one of them has no detection of its
// own.) The numbers in docs/perception.md come from
// `--plates=200 --seed=9001`; with
// --renderer=blind the plates come from a renderer written blind, as a test
// only (experiments/blind_plates.h). Detect runs as in bitewise-perception:
// the colour tables prepared first, and freed memory kept for the next plate
// (--retain_freed_memory, the service's flag). --detector_options changes
// any of DetectFood's options by name (ApplyDetectorOptions), so a setting
// tried on tuning seeds reruns from here.
#include <algorithm>
#include <array>
#include <chrono>
#include <cstdio>
#include <map>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "absl/flags/flag.h"
#include "absl/flags/usage.h"
#include "experiments/blind_plates.h"
#include "opencv2/imgcodecs.hpp"
#include "opencv2/imgproc.hpp"
#include "services/common/flags_usage.h"
#include "services/common/process_memory.h"
#include "services/perception/food_detector.h"
#include "services/perception/food_detector_options.h"
#include "services/sim/food_catalog.h"
#include "services/sim/scene.h"

ABSL_FLAG(int, plates, 200, "Plates to render.");
ABSL_FLAG(uint64_t, seed, 9001, "Seeds the plates.");
ABSL_FLAG(int, max_items, 8, "Items per plate: 2 to this.");
ABSL_FLAG(bool, verbose, false,
          "Name the foods of every merge and missed item on stderr.");
ABSL_FLAG(double, overlap, 0.0,
          "Crowded plates (sim::CrowdedPlate): chance that a flat item lies "
          "partly on a flat neighbour (a slice partly under another). With "
          "any crowding flag, items at least --min_visible of whose "
          "footprint shows are the ones that must be found.");
ABSL_FLAG(double, same_food_touch, 0.0,
          "Crowded plates: chance that an item touches one of its own food "
          "(same colour, side by side).");
ABSL_FLAG(double, touch, 0.5, "Crowded plates: chance of touching any item.");
ABSL_FLAG(double, min_visible, 0.2,
          "Crowded plates: the share of its footprint an item must show to "
          "count (the target: every such item found with IoU >= 0.5).");
ABSL_FLAG(std::string, renderer, "sim",
          "sim: the project's renderer (services/sim, RandomPlate or "
          "CrowdedPlate); blind: the renderer written blind as a test only "
          "(experiments/blind_plates.h), arranged by --overlap, "
          "--same_food_touch and --touch, with every item showing at least "
          "--min_visible required.");
ABSL_FLAG(std::string, dump, "",
          "Directory for plate<N>.png (truth green, detections red) of every "
          "plate with a merge, a missed item or an extra detection.");
ABSL_FLAG(std::string, detector_options, "",
          "DetectFood's options changed from their defaults, as "
          "name=value,name=value with the names of FoodDetectorOptions "
          "(services/perception/food_detector.h), e.g. "
          "min_soft_edge_distance=20,max_merge_top_ratio=1.4.");
ABSL_FLAG(bool, retain_freed_memory, true,
          "As bitewise-perception's flag: keep freed memory for the next "
          "plate (false: glibc's default, which returns it).");

namespace {

using bitewise::perception::DetectedFood;
using bitewise::perception::PixelBox;

struct Box {
  int x, y, w, h;
};

double Intersection(const Box& a, const Box& b) {
  const int x0 = std::max(a.x, b.x), y0 = std::max(a.y, b.y);
  const int x1 = std::min(a.x + a.w, b.x + b.w);
  const int y1 = std::min(a.y + a.h, b.y + b.h);
  return static_cast<double>(std::max(0, x1 - x0)) * std::max(0, y1 - y0);
}
double IoU(const Box& a, const Box& b) {
  const double i = Intersection(a, b);
  return i /
         (static_cast<double>(a.w) * a.h + static_cast<double>(b.w) * b.h - i);
}

// One rendered plate with, by truth index, each item's food and whether it
// lies partly on another.
struct Plate {
  bitewise::sim::RenderedFrame rendered;
  std::vector<std::string> food;
  std::vector<bool> lies_on_another;
  // By item index: how many separate pieces of at least kMinPiecePx of the
  // item show (an item under a neighbour can show on both sides of it); 0
  // when the renderer gives no label image.
  std::vector<int> pieces;
};

// The detector's smallest seed.
const int kMinPiecePx = bitewise::perception::FoodDetectorOptions().min_seed_px;

// Pieces of at least kMinPiecePx per item in a row-major label image.
std::vector<int> CountPieces(const std::vector<int16_t>& label, int width,
                             int height, size_t n_items) {
  std::vector<int> pieces(n_items, 0);
  for (size_t i = 0; i < n_items; ++i) {
    cv::Mat mask(height, width, CV_8UC1);
    for (int y = 0; y < height; ++y) {
      for (int x = 0; x < width; ++x) {
        mask.at<uint8_t>(y, x) =
            label[static_cast<size_t>(y) * width + x] == static_cast<int>(i)
                ? 255
                : 0;
      }
    }
    cv::Mat parts, stats, centroids;
    const int n = cv::connectedComponentsWithStats(mask, parts, stats,
                                                   centroids, 8, CV_32S);
    for (int c = 1; c < n; ++c) {
      pieces[i] += stats.at<int>(c, cv::CC_STAT_AREA) >= kMinPiecePx;
    }
  }
  return pieces;
}

// A plate of the project's renderer: 2 to `max_items` unseen foods.
Plate SimPlate(const std::vector<const bitewise::sim::FoodType*>& unseen,
               int max_items, bool crowded,
               const bitewise::sim::PlateCrowding& crowding,
               std::mt19937_64& rng) {
  const int n = 2 + static_cast<int>(rng() % (max_items - 1));
  std::vector<const bitewise::sim::FoodType*> foods;
  for (int i = 0; i < n; ++i) foods.push_back(unseen[rng() % unseen.size()]);
  const bitewise::sim::PlateScene scene =
      crowded ? bitewise::sim::CrowdedPlate(foods, crowding, rng)
              : bitewise::sim::RandomPlate(foods, /*allow_touching=*/true, rng);
  Plate plate;
  plate.rendered =
      bitewise::sim::RenderPlate(scene, bitewise::sim::D415Intrinsics(), rng());
  plate.pieces.assign(plate.rendered.truth.size(), 0);
  for (const bitewise::sim::ItemTruth& t : plate.rendered.truth) {
    for (const bitewise::sim::SceneItem& item : scene.items) {
      if (item.id != t.id) continue;
      plate.food.push_back(item.food->name);
      plate.lies_on_another.push_back(item.base_m > 0.0);
    }
  }
  return plate;
}

// A plate of the blind renderer.
Plate BlindPlate(uint64_t seed,
                 const bitewise::experiments::BlindPlateOptions& options) {
  bitewise::experiments::BlindPlate blind =
      bitewise::experiments::RenderBlindPlate(seed, options);
  std::vector<int> pieces =
      CountPieces(blind.label, blind.frame.intrinsics.width,
                  blind.frame.intrinsics.height, blind.frame.truth.size());
  return {std::move(blind.frame), std::move(blind.food),
          std::move(blind.lies_on_another), std::move(pieces)};
}

}  // namespace

int main(int argc, char** argv) {
  absl::SetProgramUsageMessage(
      "DetectFood on rendered plates with touching and repeated foods.");
  bitewise::ShowOwnFlagsInHelp();
  bitewise::ParseFlagsOnly(argc, argv);
  const int plates = absl::GetFlag(FLAGS_plates);
  const int max_items = std::max(2, absl::GetFlag(FLAGS_max_items));
  std::mt19937_64 rng(absl::GetFlag(FLAGS_seed));
  const std::vector<const bitewise::sim::FoodType*> unseen =
      bitewise::sim::UnseenFoods();
  if (absl::GetFlag(FLAGS_retain_freed_memory)) {
    const absl::Status retained = bitewise::RetainFreedMemory();
    if (!retained.ok()) {  // as in the service: said, and the run goes on
      std::fprintf(stderr, "warning: --retain_freed_memory: %s\n",
                   retained.ToString().c_str());
    }
  }
  bitewise::perception::PrepareColourConversions();
  bitewise::perception::FoodDetectorOptions detector_options;
  const std::string changed_options = absl::GetFlag(FLAGS_detector_options);
  if (const absl::Status applied = bitewise::perception::ApplyDetectorOptions(
          changed_options, detector_options);
      !applied.ok()) {
    std::fprintf(stderr, "--detector_options: %s\n",
                 std::string(applied.message()).c_str());
    return 2;
  }
  if (changed_options.find('=') != std::string::npos) {
    std::printf("detector options changed: %s\n", changed_options.c_str());
  }
  const bitewise::perception::FoodDetector detector(detector_options);
  bitewise::sim::PlateCrowding crowding;
  crowding.overlap_probability = absl::GetFlag(FLAGS_overlap);
  crowding.same_food_touch_probability = absl::GetFlag(FLAGS_same_food_touch);
  crowding.touch_probability = absl::GetFlag(FLAGS_touch);
  bool crowded = crowding.overlap_probability > 0.0 ||
                 crowding.same_food_touch_probability > 0.0;
  const double min_visible = absl::GetFlag(FLAGS_min_visible);
  const std::string renderer = absl::GetFlag(FLAGS_renderer);
  if (renderer != "sim" && renderer != "blind") {
    std::fprintf(stderr, "--renderer must be sim or blind, not \"%s\"\n",
                 renderer.c_str());
    return 2;
  }
  const bool blind = renderer == "blind";
  bitewise::experiments::BlindPlateOptions blind_options;
  blind_options.max_items = max_items;
  blind_options.overlap_probability = crowding.overlap_probability;
  blind_options.same_food_touch_probability =
      crowding.same_food_touch_probability;
  blind_options.touch_probability = crowding.touch_probability;
  if (blind) crowded = true;  // the blind plates always count by --min_visible
  int lying_on = 0, hidden = 0;  // items on a neighbour; below min_visible
  int items = 0, found = 0, merged = 0, missed = 0, extra = 0;
  // Lost items by how much of them shows. An item is lost when no
  // detection matches it with IoU >= 0.5 (the merged count above also
  // counts the found items of a join: a celery stick found, with a banana
  // coin lost under its box). Bands: below half showing, half to
  // kWholeShare, and in full view (kWholeShare or more), none of which may
  // be lost inside a neighbour's box.
  constexpr double kWholeShare = 0.95;
  struct Band {
    int items = 0, in_join = 0, otherwise = 0;
    // Of those, items seen in two or more pieces, and those of them lost.
    int in_pieces = 0, in_pieces_lost = 0;
  };
  std::array<Band, 3> bands;
  std::map<std::string, Band> whole_by_food;  // the items in full view
  const auto band_of = [&](double share) {
    return share >= kWholeShare ? 2 : share >= 0.5 ? 1 : 0;
  };
  int touching_items = 0, repeated_items = 0;
  double iou_sum = 0.0, worst = 1.0;
  std::vector<double> latency_ms;
  for (int p = 0; p < plates; ++p) {
    Plate plate = blind ? BlindPlate(rng(), blind_options)
                        : SimPlate(unseen, max_items, crowded, crowding, rng);
    bitewise::sim::RenderedFrame& rendered = plate.rendered;
    const bitewise::perception::DecodedFrame frame =
        bitewise::perception::ViewFrame(rendered.intrinsics, rendered.rgb,
                                        rendered.depth_mm);
    const auto start = std::chrono::steady_clock::now();
    auto detected = detector.Detect(frame);
    latency_ms.push_back(std::chrono::duration<double, std::milli>(
                             std::chrono::steady_clock::now() - start)
                             .count());
    if (!detected.ok() && absl::IsFailedPrecondition(detected.status())) {
      // No plate found: every item on it is missed (as when Detect returned
      // no items for it, before it said why), and the plate is named.
      std::fprintf(stderr, "plate %d: %s (its items count as missed)\n", p,
                   std::string(detected.status().message()).c_str());
      detected = std::vector<bitewise::perception::DetectedFood>();
    }
    if (!detected.ok()) {
      std::fprintf(stderr, "plate %d: %s\n", p,
                   detected.status().ToString().c_str());
      return 1;
    }
    std::vector<Box> truth, boxes;
    std::vector<std::string> truth_food;  // by truth index
    std::vector<bool> required;           // by truth index: must be found
    std::vector<double> shown;            // by truth index: visible share
    std::vector<int> pieces;              // by truth index: pieces seen
    for (size_t i = 0; i < rendered.truth.size(); ++i) {
      const bitewise::sim::ItemTruth& t = rendered.truth[i];
      if (t.visible_pixels == 0) continue;
      truth.push_back({t.x, t.y, t.width, t.height});
      truth_food.push_back(plate.food[i]);
      pieces.push_back(plate.pieces[i]);
      shown.push_back(static_cast<double>(t.visible_pixels) /
                      std::max(1, t.footprint_pixels));
      lying_on += plate.lies_on_another[i];
      required.push_back(!crowded ||
                         t.visible_pixels >= min_visible * t.footprint_pixels);
    }
    for (const DetectedFood& d : *detected) {
      boxes.push_back({d.bbox.x, d.bbox.y, d.bbox.width, d.bbox.height});
    }
    // Items in contact with another (their boxes overlap) and repeats.
    for (size_t a = 0; a < truth.size(); ++a) {
      bool touches = false, repeat = false;
      for (size_t b = 0; b < truth.size(); ++b) {
        if (a == b) continue;
        touches |= Intersection(truth[a], truth[b]) > 0;
        repeat |= truth_food[a] == truth_food[b];
      }
      touching_items += touches;
      repeated_items += repeat;
    }
    // One-to-one matching, best IoU first.
    std::vector<std::tuple<double, size_t, size_t>> pairs;
    for (size_t t = 0; t < truth.size(); ++t) {
      for (size_t d = 0; d < boxes.size(); ++d) {
        const double iou = IoU(truth[t], boxes[d]);
        if (iou > 0) pairs.emplace_back(iou, t, d);
      }
    }
    std::sort(pairs.rbegin(), pairs.rend());
    std::vector<double> best(truth.size(), 0.0);
    std::vector<bool> t_used(truth.size(), false), d_used(boxes.size(), false);
    for (const auto& [iou, t, d] : pairs) {
      if (t_used[t] || d_used[d]) continue;
      t_used[t] = d_used[d] = true;
      best[t] = iou;
    }
    // Merges: a detection covering at least half of the boxes of two or
    // more items, one of which found no detection of its own (a long
    // diagonal stick's box may cover a small neighbour and still be right).
    const auto dump = [&] {
      const std::string dir = absl::GetFlag(FLAGS_dump);
      if (dir.empty()) return;
      cv::Mat bgr;
      cv::cvtColor(frame.rgb, bgr, cv::COLOR_RGB2BGR);
      for (const Box& b : truth) {
        cv::rectangle(bgr, cv::Rect(b.x, b.y, b.w, b.h), {0, 255, 0});
      }
      for (const Box& b : boxes) {
        cv::rectangle(bgr, cv::Rect(b.x, b.y, b.w, b.h), {0, 0, 255});
      }
      cv::imwrite(dir + "/plate" + std::to_string(p) + ".png", bgr);
    };
    std::vector<bool> is_merged(truth.size(), false);
    for (const Box& d : boxes) {
      std::vector<size_t> covered;
      for (size_t t = 0; t < truth.size(); ++t) {
        const double area = static_cast<double>(truth[t].w) * truth[t].h;
        if (Intersection(d, truth[t]) >= 0.5 * area) covered.push_back(t);
      }
      bool lost = false;
      for (size_t t : covered) lost |= best[t] < 0.5;
      if (covered.size() >= 2 && lost) {
        for (size_t t : covered) is_merged[t] = true;
        if (absl::GetFlag(FLAGS_verbose)) {
          std::fprintf(stderr, "plate %d merged:", p);
          for (size_t t : covered) {
            std::fprintf(stderr, " %s (%.0f%%%s%s, box %d,%d %dx%d)",
                         truth_food[t].c_str(), 100.0 * std::min(1.0, shown[t]),
                         best[t] < 0.5 ? ", lost" : "",
                         pieces[t] >= 2 ? ", in pieces" : "", truth[t].x,
                         truth[t].y, truth[t].w, truth[t].h);
          }
          std::fprintf(stderr, "\n");
        }
        dump();
      }
    }
    for (size_t t = 0; t < truth.size(); ++t) {
      if (!required[t]) {
        ++hidden;
        continue;
      }
      ++items;
      Band& band = bands[band_of(shown[t])];
      Band* by_food =
          band_of(shown[t]) == 2 ? &whole_by_food[truth_food[t]] : nullptr;
      ++band.items;
      if (by_food != nullptr) ++by_food->items;
      if (pieces[t] >= 2) {
        ++band.in_pieces;
        band.in_pieces_lost += best[t] < 0.5;
      }
      if (is_merged[t]) {
        ++merged;
        band.in_join += best[t] < 0.5;
        if (by_food != nullptr) by_food->in_join += best[t] < 0.5;
      } else if (best[t] >= 0.5) {
        ++found;
        iou_sum += best[t];
        worst = std::min(worst, best[t]);
      } else {
        ++missed;
        ++band.otherwise;
        if (by_food != nullptr) ++by_food->otherwise;
        if (absl::GetFlag(FLAGS_verbose)) {
          std::fprintf(stderr,
                       "plate %d missed: %s (%.0f%%, best IoU %.2f%s, box "
                       "%d,%d %dx%d)\n",
                       p, truth_food[t].c_str(),
                       100.0 * std::min(1.0, shown[t]), best[t],
                       pieces[t] >= 2 ? ", in pieces" : "", truth[t].x,
                       truth[t].y, truth[t].w, truth[t].h);
        }
        dump();
      }
    }
    for (size_t d = 0; d < boxes.size(); ++d) {
      if (d_used[d]) continue;
      ++extra;
      dump();
      if (!absl::GetFlag(FLAGS_verbose)) continue;
      // Name the item whose box holds most of the extra detection's.
      const double area = static_cast<double>(boxes[d].w) * boxes[d].h;
      std::string inside = "the plate";
      double most = 0.5 * area;
      for (size_t t = 0; t < truth.size(); ++t) {
        const double share = Intersection(boxes[d], truth[t]);
        if (share > most) {
          most = share;
          inside = truth_food[t];
        }
      }
      std::fprintf(stderr, "plate %d extra: %dx%d px on %s\n", p, boxes[d].w,
                   boxes[d].h, inside.c_str());
    }
  }
  std::sort(latency_ms.begin(), latency_ms.end());
  const auto pct = [&](double q) {
    return latency_ms[static_cast<size_t>(q * (latency_ms.size() - 1))];
  };
  std::printf(
      "plates %d, items %d (touching a neighbour %d, same food on the "
      "plate %d)\n",
      plates, items, touching_items, repeated_items);
  if (crowded) {
    std::printf(
        "crowded plates: %d items lying partly on a neighbour; %d items "
        "showing less than %.0f%% of their footprint (not counted below)\n",
        lying_on, hidden, 100.0 * min_visible);
  }
  std::printf("found once (IoU >= 0.5)     %d (%.2f%%)\n", found,
              100.0 * found / items);
  std::printf("merged with a neighbour     %d (%.2f%%)\n", merged,
              100.0 * merged / items);
  std::printf("missed otherwise            %d\n", missed);
  const char* band_names[] = {"under 50% showing", "50-95% showing   ",
                              "in full view     "};
  for (size_t b = 0; b < bands.size(); ++b) {
    std::printf("lost, %s  %d of %d (in a join %d, otherwise %d)\n",
                band_names[b], bands[b].in_join + bands[b].otherwise,
                bands[b].items, bands[b].in_join, bands[b].otherwise);
    if (b < 2 && blind) {
      std::printf("  seen in two or more pieces: %d lost of %d\n",
                  bands[b].in_pieces_lost, bands[b].in_pieces);
    }
  }
  for (const auto& [food, band] : whole_by_food) {
    if (band.in_join + band.otherwise == 0) continue;
    std::printf("  in full view: %-14s %d of %d (in a join %d, otherwise %d)\n",
                food.c_str(), band.in_join + band.otherwise, band.items,
                band.in_join, band.otherwise);
  }
  std::printf("extra detections            %d\n", extra);
  std::printf("IoU of found items          mean %.3f, worst %.3f\n",
              found ? iou_sum / found : 0.0, worst);
  std::printf("Detect latency (ms)         median %.1f, p95 %.1f, max %.1f\n",
              pct(0.5), pct(0.95), latency_ms.back());
  return 0;
}
