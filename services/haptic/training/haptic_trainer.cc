#include "services/haptic/training/haptic_trainer.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "services/domain/random.h"

namespace bitewise::haptic {
namespace {

// The loops below fix the order of every floating-point sum: C[i][j]
// accumulates over p ascending whatever the vector width, so results do not
// depend on the CPU. Eigen's products would pick their blocking from the
// cache sizes at run time, and with it the rounding.

// C (n x m) = A (n x k) * B (k x m).
void MatMul(const double* a, const double* b, int n, int k, int m, double* c) {
  std::fill(c, c + static_cast<size_t>(n) * m, 0.0);
  for (int i = 0; i < n; ++i) {
    double* c_row = c + static_cast<size_t>(i) * m;
    for (int p = 0; p < k; ++p) {
      const double a_ip = a[static_cast<size_t>(i) * k + p];
      if (a_ip == 0.0) continue;  // ReLU zeros: a third of the work
      const double* b_row = b + static_cast<size_t>(p) * m;
      for (int j = 0; j < m; ++j) c_row[j] += a_ip * b_row[j];
    }
  }
}

// C (k x m) = A^T * B with A (n x k), B (n x m).
void MatTMul(const double* a, const double* b, int n, int k, int m, double* c) {
  std::fill(c, c + static_cast<size_t>(k) * m, 0.0);
  for (int i = 0; i < n; ++i) {
    const double* b_row = b + static_cast<size_t>(i) * m;
    for (int p = 0; p < k; ++p) {
      const double a_ip = a[static_cast<size_t>(i) * k + p];
      if (a_ip == 0.0) continue;
      double* c_row = c + static_cast<size_t>(p) * m;
      for (int j = 0; j < m; ++j) c_row[j] += a_ip * b_row[j];
    }
  }
}

// C (n x k) = A (n x m) * B^T with B (k x m).
void MatMulT(const double* a, const double* b, int n, int m, int k, double* c) {
  for (int i = 0; i < n; ++i) {
    const double* a_row = a + static_cast<size_t>(i) * m;
    for (int p = 0; p < k; ++p) {
      const double* b_row = b + static_cast<size_t>(p) * m;
      double sum = 0.0;
      for (int j = 0; j < m; ++j) sum += a_row[j] * b_row[j];
      c[static_cast<size_t>(i) * k + p] = sum;
    }
  }
}

void AddBias(const std::vector<double>& bias, int n, double* z) {
  const int m = static_cast<int>(bias.size());
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < m; ++j) z[static_cast<size_t>(i) * m + j] += bias[j];
  }
}

void ColumnSums(const double* g, int n, int m, std::vector<double>& out) {
  std::fill(out.begin(), out.end(), 0.0);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < m; ++j) out[j] += g[static_cast<size_t>(i) * m + j];
  }
}

// Parameters as blocks: each front-end layer's kernel and bias, then w1,
// b1, w2, b2, w3, b3, each row-major fan_in x fan_out (biases 1 x fan_out;
// kernels (in_channels * kConvKernel) x out_channels). Weights are the
// even blocks.
struct Parameters {
  std::vector<std::vector<double>> blocks;
  std::vector<int> rows, cols;
  int conv_layers = 0;

  explicit Parameters(const std::vector<ConvLayer>& conv) {
    conv_layers = static_cast<int>(conv.size());
    for (const ConvLayer& layer : conv) {
      Add(layer.in_channels * kConvKernel, layer.out_channels);
      Add(1, layer.out_channels);
    }
    const int fan_in = FrontEndOutputs(conv);
    Add(fan_in, kHapticHidden);
    Add(1, kHapticHidden);
    Add(kHapticHidden, kHapticHidden);
    Add(1, kHapticHidden);
    Add(kHapticHidden, kHapticClasses);
    Add(1, kHapticClasses);
  }
  void Add(int r, int c) {
    rows.push_back(r);
    cols.push_back(c);
    blocks.emplace_back(static_cast<size_t>(r) * c, 0.0);
  }
  int Fc(int layer) const { return 2 * conv_layers + 2 * layer; }  // 0..2
  int FanIn() const { return rows[Fc(0)]; }
  // The front-end layer `i` as ConvForward takes it (a copy).
  ConvLayer Conv(int i) const {
    ConvLayer layer;
    layer.in_channels = rows[2 * i] / kConvKernel;
    layer.out_channels = cols[2 * i];
    layer.weight = blocks[2 * i];
    layer.bias = blocks[2 * i + 1];
    return layer;
  }
};

