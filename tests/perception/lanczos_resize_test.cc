// ResizeLanczosAsPil (services/perception/lanczos_resize.h) against a
// floating-point Lanczos-3 written here from the filter's definition
// (support widened by the scale when shrinking, weights normalised, one
// 8-bit rounding per pass): within one level everywhere, on random images
// shrunk and enlarged, grey and colour.
#include "services/perception/lanczos_resize.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "gtest/gtest.h"

namespace bitewise::perception {
namespace {

double Lanczos3(double x) {
  if (x == 0.0) return 1.0;
  if (std::abs(x) >= 3.0) return 0.0;
  const double px = M_PI * x;
  return 3.0 * std::sin(px) * std::sin(px / 3.0) / (px * px);
}

// One pass along rows (horizontal) or columns, in double, rounded to 8
// bits at the end as PIL does between its two passes.
cv::Mat ReferencePass(const cv::Mat& src, int out_size, bool horizontal) {
  const int in_size = horizontal ? src.cols : src.rows;
  const int channels = src.channels();
  const double scale = static_cast<double>(in_size) / out_size;
  const double filter_scale = std::max(scale, 1.0);
  cv::Mat dst(horizontal ? src.rows : out_size,
              horizontal ? out_size : src.cols, src.type());
  for (int o = 0; o < out_size; ++o) {
    const double centre = (o + 0.5) * scale;
    std::vector<double> weight(in_size);
    double total = 0.0;
    for (int i = 0; i < in_size; ++i) {
      weight[i] = Lanczos3((i + 0.5 - centre) / filter_scale);
      total += weight[i];
    }
    const int lines = horizontal ? src.rows : src.cols;
    for (int line = 0; line < lines; ++line) {
      for (int c = 0; c < channels; ++c) {
        double sum = 0.0;
        for (int i = 0; i < in_size; ++i) {
          if (weight[i] == 0.0) continue;
          const uint8_t p = horizontal
                                ? src.ptr<uint8_t>(line)[i * channels + c]
                                : src.ptr<uint8_t>(i)[line * channels + c];
          sum += weight[i] / total * p;
        }
        const uint8_t out =
            static_cast<uint8_t>(std::clamp(std::floor(sum + 0.5), 0.0, 255.0));
        if (horizontal) {
          dst.ptr<uint8_t>(line)[o * channels + c] = out;
        } else {
          dst.ptr<uint8_t>(o)[line * channels + c] = out;
        }
      }
    }
  }
  return dst;
}

cv::Mat Reference(const cv::Mat& src, cv::Size size) {
  cv::Mat out = src;
  if (size.width != src.cols) out = ReferencePass(out, size.width, true);
  if (size.height != src.rows) out = ReferencePass(out, size.height, false);
  return out;
}

// Smooth shapes and hard edges plus noise: every part of the filter shows.
cv::Mat TestImage(int rows, int cols, int type, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<int> noise(-40, 40);
  cv::Mat image(rows, cols, type);
  const int channels = image.channels();
  for (int y = 0; y < rows; ++y) {
    for (int x = 0; x < cols; ++x) {
      for (int c = 0; c < channels; ++c) {
        const double smooth = 128 + 90 * std::sin(0.3 * x + 0.2 * y + c);
        const double edge = (x / 7 + y / 5 + c) % 2 ? 60 : -60;
        image.ptr<uint8_t>(y)[x * channels + c] = static_cast<uint8_t>(
            std::clamp(smooth + edge + noise(rng), 0.0, 255.0));
      }
    }
  }
  return image;
}

void ExpectWithinOneLevel(const cv::Mat& src, cv::Size size) {
  const cv::Mat got = ResizeLanczosAsPil(src, size);
  const cv::Mat want = Reference(src, size);
  ASSERT_EQ(got.size(), size);
  ASSERT_EQ(got.type(), src.type());
  cv::Mat diff;
  cv::absdiff(got, want, diff);
  EXPECT_LE(cv::norm(diff, cv::NORM_INF), 1.0) << src.size() << " -> " << size;
  // Off by one only where a value sits on a rounding boundary.
  const double exact =
      1.0 - cv::countNonZero(diff.reshape(1)) /
                static_cast<double>(diff.total() * diff.channels());
  EXPECT_GT(exact, 0.95) << src.size() << " -> " << size;
}

TEST(LanczosResizeTest, ShrinkingMatchesTheFilterWithItsWidenedSupport) {
  const cv::Mat colour = TestImage(61, 83, CV_8UC3, 1);
  for (const cv::Size size :
       {cv::Size(20, 15), cv::Size(41, 61), cv::Size(83, 30), cv::Size(7, 3)}) {
    ExpectWithinOneLevel(colour, size);
  }
  ExpectWithinOneLevel(TestImage(50, 50, CV_8UC1, 2), cv::Size(13, 17));
}

TEST(LanczosResizeTest, EnlargingMatchesTheFilterAtItsOwnSupport) {
  const cv::Mat colour = TestImage(23, 31, CV_8UC3, 3);
  for (const cv::Size size :
       {cv::Size(144, 107), cv::Size(62, 23), cv::Size(31, 100)}) {
    ExpectWithinOneLevel(colour, size);
  }
  ExpectWithinOneLevel(TestImage(9, 4, CV_8UC1, 4), cv::Size(40, 41));
}

TEST(LanczosResizeTest, ShrinkingOneWayAndEnlargingTheOtherMatchesToo) {
  ExpectWithinOneLevel(TestImage(30, 90, CV_8UC3, 5), cv::Size(144, 48));
  ExpectWithinOneLevel(TestImage(90, 30, CV_8UC3, 6), cv::Size(10, 144));
}

TEST(LanczosResizeTest, ASinglePixelOutputIsTheWeightedMean) {
  const cv::Mat src = TestImage(5, 8, CV_8UC1, 7);
  ExpectWithinOneLevel(src, cv::Size(1, 1));
}

}  // namespace
}  // namespace bitewise::perception
