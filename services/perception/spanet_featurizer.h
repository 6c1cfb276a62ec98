// SPANet (Feng et al. 2019, the visual model of Gordon et al. 2021) run
// through OpenCV's DNN module from an ONNX file: the 2048 activations before
// its head are the bandit's context; the head gives two skewer points and
// six action success rates. Preprocessing follows SPANet's own exactly (see
// SpanetCanvas); the ONNX interface is in spanet_onnx.h.
#ifndef BITEWISE_SERVICES_PERCEPTION_SPANET_FEATURIZER_H_
#define BITEWISE_SERVICES_PERCEPTION_SPANET_FEATURIZER_H_

#include <memory>
#include <string>

#include "absl/base/thread_annotations.h"
#include "absl/status/statusor.h"
#include "absl/synchronization/mutex.h"
#include "opencv2/core.hpp"
#include "opencv2/dnn.hpp"
#include "services/perception/featurizer.h"

namespace bitewise::perception {

// Side of SPANet's square input image.
constexpr int kSpanetImageSize = 144;
constexpr int kSpanetFeatureDim = 2048;
// Head: 2 skewer points (4 numbers), then 6 action success rates.
constexpr int kSpanetScores = 10;

// Where a crop lands on SPANet's canvas, exactly as SPANet's Python
// computes it: ratio = 144 / longer side (double), each side
// int(side * ratio) (at least 1), centred with the remainder split as
// (144 - size) / 2 on the top/left.
struct SpanetPlacement {
  int width = 0;
  int height = 0;
  int offset_x = 0;
  int offset_y = 0;
};
SpanetPlacement SpanetPlacementFor(int crop_width, int crop_height);

// SPANet's input image for an RGB8 crop, byte for byte what its own
// preprocessing makes: the crop resized as PIL's LANCZOS (ANTIALIAS) does
// (lanczos_resize.h) and pasted on a black 144x144 canvas. CV_8UC3, RGB.
cv::Mat SpanetCanvas8u(const cv::Mat& rgb_crop);

// The same canvas as the network takes it: CV_32FC3 RGB, each byte / 255
// in float (torchvision's ToTensor), no mean or std removed.
cv::Mat SpanetCanvas(const cv::Mat& rgb_crop);

// Thread-safe: calls into the network are serialised (a cv::dnn::Net is not
// reentrant); OpenCV uses all cores inside each call.
class SpanetFeaturizer final : public Featurizer {
 public:
  // Loads and checks the model: it must read as ONNX, take inputs "rgb"
  // [1,3,144,144] and "loc_type" [1,3], and produce "features" with 2048
  // values and "scores" with 10. Errors: NOT_FOUND when the file does not
  // exist; FAILED_PRECONDITION when it cannot be read, is not a loadable
  // ONNX model, or does not have that interface, or when "<model>.stats"
  // exists but is malformed; each names the file.
  static absl::StatusOr<std::unique_ptr<SpanetFeaturizer>> Load(
      const std::string& model_path);

  std::string name() const override { return "spanet"; }
  int dimension() const override { return kSpanetFeatureDim; }
  // From "<model>.stats" beside the model (context_scale.h); 0 without it.
  double context_mean_squared_norm() const override { return context_msn_; }
  absl::StatusOr<Features> Featurize(const DecodedFrame& frame,
                                     const PixelBox& box,
                                     FoodLocation location) const override;

 private:
  SpanetFeaturizer(cv::dnn::Net net, double context_msn);

  // Runs the network on one canvas; features and scores as float rows.
  absl::Status Run(const cv::Mat& canvas, FoodLocation location,
                   cv::Mat* features, cv::Mat* scores) const;
  // Run, and INTERNAL when an output is not a finite number.
  absl::Status RunFinite(const cv::Mat& canvas, FoodLocation location,
                         cv::Mat* features, cv::Mat* scores) const;

  const double context_msn_;
  mutable absl::Mutex mu_;
  mutable cv::dnn::Net net_ ABSL_GUARDED_BY(mu_);
};

}  // namespace bitewise::perception

#endif  // BITEWISE_SERVICES_PERCEPTION_SPANET_FEATURIZER_H_