// Activations of one batch. x is the normalised window; for each front-end
// layer, its convolution, pooled output and pooling argmax; `features` is
// fc1's input (x itself without a front end).
struct Activations {
  int n = 0;
  std::vector<double> x, features, z1, h1, z2, h2, z3;
  std::vector<std::vector<double>> conv_pre, conv_out;
  std::vector<std::vector<int>> conv_argmax;
  void Resize(int rows, int fan_in) {
    n = rows;
    x.resize(static_cast<size_t>(rows) * kHapticInputs);
    features.resize(static_cast<size_t>(rows) * fan_in);
    z1.resize(static_cast<size_t>(rows) * kHapticHidden);
    h1.resize(z1.size());
    z2.resize(z1.size());
    h2.resize(z1.size());
    z3.resize(static_cast<size_t>(rows) * kHapticClasses);
  }
};

void Forward(const Parameters& params, const std::vector<ConvLayer>& conv,
             Activations& act) {
  const int n = act.n;
  const int fan_in = params.FanIn();
  const double* input = act.x.data();
  if (!conv.empty()) {
    act.conv_pre.resize(conv.size());
    act.conv_out.resize(conv.size());
    act.conv_argmax.resize(conv.size());
    int length = kWindowPoints;
    for (size_t i = 0; i < conv.size(); ++i) {
      const ConvLayer& layer = conv[i];
      const size_t in_size = static_cast<size_t>(layer.in_channels) * length;
      const size_t pre_size = static_cast<size_t>(layer.out_channels) * length;
      const size_t out_size = pre_size / 2;
      act.conv_pre[i].resize(n * pre_size);
      act.conv_out[i].resize(n * out_size);
      act.conv_argmax[i].resize(n * out_size);
      for (int r = 0; r < n; ++r) {
        ConvForward(layer, input + r * in_size, length,
                    act.conv_pre[i].data() + r * pre_size,
                    act.conv_out[i].data() + r * out_size,
                    act.conv_argmax[i].data() + r * out_size);
      }
      input = act.conv_out[i].data();
      length /= 2;
    }
    std::copy(act.conv_out.back().begin(), act.conv_out.back().end(),
              act.features.begin());
  } else {
    std::copy(act.x.begin(), act.x.end(), act.features.begin());
  }
  MatMul(act.features.data(), params.blocks[params.Fc(0)].data(), n, fan_in,
         kHapticHidden, act.z1.data());
  AddBias(params.blocks[params.Fc(0) + 1], n, act.z1.data());
  for (size_t i = 0; i < act.z1.size(); ++i) {
    act.h1[i] = std::max(act.z1[i], 0.0);
  }
  MatMul(act.h1.data(), params.blocks[params.Fc(1)].data(), n, kHapticHidden,
         kHapticHidden, act.z2.data());
  AddBias(params.blocks[params.Fc(1) + 1], n, act.z2.data());
  for (size_t i = 0; i < act.z2.size(); ++i) {
    act.h2[i] = std::max(act.z2[i], 0.0);
  }
  MatMul(act.h2.data(), params.blocks[params.Fc(2)].data(), n, kHapticHidden,
         kHapticClasses, act.z3.data());
  AddBias(params.blocks[params.Fc(2) + 1], n, act.z3.data());
}

