// Writes the fuzzers' seed corpus (fuzz/corpus/<fuzzer>/) from the real
// encoders: valid inputs the fuzzers mutate from. Run once; the files are
// committed. Usage: make_seeds <fuzz/corpus>.
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "bitewise/v1/bandit.pb.h"
#include "bitewise/v1/haptic.pb.h"
#include "bitewise/v1/perception.pb.h"
#include "bitewise/v1/robot.pb.h"
#include "opencv2/core.hpp"
#include "opencv2/imgcodecs.hpp"
#include "services/robot/netft/rdt_protocol.h"

namespace {

void Write(const std::string& dir, const std::string& name,
           const std::string& bytes) {
  std::filesystem::create_directories(dir);
  std::ofstream(dir + "/" + name, std::ios::binary) << bytes;
}

template <typename T>
std::string Raw(const T& value) {
  return std::string(reinterpret_cast<const char*>(&value), sizeof(value));
}

std::string FrameHeader(uint16_t w, uint16_t h, uint8_t encoding,
                        uint32_t rgb_bytes) {
  std::string header = Raw(w) + Raw(h);
  header += static_cast<char>(encoding);
  header += static_cast<char>(1);  // fx valid
  header += static_cast<char>(2);  // cx
  header += static_cast<char>(1);  // cy
  return header + Raw(rgb_bytes);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: make_seeds <corpus dir>\n");
    return 2;
  }
  const std::string root = argv[1];
  using namespace bitewise;  // NOLINT: a main

  netft::RdtRecord record;
  record.rdt_sequence = 7;
  record.ft_sequence = 7000;
  record.counts = {100, -200, 3000, 4, -5, 6};
  const auto encoded = netft::EncodeRdtRecord(record);
  Write(root + "/rdt_fuzzer", "record",
        std::string(encoded.begin(), encoded.end()));
  Write(root + "/rdt_fuzzer", "request",
        std::string("\x12\x34\x00\x02\x00\x00\x00\x00", 8));

  const int w = 4, h = 3;
  std::string rgb(w * h * 3, '\0');
  for (size_t i = 0; i < rgb.size(); ++i) rgb[i] = static_cast<char>(i * 20);
  std::string depth;
  for (int i = 0; i < w * h; ++i) depth += Raw(static_cast<uint16_t>(400 + i));
  Write(root + "/frame_fuzzer", "rgb8",
        FrameHeader(w, h, 1, static_cast<uint32_t>(rgb.size())) + rgb + depth);
  cv::Mat image(h, w, CV_8UC3, rgb.data());
  for (const auto& [name, ext, encoding] :
       {std::tuple{"png", ".png", 2}, std::tuple{"jpeg", ".jpg", 3}}) {
    std::vector<uint8_t> buffer;
    cv::imencode(ext, image, buffer);
    const std::string file(buffer.begin(), buffer.end());
    Write(root + "/frame_fuzzer", name,
          FrameHeader(w, h, static_cast<uint8_t>(encoding),
                      static_cast<uint32_t>(file.size())) +
              file + depth);
  }

  std::string trace;
  for (int i = 0; i < 200; ++i) {
    const double t = i * 1e-3;
    const double fz = t < 0.1 ? 0.01 : 40.0 * (t - 0.1);
    for (double v : {t, 0.01, -0.02, fz, 0.001, 0.0, 0.0}) trace += Raw(v);
  }
  Write(root + "/trace_fuzzer", "contact_ramp", trace);

  v1::CreateUserRequest create;
  create.set_user_id("alice");
  create.mutable_config()->set_context_dim(3);
  Write(root + "/request_fuzzer", "create_user",
        std::string(1, '\0') + create.SerializeAsString());
  v1::SelectRequest select;
  select.set_user_id("alice");
  for (double c : {0.1, 0.2, 0.3}) select.add_context(c);
  Write(root + "/request_fuzzer", "select",
        std::string(1, '\1') + select.SerializeAsString());
  v1::UpdateRequest update;
  update.set_event_id("12");
  update.set_loss(1.0);
  for (double p : {-4.6, -0.03, -4.6, -4.6}) update.add_posthoc(p);
  Write(root + "/request_fuzzer", "update",
        std::string(1, '\2') + update.SerializeAsString());
  v1::DetectFoodRequest detect;
  detect.mutable_frame()->set_width(w);
  detect.mutable_frame()->set_height(h);
  detect.mutable_frame()->set_rgb_encoding(v1::IMAGE_ENCODING_RGB8);
  detect.mutable_frame()->set_rgb(rgb);
  detect.mutable_frame()->set_depth_mm(depth);
  detect.mutable_frame()->mutable_intrinsics()->set_fx(615);
  detect.mutable_frame()->mutable_intrinsics()->set_fy(615);
  Write(root + "/request_fuzzer", "detect_food",
        std::string(1, '\3') + detect.SerializeAsString());
  v1::ClassifyRequest classify;
  for (int i = 0; i < 20; ++i) {
    auto* s = classify.add_samples();
    s->set_t_s(i * 1e-3);
    s->set_fz_n(i < 10 ? 0.0 : 5.0);
  }
  Write(root + "/request_fuzzer", "classify",
        std::string(1, '\4') + classify.SerializeAsString());
  v1::AcquireRequest acquire;
  acquire.set_action(2);
  Write(root + "/request_fuzzer", "acquire",
        std::string(1, '\5') + acquire.SerializeAsString());
  return 0;
}
