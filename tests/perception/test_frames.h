// Rendered D415 frames for perception tests: plates of unseen foods from
// the simulated camera, as DecodedFrames for the core and as Frame protos
// (raw, PNG or JPEG) for the service, plus box IoU against ground truth.
#ifndef BITEWISE_TESTS_PERCEPTION_TEST_FRAMES_H_
#define BITEWISE_TESTS_PERCEPTION_TEST_FRAMES_H_

#include <algorithm>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "bitewise/v1/common.pb.h"
#include "opencv2/imgcodecs.hpp"
#include "opencv2/imgproc.hpp"
#include "services/perception/frame.h"
#include "services/sim/scene.h"

namespace bitewise::perception::testing {

struct TestScene {
  sim::PlateScene plate;
  sim::RenderedFrame rendered;
};

// `n_items` different unseen foods (shuffled by the seed) on one plate.
inline TestScene RenderTestScene(uint64_t seed, int n_items, bool touching) {
  std::mt19937_64 rng(seed);
  std::vector<const sim::FoodType*> foods = sim::UnseenFoods();
  std::shuffle(foods.begin(), foods.end(), rng);
  foods.resize(std::min<size_t>(foods.size(), n_items));
  TestScene scene;
  scene.plate = sim::RandomPlate(foods, touching, rng);
  scene.rendered = sim::RenderPlate(scene.plate, sim::D415Intrinsics(), seed);
  return scene;
}

// Views into `rendered`, which must outlive the result.
inline DecodedFrame ToDecoded(sim::RenderedFrame& rendered) {
  return ViewFrame(rendered.intrinsics, rendered.rgb, rendered.depth_mm);
}

inline std::string Encode(const sim::RenderedFrame& rendered,
                          v1::ImageEncoding encoding) {
  const sim::PinholeIntrinsics& k = rendered.intrinsics;
  if (encoding == v1::IMAGE_ENCODING_RGB8) {
    return std::string(rendered.rgb.begin(), rendered.rgb.end());
  }
  cv::Mat rgb(k.height, k.width, CV_8UC3,
              const_cast<uint8_t*>(rendered.rgb.data()));
  cv::Mat bgr;
  cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
  std::vector<uint8_t> bytes;
  cv::imencode(encoding == v1::IMAGE_ENCODING_PNG ? ".png" : ".jpg", bgr, bytes,
               {cv::IMWRITE_JPEG_QUALITY, 95});
  return std::string(bytes.begin(), bytes.end());
}

inline v1::Frame ToProto(const sim::RenderedFrame& rendered,
                         v1::ImageEncoding encoding) {
  const sim::PinholeIntrinsics& k = rendered.intrinsics;
  v1::Frame frame;
  frame.set_width(k.width);
  frame.set_height(k.height);
  frame.set_rgb_encoding(encoding);
  frame.set_rgb(Encode(rendered, encoding));
  std::string depth(rendered.depth_mm.size() * 2, '\0');
  for (size_t i = 0; i < rendered.depth_mm.size(); ++i) {
    depth[2 * i] = static_cast<char>(rendered.depth_mm[i] & 0xFF);
    depth[2 * i + 1] = static_cast<char>(rendered.depth_mm[i] >> 8);
  }
  frame.set_depth_mm(depth);
  frame.mutable_intrinsics()->set_fx(k.fx);
  frame.mutable_intrinsics()->set_fy(k.fy);
  frame.mutable_intrinsics()->set_cx(k.cx);
  frame.mutable_intrinsics()->set_cy(k.cy);
  frame.set_timestamp_s(1.0);
  frame.set_frame_id("test");
  return frame;
}

inline double BoxIoU(int ax, int ay, int aw, int ah, int bx, int by, int bw,
                     int bh) {
  const int x0 = std::max(ax, bx), y0 = std::max(ay, by);
  const int x1 = std::min(ax + aw, bx + bw), y1 = std::min(ay + ah, by + bh);
  const double inter =
      static_cast<double>(std::max(0, x1 - x0)) * std::max(0, y1 - y0);
  return inter /
         (static_cast<double>(aw) * ah + static_cast<double>(bw) * bh - inter);
}

}  // namespace bitewise::perception::testing

#endif  // BITEWISE_TESTS_PERCEPTION_TEST_FRAMES_H_