// Back through front-end layer `i` of a batch: `d_out` is the gradient of
// its pooled output; accumulates its kernel's and bias's gradients into
// `d_weight` and `d_bias` and, if `d_in` is not null, writes the gradient of
// its input. Every sum runs in a fixed order.
void ConvBackward(const ConvLayer& layer, int length, int n,
                  const double* input, const std::vector<double>& pre,
                  const std::vector<int>& argmax, const double* d_out,
                  std::vector<double>& d_weight, std::vector<double>& d_bias,
                  double* d_in) {
  const int outs = layer.out_channels, ins = layer.in_channels;
  const size_t pre_size = static_cast<size_t>(outs) * length;
  const size_t out_size = pre_size / 2;
  const size_t in_size = static_cast<size_t>(ins) * length;
  std::vector<double> d_pre(pre_size);
  std::fill(d_weight.begin(), d_weight.end(), 0.0);
  std::fill(d_bias.begin(), d_bias.end(), 0.0);
  for (int r = 0; r < n; ++r) {
    // Through the pooling (to the point it took) and the ReLU.
    std::fill(d_pre.begin(), d_pre.end(), 0.0);
    const double* z = pre.data() + r * pre_size;
    for (size_t j = 0; j < out_size; ++j) {
      const int from = argmax[r * out_size + j];
      if (z[from] > 0.0) d_pre[from] = d_out[r * out_size + j];
    }
    const double* x = input + r * in_size;
    for (int co = 0; co < outs; ++co) {
      const double* g = d_pre.data() + static_cast<size_t>(co) * length;
      double sum = 0.0;
      for (int l = 0; l < length; ++l) sum += g[l];
      d_bias[co] += sum;
    }
    for (int ci = 0; ci < ins; ++ci) {
      for (int t = 0; t < kConvKernel; ++t) {
        const auto [shift, begin, end] = SpanOf(t, length);
        const double* xc = x + static_cast<size_t>(ci) * length;
        double* dw =
            d_weight.data() + static_cast<size_t>(ci * kConvKernel + t) * outs;
        for (int co = 0; co < outs; ++co) {
          const double* g = d_pre.data() + static_cast<size_t>(co) * length;
          double sum = 0.0;
          for (int l = begin; l < end; ++l) sum += g[l] * xc[l + shift];
          dw[co] += sum;
        }
      }
    }
    if (d_in != nullptr) {
      double* dx = d_in + r * in_size;
      std::fill(dx, dx + in_size, 0.0);
      for (int ci = 0; ci < ins; ++ci) {
        for (int t = 0; t < kConvKernel; ++t) {
          const auto [shift, begin, end] = SpanOf(t, length);
          const double* w = layer.weight.data() +
                            static_cast<size_t>(ci * kConvKernel + t) * outs;
          double* dxc = dx + static_cast<size_t>(ci) * length;
          for (int co = 0; co < outs; ++co) {
            const double w_co = w[co];
            const double* g = d_pre.data() + static_cast<size_t>(co) * length;
            for (int l = begin; l < end; ++l) dxc[l + shift] += w_co * g[l];
          }
        }
      }
    }
  }
}

// log-softmax of one row of logits scaled by 1 / temperature.
std::array<double, kHapticClasses> LogSoftmax(const double* logits,
                                              double temperature) {
  std::array<double, kHapticClasses> out;
  double max_logit = logits[0] / temperature;
  for (int k = 0; k < kHapticClasses; ++k) {
    out[k] = logits[k] / temperature;
    max_logit = std::max(max_logit, out[k]);
  }
  double sum = 0.0;
  for (int k = 0; k < kHapticClasses; ++k) sum += std::exp(out[k] - max_logit);
  const double log_sum = max_logit + std::log(sum);
  for (int k = 0; k < kHapticClasses; ++k) out[k] -= log_sum;
  return out;
}

