// The weight-free food detector behind DetectFood: finds the plate as the
// dominant plane in the depth image, takes what rises above it as food, and
// uses colour to draw each item's exact outline and to split touching items
// (a watershed on the RGB image seeded from the depth blobs' cores). Works on
// the D415's noisy depth with holes; needs no trained weights.
#ifndef BITEWISE_SERVICES_PERCEPTION_FOOD_DETECTOR_H_
#define BITEWISE_SERVICES_PERCEPTION_FOOD_DETECTOR_H_

#include <cstdint>
#include <vector>

#include "absl/status/statusor.h"
#include "services/perception/frame.h"

namespace bitewise::perception {

// DetectFood's settings. Each field is also settable by its name through
// ApplyDetectorOptions (food_detector_options.h), whose table lists them
// all: a new field goes into that table too (its test sets every name).
struct FoodDetectorOptions {
  // Height above the plate surface from which a pixel counts as food. Above
  // the D415's depth noise at arm's length (about 1 mm), below the flattest
  // food items (about 8 mm).
  double min_height_mm = 4.0;
  // Plate surface: points within this distance of the fitted plane.
  double plate_tolerance_mm = 3.0;
  // Smallest item kept, by its footprint on the plate (1 cm^2 drops crumbs
  // and noise, keeps a blueberry).
  double min_item_area_m2 = 0.6e-4;
  // CIELAB distance from the plate colour beyond which a pixel looks like
  // food rather than plate (shadows on a white plate stay below it).
  double min_colour_distance = 14.0;
  // Bare plate: a pixel with depth at most this high above the plate and
  // the plate's colour is plate, however close to food. The flood that
  // outlines the items stops there instead of running along a neighbour's
  // shadow. 0: off (only plate well away from food is background).
  double max_bare_plate_mm = 1.5;
  // Shadow on the plate: a pixel with depth on the plate (as above), darker
  // than the plate but within this many CIELAB units of its chroma (a*, b*),
  // is the plate in a shadow, not food, whatever its lightness: a shadow
  // dims the light, it does not change the plate's colour. 0: off.
  double max_shadow_chroma = 8.0;
  // Colour gradient (CIELAB units per pixel) that separates two touching
  // items; texture within one item stays below it.
  double min_edge_strength = 10.0;
  // Soft edges: pixels whose colours 2 px to either side (across or down)
  // differ by more than this (CIELAB) cut seeds too, where a shaded rim
  // spreads the change between two items over a few pixels. 0: off. (20
  // until the sixteenth session, chosen on the own renderer's plates, where
  // 14, 20 and 25 found nearly the same items; 16 on the blind tuning
  // plates, where a pale banana coin and a celery stick's lit wall touch
  // at one height and shared a seed: docs/perception.md, "Softer colour
  // edges".)
  double min_soft_edge_distance = 16.0;
  // Seeds stop at height valleys (where touching items meet): a pixel that
  // a closing of this width lifts by more than max(min_valley_mm,
  // valley_fraction x the local top) is not a seed.
  int valley_width_px = 31;
  double min_valley_mm = 1.5;
  double valley_fraction = 0.15;
  // Seeds stop at height steps too (an item lying partly on another): a
  // pixel whose cliff_window_px neighbourhood rises above it by more than
  // max(min_cliff_mm, cliff_fraction x its height). 0 or 1: no step cut.
  int cliff_window_px = 7;
  double min_cliff_mm = 3.0;
  double cliff_fraction = 0.25;
  // A cut seed counts as a part when it keeps at least this many pixels.
  int min_seed_px = 30;
  // Terraces: an item partly under another (a slice lying on a slice) shows
  // as a lower step beside the upper one, below half the local top and so
  // with no seed. Pixels that are at least half as high as the highest point
  // within terrace_window_px / 2 (too small a window to see the step's top)
  // and not next to a seed are seeded on their own when, after an opening
  // that drops the thin flanks of every item, they keep min_terrace_px.
  // The opening's width: a strip of a lower item narrower than this is
  // not seeded (the flanks of an item are about 2 px wide).
  int terrace_window_px = 7;
  int terrace_open_px = 3;
  int min_terrace_px = 40;
  // Neighbours of similar colour are merged (one item cut in two) only when
  // the higher one's top is at most this many times the lower one's: a
  // slice lying on another stands about twice as high as the one under it.
  double max_merge_top_ratio = 1.5;
  // A region inside food (at least this share of the watershed ridge
  // beside it borders other regions, not the background) is part of the
  // neighbour it shares its longest seam with, whatever its colour, when
  // there is no valley between them and neither stands on the other (the
  // top ratio above; and max_enclosed_median_ratio below): a kiwi slice's
  // pale core and seed ring inside its green flesh. Above 1: off. Not so a
  // region that has a larger neighbour of similar colour (under
  // min_colour_distance), open to the background, with no dip between
  // them: that is the item it is part of (a sliver of a kiwi's flesh beside
  // a carrot coin lying on the kiwi), when enclosed_kin is true. (That
  // neighbour is not checked for a shaded crease, a step or a low seam, so
  // the merge may still keep the two apart, and the region is left on its
  // own.)
  double min_enclosed_share = 0.9;
  bool enclosed_kin = true;
  // The inside rule joins two regions only when the higher one's median
  // height is at most this times the lower one's: a region of a kiwi's seed
  // ring at the foot of a carrot coin lying on the kiwi, whose top (the
  // 90th percentile of its heights, which the top ratio above compares) the
  // coin's edge had raised, was joined to the coin. 0: off.
  double max_enclosed_median_ratio = 1.5;
  // A band across an item: a region of at least min_seed_px joins two of
  // its neighbours of similar colour to each other (under
  // min_colour_distance), whatever its own colour, when neither seam with
  // them has a dip by the closing's lift (min_valley_mm, valley_fraction;
  // the seam's own height is not asked, since a cut face may slope), a
  // shaded crease or one standing on the other (max_merge_top_ratio), and
  // the two seams make up at least this share of the watershed ridge
  // beside it (0: never joined): a halved strawberry's pale core between
  // two strips of red flesh, which reaches the outline at both ends. A band
  // more than min_crease_shade_l darker than the darker of the two is the
  // shaded crease between two touching items and is not joined with them,
  // and two neighbours whose own seam keeps them apart (a shaded crease,
  // one standing on the other, a valley along it) are not joined by a band.
  double min_sandwich_share = 0.6;
  // A highlight is part of the item it lies on. A glossy skin (a
  // strawberry's, a tomato's) reflects the lamp or the window, which adds
  // white light to the item's own colour: lighter, less chromatic, the same
  // hue. Two neighbours with no valley between them (by the closing's lift;
  // the highlight runs along the item's crest, so the seams run down its
  // flanks) and neither standing on the other are joined when the lighter
  // one's mean colour is at most max_highlight_below_plate_l darker than the
  // plate (a highlight is about as light as white ceramic), at most
  // max_highlight_chroma_share as chromatic as the darker one (at least half
  // the light there is the reflection), and of its hue within
  // max_highlight_hue_deg (both at least 8 units of chroma, below which a
  // hue is noise). 0: never joined.
  double max_highlight_hue_deg = 10.0;
  double max_highlight_chroma_share = 0.5;
  double max_highlight_below_plate_l = 15.0;
  // Two bodies that touch shade the crease between them: each hides part of
  // the room's light from it. (On blind tuning plates, over the pairs the
  // merge joined, seams between two items were a median 8.3 L darker than
  // the darker region; seams inside one item, a median 5.3 L lighter.) Two
  // neighbours whose seam is on average more than min_crease_shade_l
  // (CIELAB L) darker than the darker of the two are not merged by the
  // colour, inside or highlight test, whatever their colour and height.
  // (They can still end up one region through a third, and the stick join
  // does not look at seams.) 0: off.
  double min_crease_shade_l = 4.0;
  // A valley that runs across a seam is not a valley between the two
  // regions. A celery stick is a U-shaped channel: its floor lies below its
  // walls, so the closing lifts the whole floor, and a seam that cuts the
  // stick crosswise crosses that valley instead of following it. Where two
  // items touch, the lift peaks on the seam and falls off to either side.
  // So the lift is also sampled valley_flank_px to either side of each seam
  // pixel, across the seam and inside the two regions; when a seam with a
  // dip has at least 3 such readings and is lifted there on average at
  // least min_valley_flank_share as much as on the seam, neither the dip
  // nor the seam's height (low on a channel's floor) keeps two regions of
  // similar colour apart (the colour test of the merge; the shaded-crease
  // and top-ratio tests still apply). 0: off.
  int valley_flank_px = 5;
  double min_valley_flank_share = 0.8;
  // A seam with no dip is low (on average under 0.8 of the lower region's
  // top) where two touching items meet down their rounded sides, and also
  // where it runs across one item's profile (a stick cut crosswise: the
  // seam crosses its sloping sides and a celery's low floor). Across a
  // profile, the points valley_flank_px to either side of the seam are as
  // low as the seam; where two items meet down rounded sides, the items
  // rise from it (on the blind plates mostly not: docs/perception.md, "A
  // seam across a stick's profile", measured afterwards). So a seam with
  // no dip whose height, over at least 3 seam pixels whose two flanks lie
  // in the two regions (all three with depth), is at least
  // min_seam_flank_height_share of the flanks' mean height does not keep
  // two regions apart either: neither for the colour test nor for the
  // inside rule (min_enclosed_share). 0, or valley_flank_px 0: off.
  double min_seam_flank_height_share = 0.9;
  // Two bodies touch along a short contact: round or tapered items meet at
  // a point, so the seam between them is short against their size. One
  // item cut in two by a crease, a colour band or a highlight is cut across
  // its width, so the seam runs about as long as the parts are wide: for a
  // part l long and w wide cut across, the seam over the square root of
  // the part's pixels is sqrt(w / l), 1.6 for half a disc. Two regions that
  // each hold at least min_contact_part_px pixels, and whose seam is
  // shorter than min_contact_seam_share x the square root of the smaller
  // one's pixels, are not merged by the colour, inside or highlight test
  // (a band between them, the stick join or a third region may still join
  // them). At 0.5, the halves of a stick up to about eight times as long as
  // wide are still merged (about seven for a 20 px wide stick, whose
  // outline is ridge). The seam's length is its ridge pixels over the
  // larger of |cos| and |sin| of its direction (the watershed draws one
  // pixel per step along a seam's main axis); a region's pixels leave out
  // its outline, which is ridge, so a thin part reads a little thinner.
  // Regions under min_contact_part_px (slivers, a highlight, a seed's
  // crumbs) are left to the other tests. min_contact_seam_share 0: off.
  double min_contact_seam_share = 0.5;
  int min_contact_part_px = 400;
  // A stick with an item lying across it shows as two parts; they are
  // joined when the item on them borders both and the line between them
  // runs under that item, they and that item cover at least min_join_fill
  // of the smallest rectangle around the two parts (a stick is a
  // rectangle; a round slice beside a stick leaves plate in it), and one
  // part has an axis ratio of at least min_join_elongation (two whole round
  // slices either side of a tall item are two items). Above 1: never
  // joined.
  double min_join_fill = 0.75;
  double min_join_elongation = 1.3;
  // A stick cut lengthwise into parts of one colour (a celery's two walls
  // and its floor): starting from a part at least min_stick_seed_elongation
  // long for its width, neighbours of similar colour (or of its colour in
  // other light, max_stick_shade_distance below) at least
  // min_stick_part_elongation long for theirs are joined to it while the
  // parts fill at least min_stick_fill of the smallest rectangle around them
  // and that rectangle is at least min_stick_elongation long for its width.
  // min_stick_seed_elongation 0 turns the step off; any of the other three
  // at 0 only drops its own test.
  double min_stick_seed_elongation = 3.0;
  double min_stick_part_elongation = 2.0;
  double min_stick_fill = 0.9;
  double min_stick_elongation = 3.0;
  // In that fill, count every part the band may still take (long, of its
  // colour) as well as its own: a stick cut in three, wall, floor, wall,
  // whose floor is narrow or uneven, takes some of the far wall into the
  // rectangle around the near wall and the floor. false: only the band's
  // own parts (and the ridges between) fill it.
  bool stick_fill_counts_long_parts = true;
  // A stick's parts face the light in different ways (a celery's walls up
  // and out, its floor in the channel's shade). More or less light on one
  // surface scales its X, Y and Z by one factor, and so (L + 16, a, b) in
  // CIELAB, made of their cube roots, by one factor too (while none of X, Y,
  // Z is below 0.8856 % of white). So in that band a part is of the band's
  // colour when within min_colour_distance of it or when, each colour
  // scaled by that factor to the other's lightness, the two are within
  // max_stick_shade_distance in a and b (both ways: a dark grey is not a
  // pale, nearly grey colour in shade). 0: colour distance only.
  double max_stick_shade_distance = 4.0;
  // A part's top in the join across an item lying on a stick (min_join_fill
  // above): this quantile of its heights. Lower than the merge's 0.9,
  // because the highest pixels of a small stub are the flank of the item
  // lying on it.
  double join_top_quantile = 0.8;
  // Two touching convex items that no seed told apart grow into one
  // region with a waist. A region whose solidity (area over its convex
  // hull's) is below max_waist_solidity is cut along the segment between
  // two of its hull's concavities at least min_waist_depth_px deep, when
  // that leaves two parts, each at least min_waist_part_share of the region
  // and more than min_waist_solidity solid. 0: never cut. With
  // waist_fills_inner_seams, a region's own inner seams (the ridge pixels
  // within its box between parts the merge joined, which touch no other
  // region or the background as 8-neighbours) count as its pixels;
  // without, they are notches that lower its parts' solidity.
  double max_waist_solidity = 0.97;
  double min_waist_solidity = 0.92;
  double min_waist_depth_px = 3.0;
  double min_waist_part_share = 0.2;
  bool waist_fills_inner_seams = true;
  // Crumbs of an item: the shaded side face of a cube, a strawberry's calyx
  // or a seed that the merge left as regions of their own nibble notches
  // into the item's outline, and so into the solidity of the parts a waist
  // cut would leave. In those tests (not in the regions themselves), a
  // region also counts as its own the pixels, within its box and within
  // the convex hull of its own pixels, of each region of at most
  // max_waist_crumb_px pixels that borders it and no other region but such
  // small ones and the background (8-neighbours of the ridge pixels around
  // the small region), and the ridge pixels between them, as the inner
  // seams above. A crumb fills a notch; where a small region bulges out of
  // the region's hull (the crescent of an item mostly hidden under it, or
  // the rest of a neighbour the merge wrongly joined), it is not read as a
  // crumb there. The crumbs keep their labels when the region is cut. 0:
  // none. Needs waist_fills_inner_seams: without it, the ridge around a
  // crumb is left unfilled, and the crumb stays apart from the outline.
  // Limit: a cut's parts are measured with their crumbs (for
  // min_waist_part_share too), so a part that is mostly a crumb can be cut
  // off, leaving its new item a sliver of the region's own pixels. (Without the
  // hull, reported twice and not kept: docs/perception.md, "Crumbs in a waist,
  // and two rules not kept".)
  int max_waist_crumb_px = 600;
  // A region at least min_stick_elongation long for its width is cut only
  // where the cut is at most max_waist_cut_share of each part's width (the
  // short side of its minimum-area rectangle): two items meet at a waist
  // narrower than either, while a stick seen bent or notched, cut across,
  // is as wide as its parts. 0: no such test.
  double max_waist_cut_share = 0.7;
  // A region that is a compact convex item (more than min_waist_solidity
  // solid, at most max_tail_body_elongation long for its width) and a thin
  // strip along it (at least min_stick_elongation long for its width, its
  // pixels at most max_tail_width_px times its length, so that thin on
  // average) is cut between them when no waist cut is found: a banana coin
  // beside a celery stick takes the stick's pale lit wall by colour. Only
  // cuts that fail the waist cut's solidity test are tried so (a strip
  // that is not convex), the body is the larger part, and the strip is at
  // least min_waist_part_share of the region. The strip becomes an item of
  // its own. max_tail_width_px 0: no such cut.
  double max_tail_width_px = 10.0;
  double max_tail_body_elongation = 2.0;
  // RANSAC plane fit: iterations and seed (fixed, so detection repeats).
  int ransac_iterations = 150;
  uint64_t ransac_seed = 1;
  // RANSAC scores a plane by its points within plate_tolerance_mm minus
  // ransac_below_weight x its points more than plate_tolerance_mm below it.
  // The fit looks at the middle of the image, where the camera sees the
  // plate's well, and nothing there lies below the well; a plane with points
  // well below it is tilted through the tops of flat food (slices covering
  // much of the middle, with bare plate on one side), which by its points
  // alone can beat the plate's own plane and leave thin items where the
  // well lies below the plane under min_height_mm. 0: the inlier count
  // alone (the detector before this rule). A view whose middle shows much
  // of the table below the plate breaks the fit's premise either way: the
  // table's plane wins once the table shows more than 1 / (1 + weight) of
  // the well's points (half at 1; with 0, as many). When no candidate holds
  // more points on it than weight x its points below it (the window's lowest
  // surface never sampled), there is no plane, and Detect finds nothing.
  double ransac_below_weight = 1.0;
};

struct DetectedFood {
  PixelBox bbox;
  // Centroid of the item's pixels.
  double center_u_px = 0.0;
  double center_v_px = 0.0;
  // Direction of the minimum-area rectangle's longer side, from +u (image
  // right) towards +v (image down), in (-pi/2, pi/2].
  double major_axis_angle_rad = 0.0;
  // Median depth of the item's pixels that have depth.
  double depth_m = 0.0;
  // The centre pixel deprojected at depth_m, camera frame (x right, y down,
  // z forward).
  double center_x_m = 0.0;
  double center_y_m = 0.0;
  double center_z_m = 0.0;
  // How well depth and colour agree that these pixels are food, in [0, 1]:
  // the mean over the item's pixels of 1 when both do, 0.5 when one does.
  double score = 0.0;
  int area_px = 0;
};

// OpenCV builds its CIELAB tables on the first colour conversion (about
// 90 ms on the development machine), so the first DetectFood, and the
// default featurizer's first Featurize, would pay for them. A service calls
// this once before it reports SERVING.
void PrepareColourConversions();

// Thread-compatible and stateless after construction: Detect is const and
// may run concurrently.
class FoodDetector {
 public:
  explicit FoodDetector(const FoodDetectorOptions& options = {});

  // Items on the plate, highest score first. A frame without a visible
  // plate (no flat surface covering a tenth of the image) has no items.
  // Errors: INVALID_ARGUMENT if the frame has no depth (the detector
  // segments by height above the plate).
  absl::StatusOr<std::vector<DetectedFood>> Detect(
      const DecodedFrame& frame) const;

  const FoodDetectorOptions& options() const { return options_; }

 private:
  FoodDetectorOptions options_;
};

}  // namespace bitewise::perception

#endif  // BITEWISE_SERVICES_PERCEPTION_FOOD_DETECTOR_H_
