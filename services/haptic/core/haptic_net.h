// HapticNet inference: the 384-128-ReLU-128-ReLU-4 MLP with softmax, loaded
// from an ONNX file and run through OpenCV's DNN module. The normalisation
// statistics live inside the graph (a Sub and a Div node in front of the
// first layer), so a model can never be run without the statistics it was
// trained with. The graph contract (docs/haptic.md): input "wrench_window"
// of shape [1, 384], outputs "logits" and "probabilities" of shape [1, 4].
#ifndef BITEWISE_SERVICES_HAPTIC_CORE_HAPTIC_NET_H_
#define BITEWISE_SERVICES_HAPTIC_CORE_HAPTIC_NET_H_

#include <array>
#include <memory>
#include <optional>
#include <string>

#include "absl/base/thread_annotations.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "absl/synchronization/mutex.h"
#include "opencv2/dnn.hpp"
#include "services/haptic/core/haptic_window.h"
#include "services/haptic/core/wrench_trace.h"

namespace bitewise::haptic {

constexpr char kHapticNetInputName[] = "wrench_window";
constexpr char kHapticNetLogitsName[] = "logits";
constexpr char kHapticNetProbabilitiesName[] = "probabilities";
// metadata_props key under which a model records its window (s).
constexpr char kHapticNetWindowKey[] = "bitewise.window_s";

struct HapticNetOutput {
  // Softmax of the network, in class order hard, medium, soft, hard-skin,
  // computed in double from the logits: it matches the graph's float
  // softmax to about 1e-7 but never underflows to exactly 0, so it stays
  // consistent with log_probabilities.
  std::array<double, kHapticClasses> probabilities{};
  // log-softmax of the logits, in double, so that confident predictions
  // keep finite log-probabilities for the unlikely classes.
  std::array<double, kHapticClasses> log_probabilities{};
};

// Thread-safe: OpenCV's Net is not, so runs are serialised by a mutex (one
// run costs tens of microseconds).
class HapticNet {
 public:
  // Parses an ONNX model held in memory and checks it against the graph
  // contract with one run on a zero input. `source` names the model in
  // error messages. Errors: INVALID_ARGUMENT when the bytes are not a
  // loadable ONNX model, the graph breaks the contract, or its
  // "bitewise.window_s" is not a number of seconds in (0, 1].
  static absl::StatusOr<std::unique_ptr<HapticNet>> FromOnnxBytes(
      absl::string_view bytes, const std::string& source);
  // As FromOnnxBytes, from a file. NOT_FOUND when the file cannot be read.
  static absl::StatusOr<std::unique_ptr<HapticNet>> FromOnnxFile(
      const std::string& path);

  HapticNet(const HapticNet&) = delete;
  HapticNet& operator=(const HapticNet&) = delete;

  // Runs the network on one window. INTERNAL if OpenCV fails or the output
  // is not finite.
  absl::StatusOr<HapticNetOutput> Run(
      const std::array<float, kHapticInputs>& inputs) const;

  // "fnv1a64:<16 hex digits>" of the model bytes: which model answered.
  const std::string& fingerprint() const { return fingerprint_; }

  // The window after contact (s) the model was trained on, from its
  // metadata_props entry "bitewise.window_s"; nullopt for a model that
  // records none (then it is the original 0.05 s). A window runs the
  // network on a different picture, so the service must use this one.
  std::optional<double> window_s() const { return window_s_; }

 private:
  HapticNet(cv::dnn::Net net, std::string fingerprint,
            std::optional<double> window_s)
      : net_(std::move(net)),
        fingerprint_(std::move(fingerprint)),
        window_s_(window_s) {}

  mutable absl::Mutex mu_;
  mutable cv::dnn::Net net_ ABSL_GUARDED_BY(mu_);
  const std::string fingerprint_;
  const std::optional<double> window_s_;
};

}  // namespace bitewise::haptic

#endif  // BITEWISE_SERVICES_HAPTIC_CORE_HAPTIC_NET_H_