// The gradient of the batch's mean smoothed cross-entropy (act holds the
// batch after Forward; labels(r) is row r's class) with respect to every
// block of `params`, into `gradient`. Returns the batch's summed loss.
double Backward(const Parameters& params, const std::vector<ConvLayer>& conv,
                const Activations& act, const std::function<int(int)>& labels,
                double smoothing, Parameters& gradient) {
  const int n = act.n;
  const int fan_in = params.FanIn();
  const int fc1 = params.Fc(0), fc2 = params.Fc(1), fc3 = params.Fc(2);
  double loss = 0.0;
  // dLoss/dz3 = (softmax - target) / n, the target being the smoothed
  // one-hot vector.
  std::vector<double> g3(static_cast<size_t>(n) * kHapticClasses, 0.0);
  for (int r = 0; r < n; ++r) {
    const int label = labels(r);
    const auto log_p = LogSoftmax(&act.z3[r * kHapticClasses], 1.0);
    for (int k = 0; k < kHapticClasses; ++k) {
      const double target =
          (k == label ? 1.0 - smoothing : 0.0) + smoothing / kHapticClasses;
      loss -= target * log_p[k];
      g3[r * kHapticClasses + k] = (std::exp(log_p[k]) - target) / n;
    }
  }
  MatTMul(act.h2.data(), g3.data(), n, kHapticHidden, kHapticClasses,
          gradient.blocks[fc3].data());
  ColumnSums(g3.data(), n, kHapticClasses, gradient.blocks[fc3 + 1]);
  std::vector<double> dh2(static_cast<size_t>(n) * kHapticHidden);
  MatMulT(g3.data(), params.blocks[fc3].data(), n, kHapticClasses,
          kHapticHidden, dh2.data());
  for (size_t i = 0; i < dh2.size(); ++i) {
    if (act.z2[i] <= 0.0) dh2[i] = 0.0;
  }
  MatTMul(act.h1.data(), dh2.data(), n, kHapticHidden, kHapticHidden,
          gradient.blocks[fc2].data());
  ColumnSums(dh2.data(), n, kHapticHidden, gradient.blocks[fc2 + 1]);
  std::vector<double> dh1(dh2.size());
  MatMulT(dh2.data(), params.blocks[fc2].data(), n, kHapticHidden,
          kHapticHidden, dh1.data());
  for (size_t i = 0; i < dh1.size(); ++i) {
    if (act.z1[i] <= 0.0) dh1[i] = 0.0;
  }
  MatTMul(act.features.data(), dh1.data(), n, fan_in, kHapticHidden,
          gradient.blocks[fc1].data());
  ColumnSums(dh1.data(), n, kHapticHidden, gradient.blocks[fc1 + 1]);
  if (params.conv_layers > 0) {
    std::vector<double> d_out(static_cast<size_t>(n) * fan_in), d_in;
    MatMulT(dh1.data(), params.blocks[fc1].data(), n, kHapticHidden, fan_in,
            d_out.data());
    for (int i = params.conv_layers - 1; i >= 0; --i) {
      const int length = kWindowPoints >> i;
      const double* input = i == 0 ? act.x.data() : act.conv_out[i - 1].data();
      if (i > 0) {
        d_in.resize(static_cast<size_t>(n) * conv[i].in_channels * length);
      }
      ConvBackward(conv[i], length, n, input, act.conv_pre[i],
                   act.conv_argmax[i], d_out.data(), gradient.blocks[2 * i],
                   gradient.blocks[2 * i + 1], i > 0 ? d_in.data() : nullptr);
      if (i > 0) d_out.swap(d_in);
    }
  }
  return loss;
}

// Normalised inputs of `rows` windows into act.x.
void LoadBatch(const LabelledWindows& data, const std::vector<int>& order,
               int begin, int rows, const HapticNetWeights& norm, int fan_in,
               Activations& act) {
  act.Resize(rows, fan_in);
  for (int r = 0; r < rows; ++r) {
    const auto& window = data.inputs[order[begin + r]];
    double* x = act.x.data() + static_cast<size_t>(r) * kHapticInputs;
    for (int i = 0; i < kHapticInputs; ++i) {
      x[i] = (window[i] - norm.input_mean[i]) / norm.input_stddev[i];
    }
  }
}

