#include "services/perception/spanet_featurizer.h"

#include <algorithm>
#include <array>
#include <cstdint>
#include <fstream>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "services/common/status_macros.h"
#include "services/perception/context_scale.h"
#include "services/perception/lanczos_resize.h"
#include "services/perception/spanet_onnx.h"

namespace bitewise::perception {
namespace {

constexpr char kRgbInput[] = "rgb";
constexpr char kLocationInput[] = "loc_type";
constexpr char kFeaturesOutput[] = "features";
constexpr char kScoresOutput[] = "scores";

}  // namespace

SpanetPlacement SpanetPlacementFor(int crop_width, int crop_height) {
  // As SPANet's Python: ratio = 144 / longer side in double precision, each
  // side int(side * ratio). The longer side can come out at 143 when the
  // product rounds just below 144, and the reference does the same.
  const double ratio =
      static_cast<double>(kSpanetImageSize) / std::max(crop_width, crop_height);
  SpanetPlacement p;
  p.width = std::max(1, static_cast<int>(crop_width * ratio));
  p.height = std::max(1, static_cast<int>(crop_height * ratio));
  p.offset_x = (kSpanetImageSize - p.width) / 2;
  p.offset_y = (kSpanetImageSize - p.height) / 2;
  return p;
}

cv::Mat SpanetCanvas8u(const cv::Mat& rgb_crop) {
  const SpanetPlacement p = SpanetPlacementFor(rgb_crop.cols, rgb_crop.rows);
  cv::Mat canvas(kSpanetImageSize, kSpanetImageSize, CV_8UC3,
                 cv::Scalar(0, 0, 0));
  ResizeLanczosAsPil(rgb_crop, cv::Size(p.width, p.height))
      .copyTo(canvas(cv::Rect(p.offset_x, p.offset_y, p.width, p.height)));
  return canvas;
}

cv::Mat SpanetCanvas(const cv::Mat& rgb_crop) {
  // v / 255 in float, as torchvision's ToTensor (a float division, which
  // can differ in the last bit from multiplying by 1/255).
  static const std::array<float, 256> kUnit = [] {
    std::array<float, 256> t{};
    for (int v = 0; v < 256; ++v) t[v] = static_cast<float>(v) / 255.0f;
    return t;
  }();
  const cv::Mat bytes = SpanetCanvas8u(rgb_crop);
  cv::Mat canvas(bytes.size(), CV_32FC3);
  const uint8_t* in = bytes.ptr<uint8_t>(0);
  float* out = canvas.ptr<float>(0);
  for (size_t i = 0; i < bytes.total() * 3; ++i) out[i] = kUnit[in[i]];
  return canvas;
}

SpanetFeaturizer::SpanetFeaturizer(cv::dnn::Net net, double context_msn)
    : context_msn_(context_msn), net_(std::move(net)) {}

absl::StatusOr<std::unique_ptr<SpanetFeaturizer>> SpanetFeaturizer::Load(
    const std::string& model_path) {
  {
    std::ifstream in(model_path, std::ios::binary);
    if (!in) {
      return absl::NotFoundError(
          absl::StrCat("SPANet model file \"", model_path,
                       "\" does not exist or cannot be opened"));
    }
  }
  // The check reads the file, then OpenCV reads it again: reading it once
  // into memory for both was measured to cost 0.2 GB more peak memory at
  // the same start-up time (0.9 s), so each reads from the page cache.
  RETURN_IF_ERROR(CheckSpanetOnnxGraph(model_path));
  cv::dnn::Net net;
  try {
    net = cv::dnn::readNetFromONNX(model_path);
  } catch (const cv::Exception& e) {
    return absl::FailedPreconditionError(
        absl::StrCat("SPANet model file \"", model_path,
                     "\" is not a loadable ONNX model: ", e.what()));
  }
  if (net.empty()) {
    return absl::FailedPreconditionError(absl::StrCat(
        "SPANet model file \"", model_path, "\" holds no network"));
  }
  net.setPreferableBackend(cv::dnn::DNN_BACKEND_OPENCV);
  net.setPreferableTarget(cv::dnn::DNN_TARGET_CPU);
  // E||c||^2 on seen foods, shipped beside the model; unknown without it.
  double context_msn = 0.0;
  absl::StatusOr<double> scale =
      ReadContextScaleFile(ContextScalePathFor(model_path));
  if (scale.ok()) {
    context_msn = *scale;
  } else if (!absl::IsNotFound(scale.status())) {
    return absl::FailedPreconditionError(scale.status().message());
  }
  auto featurizer = std::unique_ptr<SpanetFeaturizer>(
      new SpanetFeaturizer(std::move(net), context_msn));
  // One run on a black image proves the interface before the service
  // reports SERVING.
  const cv::Mat black(kSpanetImageSize, kSpanetImageSize, CV_32FC3,
                      cv::Scalar(0, 0, 0));
  cv::Mat features, scores;
  absl::Status probe =
      featurizer->Run(black, FoodLocation::kIsolated, &features, &scores);
  if (!probe.ok()) {
    return absl::FailedPreconditionError(
        absl::StrCat("SPANet model file \"", model_path,
                     "\" does not have SPANet's interface: ", probe.message()));
  }
  if (!cv::checkRange(features) || !cv::checkRange(scores)) {
    return absl::FailedPreconditionError(
        absl::StrCat("SPANet model file \"", model_path,
                     "\" gives outputs that are not finite numbers on a black "
                     "image (weights that are NaN or infinite?)"));
  }
  if (!cv::checkRange(scores, /*quiet=*/true, nullptr, 0.0, 1.0 + 1e-6)) {
    double lo = 0, hi = 0;
    cv::minMaxLoc(scores, &lo, &hi);
    return absl::FailedPreconditionError(absl::StrCat(
        "SPANet model file \"", model_path, "\" gives \"", kScoresOutput,
        "\" outside [0, 1] on a black image (", lo, " to ", hi,
        "): SPANet's head ends in a sigmoid (skewer points in the crop's "
        "unit square, action success rates); was it exported without it?"));
  }
  return featurizer;
}

absl::Status SpanetFeaturizer::Run(const cv::Mat& canvas, FoodLocation location,
                                   cv::Mat* features, cv::Mat* scores) const {
  const cv::Mat blob = cv::dnn::blobFromImage(canvas);  // NCHW, as is
  cv::Mat loc = cv::Mat::zeros(1, 3, CV_32F);
  loc.at<float>(0, static_cast<int>(location)) = 1.0f;
  std::vector<cv::Mat> outs;
  {
    absl::MutexLock lock(&mu_);
    try {
      net_.setInput(blob, kRgbInput);
      net_.setInput(loc, kLocationInput);
      net_.forward(outs,
                   std::vector<cv::String>{kFeaturesOutput, kScoresOutput});
    } catch (const cv::Exception& e) {
      return absl::InternalError(
          absl::StrCat("running SPANet (inputs \"", kRgbInput, "\", \"",
                       kLocationInput, "\"; outputs \"", kFeaturesOutput,
                       "\", \"", kScoresOutput, "\"): ", e.what()));
    }
  }
  if (outs.size() != 2 || outs[0].total() != kSpanetFeatureDim ||
      outs[1].total() != kSpanetScores) {
    return absl::InternalError(absl::StrCat(
        "SPANet outputs have ", outs.empty() ? 0 : outs[0].total(),
        " features and ", outs.size() < 2 ? 0 : outs[1].total(),
        " scores; expected ", kSpanetFeatureDim, " and ", kSpanetScores));
  }
  *features = outs[0].reshape(1, 1).clone();
  *scores = outs[1].reshape(1, 1).clone();
  return absl::OkStatus();
}

absl::Status SpanetFeaturizer::RunFinite(const cv::Mat& canvas,
                                         FoodLocation location,
                                         cv::Mat* features,
                                         cv::Mat* scores) const {
  RETURN_IF_ERROR(Run(canvas, location, features, scores));
  // A model that loaded (its probe was finite) can still give NaN or
  // infinity on some crop; a context that is not a number is the model's
  // fault, never sent on.
  if (!cv::checkRange(*features) || !cv::checkRange(*scores)) {
    return absl::InternalError(
        "SPANet gave outputs that are not finite numbers for this crop; the "
        "model is at fault");
  }
  if (!cv::checkRange(*scores, /*quiet=*/true, nullptr, 0.0, 1.0 + 1e-6)) {
    return absl::InternalError(
        absl::StrCat("SPANet gave \"", kScoresOutput,
                     "\" outside [0, 1] for this crop; the model is at fault"));
  }
  return absl::OkStatus();
}

absl::StatusOr<Features> SpanetFeaturizer::Featurize(
    const DecodedFrame& frame, const PixelBox& box,
    FoodLocation location) const {
  RETURN_IF_ERROR(ValidateBox(box, frame.width(), frame.height()));
  const cv::Mat crop = frame.rgb(cv::Rect(box.x, box.y, box.width, box.height));
  cv::Mat features, scores;
  RETURN_IF_ERROR(RunFinite(SpanetCanvas(crop), location, &features, &scores));
  Features out;
  out.context.reserve(kSpanetFeatureDim);
  // OpenCV's ReLU yields -0 for negative inputs; report a plain 0.
  for (const float f : cv::Mat_<float>(features)) {
    out.context.push_back(f == 0.0f ? 0.0 : f);
  }
  // The head's points are in canvas coordinates in [0, 1]; undo the
  // letterboxing so that clients get them relative to their own crop.
  const SpanetPlacement p = SpanetPlacementFor(box.width, box.height);
  for (int i = 0; i < 2; ++i) {
    const double cu = scores.at<float>(0, 2 * i) * kSpanetImageSize;
    const double cv_ = scores.at<float>(0, 2 * i + 1) * kSpanetImageSize;
    out.skewer_points.push_back(
        {(cu - p.offset_x) / p.width, (cv_ - p.offset_y) / p.height});
  }
  for (int a = 4; a < kSpanetScores; ++a) {
    out.action_scores.push_back(scores.at<float>(0, a));
  }
  return out;
}

}  // namespace bitewise::perception
