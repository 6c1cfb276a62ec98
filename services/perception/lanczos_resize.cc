#include "services/perception/lanczos_resize.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

namespace bitewise::perception {
namespace {

constexpr int kPrecisionBits = 32 - 8 - 2;
constexpr double kSupport = 3.0;

double Sinc(double x) {
  if (x == 0.0) return 1.0;
  const double px = x * M_PI;
  return std::sin(px) / px;
}

double Lanczos3(double x) {
  return (x >= -kSupport && x < kSupport) ? Sinc(x) * Sinc(x / kSupport) : 0.0;
}

// For each output sample along one axis: the first input index and the
// fixed-point weights of the inputs from there on.
struct AxisWeights {
  std::vector<int> first;
  std::vector<int> count;
  std::vector<int32_t> weights;  // taps per output, `taps` apart
  int taps = 0;
};

AxisWeights ComputeAxisWeights(int in_size, int out_size) {
  const double scale = static_cast<double>(in_size) / out_size;
  const double filter_scale = std::max(scale, 1.0);
  const double support = kSupport * filter_scale;
  AxisWeights w;
  w.taps = static_cast<int>(std::ceil(support)) * 2 + 1;
  w.first.resize(out_size);
  w.count.resize(out_size);
  w.weights.assign(static_cast<size_t>(out_size) * w.taps, 0);
  std::vector<double> k(w.taps);
  const double inv_filter_scale = 1.0 / filter_scale;
  for (int o = 0; o < out_size; ++o) {
    const double centre = (o + 0.5) * scale;
    // The input window, rounded by truncation and clamped to the image.
    int lo = static_cast<int>(centre - support + 0.5);
    if (lo < 0) lo = 0;
    int hi = static_cast<int>(centre + support + 0.5);
    if (hi > in_size) hi = in_size;
    const int n = hi - lo;
    double sum = 0.0;
    for (int i = 0; i < n; ++i) {
      k[i] = Lanczos3((i + lo - centre + 0.5) * inv_filter_scale);
      sum += k[i];
    }
    for (int i = 0; i < n; ++i) {
      const double normalised = sum != 0.0 ? k[i] / sum : k[i];
      const double fixed = normalised * (1 << kPrecisionBits);
      // Round half away from zero.
      w.weights[static_cast<size_t>(o) * w.taps + i] =
          static_cast<int32_t>(fixed < 0 ? fixed - 0.5 : fixed + 0.5);
    }
    w.first[o] = lo;
    w.count[o] = n;
  }
  return w;
}

uint8_t Clip8(int32_t accumulated) {
  const int32_t v = accumulated >> kPrecisionBits;
  return static_cast<uint8_t>(std::clamp(v, 0, 255));
}

// One pass along x (horizontal) or y (vertical), 8 bits in and out.
cv::Mat ResamplePass(const cv::Mat& src, int out_size, bool horizontal) {
  const int channels = src.channels();
  const int in_size = horizontal ? src.cols : src.rows;
  const AxisWeights w = ComputeAxisWeights(in_size, out_size);
  cv::Mat dst(horizontal ? src.rows : out_size,
              horizontal ? out_size : src.cols, src.type());
  for (int y = 0; y < dst.rows; ++y) {
    uint8_t* out = dst.ptr<uint8_t>(y);
    for (int x = 0; x < dst.cols; ++x) {
      const int o = horizontal ? x : y;
      const int32_t* k = &w.weights[static_cast<size_t>(o) * w.taps];
      for (int c = 0; c < channels; ++c) {
        // Start at one half so that the shift rounds to nearest. The sum
        // stays far inside int32: weights total 2^22 and pixels are < 2^8.
        int32_t acc = 1 << (kPrecisionBits - 1);
        for (int i = 0; i < w.count[o]; ++i) {
          const int at = w.first[o] + i;
          const uint8_t p = horizontal ? src.ptr<uint8_t>(y)[at * channels + c]
                                       : src.ptr<uint8_t>(at)[x * channels + c];
          acc += static_cast<int32_t>(p) * k[i];
        }
        out[x * channels + c] = Clip8(acc);
      }
    }
  }
  return dst;
}

}  // namespace

cv::Mat ResizeLanczosAsPil(const cv::Mat& src, cv::Size size) {
  CV_Assert(src.depth() == CV_8U && size.width >= 1 && size.height >= 1);
  cv::Mat out = src;
  if (size.width != src.cols) out = ResamplePass(out, size.width, true);
  if (size.height != src.rows) out = ResamplePass(out, size.height, false);
  return out.data == src.data ? src.clone() : out;
}

}  // namespace bitewise::perception