// Logits of every window of `data`, in order.
std::vector<double> AllLogits(const LabelledWindows& data,
                              const Parameters& params,
                              const HapticNetWeights& norm) {
  std::vector<ConvLayer> conv;
  for (int i = 0; i < params.conv_layers; ++i) conv.push_back(params.Conv(i));
  const int total = static_cast<int>(data.inputs.size());
  std::vector<int> order(total);
  std::iota(order.begin(), order.end(), 0);
  std::vector<double> logits(static_cast<size_t>(total) * kHapticClasses);
  Activations act;
  constexpr int kChunk = 256;
  for (int begin = 0; begin < total; begin += kChunk) {
    const int rows = std::min(kChunk, total - begin);
    LoadBatch(data, order, begin, rows, norm, params.FanIn(), act);
    Forward(params, conv, act);
    std::copy(act.z3.begin(), act.z3.end(),
              logits.begin() + static_cast<size_t>(begin) * kHapticClasses);
  }
  return logits;
}

double MeanLogLoss(const std::vector<double>& logits,
                   const std::vector<int>& labels, double temperature) {
  double sum = 0.0;
  for (size_t i = 0; i < labels.size(); ++i) {
    sum -= LogSoftmax(&logits[i * kHapticClasses], temperature)[labels[i]];
  }
  return sum / labels.size();
}

double Accuracy(const std::vector<double>& logits,
                const std::vector<int>& labels) {
  int correct = 0;
  for (size_t i = 0; i < labels.size(); ++i) {
    const double* row = &logits[i * kHapticClasses];
    correct += std::max_element(row, row + kHapticClasses) - row == labels[i];
  }
  return static_cast<double>(correct) / labels.size();
}

absl::Status CheckSet(const LabelledWindows& data, const char* name) {
  if (data.inputs.empty()) {
    return absl::InvalidArgumentError(absl::StrCat(name, ": no windows"));
  }
  if (data.inputs.size() != data.labels.size()) {
    return absl::InvalidArgumentError(
        absl::StrCat(name, ": ", data.inputs.size(), " windows but ",
                     data.labels.size(), " labels"));
  }
  for (size_t i = 0; i < data.labels.size(); ++i) {
    if (data.labels[i] < 0 || data.labels[i] >= kHapticClasses) {
      return absl::InvalidArgumentError(
          absl::StrCat(name, ": label ", data.labels[i], " of window ", i,
                       " is outside 0..", kHapticClasses - 1));
    }
  }
  return absl::OkStatus();
}

// Per-channel mean and standard deviation over all training windows,
// spread to the 64 inputs of each channel and rounded to float so that
// training normalises exactly as the exported graph will.
void FitNormalisation(const LabelledWindows& train, HapticNetWeights& norm) {
  for (int c = 0; c < kWrenchChannels; ++c) {
    double sum = 0.0;
    for (const auto& window : train.inputs) {
      for (int k = 0; k < kWindowPoints; ++k) {
        sum += window[c * kWindowPoints + k];
      }
    }
    const double count =
        static_cast<double>(train.inputs.size()) * kWindowPoints;
    const double mean = sum / count;
    double squares = 0.0;
    for (const auto& window : train.inputs) {
      for (int k = 0; k < kWindowPoints; ++k) {
        const double d = window[c * kWindowPoints + k] - mean;
        squares += d * d;
      }
    }
    // A constant channel would divide by zero; 1e-6 of a newton or
    // newton-metre is far below the sensor's resolution.
    const double stddev = std::max(std::sqrt(squares / count), 1e-6);
    for (int k = 0; k < kWindowPoints; ++k) {
      norm.input_mean[c * kWindowPoints + k] = static_cast<float>(mean);
      norm.input_stddev[c * kWindowPoints + k] = static_cast<float>(stddev);
    }
  }
}

}  // namespace

absl::StatusOr<TrainingResult> TrainHapticNet(
    const LabelledWindows& train, const LabelledWindows& validation,
    const TrainerOptions& options,
    const std::function<void(const EpochLog&)>& on_epoch) {
  if (absl::Status s = CheckSet(train, "training set"); !s.ok()) return s;
  if (absl::Status s = CheckSet(validation, "validation set"); !s.ok()) {
    return s;
  }
  if (options.batch_size < 1 || options.max_epochs < 1 ||
      options.patience < 1 || !(options.learning_rate > 0.0) ||
      !(options.weight_decay >= 0.0) || !(options.label_smoothing >= 0.0) ||
      !(options.label_smoothing < 1.0) || !(options.min_temperature > 0.0) ||
      !(options.max_temperature >= options.min_temperature)) {
    return absl::InvalidArgumentError(
        "trainer options: batch_size, max_epochs and patience must be >= 1, "
        "learning_rate > 0, weight_decay >= 0, label_smoothing in [0, 1) and "
        "0 < min_temperature <= max_temperature");
  }

  TrainingResult result;
  absl::StatusOr<HapticNetWeights> shaped =
      WeightsWithFrontEnd(options.conv_channels);
  if (!shaped.ok()) return shaped.status();
  result.weights = *std::move(shaped);
  HapticNetWeights& norm = result.weights;
  FitNormalisation(train, norm);

  std::mt19937_64 rng(options.seed);
  Parameters params(norm.conv);
  {
    // He initialisation for ReLU layers; biases start at zero.
    random::Normal normal;
    for (size_t b = 0; b < params.blocks.size(); b += 2) {
      const double scale = std::sqrt(2.0 / params.rows[b]);
      for (double& w : params.blocks[b]) w = scale * normal(rng);
    }
  }
  Parameters first_moment(norm.conv), second_moment(norm.conv),
      gradient(norm.conv);
  const int fan_in = params.FanIn();
  const int fc1 = params.Fc(0), fc2 = params.Fc(1), fc3 = params.Fc(2);
  std::vector<ConvLayer> conv(params.conv_layers);
  Parameters best = params;
  double best_loss = INFINITY;
  int since_best = 0;

  const int total = static_cast<int>(train.inputs.size());
  std::vector<int> order(total);
  std::iota(order.begin(), order.end(), 0);
  Activations act;
  constexpr double kBeta1 = 0.9, kBeta2 = 0.999, kEpsilon = 1e-8;
  int64_t step = 0;
  const double smoothing = options.label_smoothing;

  for (int epoch = 1; epoch <= options.max_epochs; ++epoch) {
    // Fisher-Yates with the raw engine, so the order does not depend on the
    // standard library's distribution algorithms.
    for (int i = total - 1; i > 0; --i) {
      std::swap(order[i], order[rng() % static_cast<uint64_t>(i + 1)]);
    }
    double epoch_loss = 0.0;
    for (int begin = 0; begin < total; begin += options.batch_size) {
      const int n = std::min(options.batch_size, total - begin);
      LoadBatch(train, order, begin, n, norm, fan_in, act);
      for (int i = 0; i < params.conv_layers; ++i) conv[i] = params.Conv(i);
      Forward(params, conv, act);
      const auto labels_at = [&](int r) {
        return train.labels[order[begin + r]];
      };
      epoch_loss += Backward(params, conv, act, labels_at, smoothing, gradient);
      ++step;
      const double correction1 = 1.0 - std::pow(kBeta1, step);
      const double correction2 = 1.0 - std::pow(kBeta2, step);
      for (size_t b = 0; b < params.blocks.size(); ++b) {
        const bool is_weight = b % 2 == 0;
        std::vector<double>& w = params.blocks[b];
        std::vector<double>& g = gradient.blocks[b];
        std::vector<double>& m = first_moment.blocks[b];
        std::vector<double>& v = second_moment.blocks[b];
        for (size_t i = 0; i < w.size(); ++i) {
          const double grad =
              g[i] + (is_weight ? options.weight_decay * w[i] : 0.0);
          m[i] = kBeta1 * m[i] + (1.0 - kBeta1) * grad;
          v[i] = kBeta2 * v[i] + (1.0 - kBeta2) * grad * grad;
          w[i] -= options.learning_rate * (m[i] / correction1) /
                  (std::sqrt(v[i] / correction2) + kEpsilon);
        }
      }
    }
    const std::vector<double> logits = AllLogits(validation, params, norm);
    EpochLog log;
    log.epoch = epoch;
    log.train_loss = epoch_loss / total;
    log.validation_loss = MeanLogLoss(logits, validation.labels, 1.0);
    log.validation_accuracy = Accuracy(logits, validation.labels);
    result.epochs.push_back(log);
    if (on_epoch) on_epoch(log);
    if (log.validation_loss < best_loss) {
      best_loss = log.validation_loss;
      best = params;
      result.best_epoch = epoch;
      since_best = 0;
    } else if (++since_best >= options.patience) {
      break;
    }
  }

  if (options.calibrate_temperature) {
    // Grid search in steps of 0.01 rather than an optimiser: a handful of
    // exp() per window and point, and trivially reproducible.
    const std::vector<double> logits = AllLogits(validation, best, norm);
    const int first =
        static_cast<int>(std::ceil(options.min_temperature * 100));
    const int last =
        static_cast<int>(std::floor(options.max_temperature * 100));
    double best_nll = INFINITY;
    result.temperature = first / 100.0;
    for (int i = first; i <= last; ++i) {
      const double temperature = i / 100.0;
      const double nll = MeanLogLoss(logits, validation.labels, temperature);
      if (nll < best_nll) {
        best_nll = nll;
        result.temperature = temperature;
      }
    }
    for (double& w : best.blocks[fc3]) w /= result.temperature;
    for (double& w : best.blocks[fc3 + 1]) w /= result.temperature;
  }

  auto copy = [](const std::vector<double>& from, auto& to) {
    std::copy(from.begin(), from.end(), to.data());
  };
  for (int i = 0; i < best.conv_layers; ++i) {
    result.weights.conv[i].weight = best.blocks[2 * i];
    result.weights.conv[i].bias = best.blocks[2 * i + 1];
  }
  copy(best.blocks[fc1], result.weights.w1);
  copy(best.blocks[fc1 + 1], result.weights.b1);
  copy(best.blocks[fc2], result.weights.w2);
  copy(best.blocks[fc2 + 1], result.weights.b2);
  copy(best.blocks[fc3], result.weights.w3);
  copy(best.blocks[fc3 + 1], result.weights.b3);
  RoundToFloat(result.weights);
  return result;
}

absl::StatusOr<LossGradient> SmoothedLossGradient(
    const HapticNetWeights& weights, const LabelledWindows& data,
    double label_smoothing) {
  if (absl::Status s = CheckSet(data, "data"); !s.ok()) return s;
  if (weights.w1.rows() != FrontEndOutputs(weights.conv)) {
    return absl::InvalidArgumentError(absl::StrCat(
        "w1 has ", weights.w1.rows(), " rows; the front end gives ",
        FrontEndOutputs(weights.conv)));
  }
  Parameters params(weights.conv);
  for (size_t i = 0; i < weights.conv.size(); ++i) {
    params.blocks[2 * i] = weights.conv[i].weight;
    params.blocks[2 * i + 1] = weights.conv[i].bias;
  }
  const std::array<const double*, 6> dense = {
      weights.w1.data(), weights.b1.data(), weights.w2.data(),
      weights.b2.data(), weights.w3.data(), weights.b3.data()};
  for (int b = 0; b < 6; ++b) {
    std::vector<double>& block = params.blocks[params.Fc(0) + b];
    std::copy(dense[b], dense[b] + block.size(), block.begin());
  }
  const int n = static_cast<int>(data.inputs.size());
  std::vector<int> order(n);
  std::iota(order.begin(), order.end(), 0);
  Activations act;
  LoadBatch(data, order, 0, n, weights, params.FanIn(), act);
  Forward(params, weights.conv, act);
  Parameters gradient(weights.conv);
  LossGradient out;
  out.loss =
      Backward(
          params, weights.conv, act, [&](int r) { return data.labels[r]; },
          label_smoothing, gradient) /
      n;
  out.gradient = weights;
  for (size_t i = 0; i < weights.conv.size(); ++i) {
    out.gradient.conv[i].weight = gradient.blocks[2 * i];
    out.gradient.conv[i].bias = gradient.blocks[2 * i + 1];
  }
  const std::array<double*, 6> into = {
      out.gradient.w1.data(), out.gradient.b1.data(), out.gradient.w2.data(),
      out.gradient.b2.data(), out.gradient.w3.data(), out.gradient.b3.data()};
  for (int b = 0; b < 6; ++b) {
    const std::vector<double>& block = gradient.blocks[params.Fc(0) + b];
    std::copy(block.begin(), block.end(), into[b]);
  }
  return out;
}

int ConfusionMatrix::Total() const {
  int total = 0;
  for (const auto& row : counts) {
    for (int c : row) total += c;
  }
  return total;
}

double ConfusionMatrix::Accuracy() const {
  int correct = 0;
  for (int k = 0; k < kHapticClasses; ++k) correct += counts[k][k];
  const int total = Total();
  return total == 0 ? 0.0 : static_cast<double>(correct) / total;
}

double ConfusionMatrix::Recall(int true_class) const {
  int row_total = 0;
  for (int p = 0; p < kHapticClasses; ++p) row_total += counts[true_class][p];
  return row_total == 0
             ? 0.0
             : static_cast<double>(counts[true_class][true_class]) / row_total;
}

std::string ConfusionMatrix::ToString() const {
  std::string out = absl::StrFormat("%-12s", "true\\pred");
  for (int k = 0; k < kHapticClasses; ++k) {
    absl::StrAppendFormat(&out, "%10s",
                          HapticClassName(static_cast<HapticClass>(k)));
  }
  absl::StrAppend(&out, "    recall\n");
  for (int t = 0; t < kHapticClasses; ++t) {
    absl::StrAppendFormat(&out, "%-12s",
                          HapticClassName(static_cast<HapticClass>(t)));
    for (int p = 0; p < kHapticClasses; ++p) {
      absl::StrAppendFormat(&out, "%10d", counts[t][p]);
    }
    absl::StrAppendFormat(&out, "%9.1f%%\n", 100.0 * Recall(t));
  }
  absl::StrAppendFormat(&out, "accuracy %.2f%% of %d\n", 100.0 * Accuracy(),
                        Total());
  return out;
}

ProbabilisticScore ScorePredictions(
    const std::vector<std::array<double, kHapticClasses>>& probabilities,
    const std::vector<int>& labels) {
  ProbabilisticScore score;
  constexpr int kBins = 10;
  std::array<double, kBins> confidence{}, correct{};
  std::array<int, kBins> count{};
  std::array<double, kHapticClasses> top_sum{}, right{};
  std::array<int, kHapticClasses> of_class{};
  for (size_t i = 0; i < labels.size(); ++i) {
    const auto& p = probabilities[i];
    const int predicted =
        static_cast<int>(std::max_element(p.begin(), p.end()) - p.begin());
    ++score.confusion.counts[labels[i]][predicted];
    top_sum[labels[i]] += p[predicted];
    right[labels[i]] += predicted == labels[i] ? 1.0 : 0.0;
    ++of_class[labels[i]];
    // Clamped so one impossible-looking miss does not make the mean infinite.
    score.mean_log_loss -= std::log(std::max(p[labels[i]], 1e-12));
    const int bin = std::min(static_cast<int>(p[predicted] * kBins), kBins - 1);
    confidence[bin] += p[predicted];
    correct[bin] += predicted == labels[i] ? 1.0 : 0.0;
    ++count[bin];
  }
  if (!labels.empty()) {
    score.mean_log_loss /= labels.size();
    for (int b = 0; b < kBins; ++b) {
      score.expected_calibration_error +=
          std::abs(confidence[b] - correct[b]) / labels.size();
    }
  }
  for (int k = 0; k < kHapticClasses; ++k) {
    if (of_class[k] > 0) {
      score.overconfidence[k] = (top_sum[k] - right[k]) / of_class[k];
    }
  }
  return score;
}

}  // namespace bitewise::haptic
