#include "services/camera/realsense_source.h"

#include <dlfcn.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "services/camera/realsense_api.h"
#include "services/common/status_macros.h"

namespace bitewise::camera {

using namespace rs2;  // NOLINT: the SDK's names, as in its own headers

struct RealSenseSource::Api {
  void* handle = nullptr;
  CreateContextFn create_context;
  DeleteContextFn delete_context;
  CreatePipelineFn create_pipeline;
  DeletePipelineFn delete_pipeline;
  CreateConfigFn create_config;
  DeleteConfigFn delete_config;
  ConfigEnableStreamFn config_enable_stream;
  PipelineStartWithConfigFn pipeline_start_with_config;
  PipelineStopFn pipeline_stop;
  DeletePipelineProfileFn delete_pipeline_profile;
  PipelineWaitForFramesFn pipeline_wait_for_frames;
  EmbeddedFramesCountFn embedded_frames_count;
  ExtractFrameFn extract_frame;
  ReleaseFrameFn release_frame;
  GetFrameStreamProfileFn get_frame_stream_profile;
  GetStreamProfileDataFn get_stream_profile_data;
  GetVideoStreamIntrinsicsFn get_video_stream_intrinsics;
  GetFrameDataFn get_frame_data;
  GetFrameIntFn get_frame_width;
  GetFrameIntFn get_frame_height;
  GetFrameIntFn get_frame_stride_in_bytes;
  GetFrameNumberFn get_frame_number;
  DepthFrameGetUnitsFn depth_frame_get_units;
  CreateAlignFn create_align;
  DeleteProcessingBlockFn delete_processing_block;
  CreateFrameQueueFn create_frame_queue;
  DeleteFrameQueueFn delete_frame_queue;
  StartProcessingQueueFn start_processing_queue;
  ProcessFrameFn process_frame;
  WaitForFrameFn wait_for_frame;
  GetErrorMessageFn get_error_message;
  FreeErrorFn free_error;

  ~Api() {
    if (handle != nullptr) dlclose(handle);
  }

  // The SDK's error, freed, as a status naming the call; OK if none.
  absl::Status Check(
      rs2_error* error, const char* call,
      absl::StatusCode code = absl::StatusCode::kFailedPrecondition) const {
    if (error == nullptr) return absl::OkStatus();
    const char* message = get_error_message(error);
    absl::Status status(code, absl::StrCat("RealSense ", call, ": ",
                                           message ? message : "(no message)"));
    free_error(error);
    return status;
  }
};

struct RealSenseSource::Handles {
  const Api* api = nullptr;
  rs2_context* context = nullptr;
  rs2_pipeline* pipeline = nullptr;
  rs2_config* config = nullptr;
  rs2_pipeline_profile* profile = nullptr;
  rs2_processing_block* align = nullptr;
  rs2_frame_queue* queue = nullptr;

  // Stops the streams if they run. The SDK may have stopped them itself
  // (a failed reconnect): stopping again is then an error of no
  // consequence.
  void StopStreams() {
    if (profile == nullptr) return;
    rs2_error* e = nullptr;
    api->pipeline_stop(pipeline, &e);
    if (e != nullptr) api->free_error(e);
    api->delete_pipeline_profile(profile);
    profile = nullptr;
  }

  ~Handles() {
    if (api == nullptr) return;
    StopStreams();
    if (align != nullptr) api->delete_processing_block(align);
    if (queue != nullptr) api->delete_frame_queue(queue);
    if (config != nullptr) api->delete_config(config);
    if (pipeline != nullptr) api->delete_pipeline(pipeline);
    if (context != nullptr) api->delete_context(context);
  }
};

namespace {

template <typename Fn>
absl::Status Resolve(void* handle, const std::string& library,
                     const char* symbol, Fn* out) {
  void* address = dlsym(handle, symbol);
  if (address == nullptr) {
    return absl::FailedPreconditionError(
        absl::StrCat("RealSense SDK \"", library, "\" has no function ", symbol,
                     " (not librealsense2, or older than 2.50?)"));
  }
  *out = reinterpret_cast<Fn>(address);
  return absl::OkStatus();
}

// Releases a frame when it goes out of scope.
class FrameRef {
 public:
  FrameRef(const RealSenseSource::Api* api, rs2_frame* frame)
      : api_(api), frame_(frame) {}
  ~FrameRef() {
    if (frame_ != nullptr) api_->release_frame(frame_);
  }
  FrameRef(const FrameRef&) = delete;
  FrameRef& operator=(const FrameRef&) = delete;
  rs2_frame* get() const { return frame_; }

 private:
  const RealSenseSource::Api* api_;
  rs2_frame* frame_;
};

}  // namespace

#define BITEWISE_RS2_RESOLVE(field, symbol) \
  RETURN_IF_ERROR(Resolve(api->handle, library, symbol, &api->field))

absl::StatusOr<std::unique_ptr<RealSenseSource>> RealSenseSource::Open(
    const RealSenseOptions& options) {
  if (options.width <= 0 || options.height <= 0 || options.fps <= 0 ||
      options.timeout_ms <= 0) {
    return absl::InvalidArgumentError(absl::StrCat(
        "RealSense: width, height, fps and timeout must be > 0 (got ",
        options.width, "x", options.height, " at ", options.fps, " fps)"));
  }
  auto api = std::make_unique<Api>();
  std::vector<std::string> candidates;
  if (options.library.empty()) {
    // The development symlink, then the run-time names (the SONAME is
    // librealsense2.so.2.<minor>), newest first.
    candidates = {"librealsense2.so"};
    for (int minor = 60; minor >= 50; --minor) {
      candidates.push_back(absl::StrCat("librealsense2.so.2.", minor));
    }
  } else {
    candidates = {options.library};
  }
  std::string library, errors;
  for (const std::string& candidate : candidates) {
    api->handle = dlopen(candidate.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (api->handle != nullptr) {
      library = candidate;
      break;
    }
    const char* why = dlerror();
    if (!options.library.empty()) errors = why ? why : candidate;
  }
  if (errors.empty()) {
    errors = "none of librealsense2.so, librealsense2.so.2.60 ... 2.50 found";
  }
  if (api->handle == nullptr) {
    return absl::NotFoundError(absl::StrCat(
        "cannot load the RealSense SDK (install librealsense2 or pass "
        "--realsense_library): ",
        errors));
  }
  BITEWISE_RS2_RESOLVE(create_context, "rs2_create_context");
  BITEWISE_RS2_RESOLVE(delete_context, "rs2_delete_context");
  BITEWISE_RS2_RESOLVE(create_pipeline, "rs2_create_pipeline");
  BITEWISE_RS2_RESOLVE(delete_pipeline, "rs2_delete_pipeline");
  BITEWISE_RS2_RESOLVE(create_config, "rs2_create_config");
  BITEWISE_RS2_RESOLVE(delete_config, "rs2_delete_config");
  BITEWISE_RS2_RESOLVE(config_enable_stream, "rs2_config_enable_stream");
  BITEWISE_RS2_RESOLVE(pipeline_start_with_config,
                       "rs2_pipeline_start_with_config");
  BITEWISE_RS2_RESOLVE(pipeline_stop, "rs2_pipeline_stop");
  BITEWISE_RS2_RESOLVE(delete_pipeline_profile, "rs2_delete_pipeline_profile");
  BITEWISE_RS2_RESOLVE(pipeline_wait_for_frames,
                       "rs2_pipeline_wait_for_frames");
  BITEWISE_RS2_RESOLVE(embedded_frames_count, "rs2_embedded_frames_count");
  BITEWISE_RS2_RESOLVE(extract_frame, "rs2_extract_frame");
  BITEWISE_RS2_RESOLVE(release_frame, "rs2_release_frame");
  BITEWISE_RS2_RESOLVE(get_frame_stream_profile,
                       "rs2_get_frame_stream_profile");
  BITEWISE_RS2_RESOLVE(get_stream_profile_data, "rs2_get_stream_profile_data");
  BITEWISE_RS2_RESOLVE(get_video_stream_intrinsics,
                       "rs2_get_video_stream_intrinsics");
  BITEWISE_RS2_RESOLVE(get_frame_data, "rs2_get_frame_data");
  BITEWISE_RS2_RESOLVE(get_frame_width, "rs2_get_frame_width");
  BITEWISE_RS2_RESOLVE(get_frame_height, "rs2_get_frame_height");
  BITEWISE_RS2_RESOLVE(get_frame_stride_in_bytes,
                       "rs2_get_frame_stride_in_bytes");
  BITEWISE_RS2_RESOLVE(get_frame_number, "rs2_get_frame_number");
  BITEWISE_RS2_RESOLVE(depth_frame_get_units, "rs2_depth_frame_get_units");
  BITEWISE_RS2_RESOLVE(create_align, "rs2_create_align");
  BITEWISE_RS2_RESOLVE(delete_processing_block, "rs2_delete_processing_block");
  BITEWISE_RS2_RESOLVE(create_frame_queue, "rs2_create_frame_queue");
  BITEWISE_RS2_RESOLVE(delete_frame_queue, "rs2_delete_frame_queue");
  BITEWISE_RS2_RESOLVE(start_processing_queue, "rs2_start_processing_queue");
  BITEWISE_RS2_RESOLVE(process_frame, "rs2_process_frame");
  BITEWISE_RS2_RESOLVE(wait_for_frame, "rs2_wait_for_frame");
  BITEWISE_RS2_RESOLVE(get_error_message, "rs2_get_error_message");
  BITEWISE_RS2_RESOLVE(free_error, "rs2_free_error");

  auto h = std::make_unique<Handles>();
  h->api = api.get();
  rs2_error* e = nullptr;
  h->context = api->create_context(kApiVersion, &e);
  RETURN_IF_ERROR(api->Check(e, "rs2_create_context"));
  h->pipeline = api->create_pipeline(h->context, &e);
  RETURN_IF_ERROR(api->Check(e, "rs2_create_pipeline"));
  h->config = api->create_config(&e);
  RETURN_IF_ERROR(api->Check(e, "rs2_create_config"));
  api->config_enable_stream(h->config, RS2_STREAM_COLOR, -1, options.width,
                            options.height, RS2_FORMAT_RGB8, options.fps, &e);
  RETURN_IF_ERROR(api->Check(e, "rs2_config_enable_stream (colour)"));
  api->config_enable_stream(h->config, RS2_STREAM_DEPTH, -1, options.width,
                            options.height, RS2_FORMAT_Z16, options.fps, &e);
  RETURN_IF_ERROR(api->Check(e, "rs2_config_enable_stream (depth)"));
  h->profile = api->pipeline_start_with_config(h->pipeline, h->config, &e);
  if (absl::Status s = api->Check(e, "rs2_pipeline_start_with_config");
      !s.ok()) {
    h->profile = nullptr;
    return s;
  }
  h->align = api->create_align(RS2_STREAM_COLOR, &e);
  RETURN_IF_ERROR(api->Check(e, "rs2_create_align"));
  h->queue = api->create_frame_queue(1, &e);
  RETURN_IF_ERROR(api->Check(e, "rs2_create_frame_queue"));
  api->start_processing_queue(h->align, h->queue, &e);
  RETURN_IF_ERROR(api->Check(e, "rs2_start_processing_queue"));
  return std::unique_ptr<RealSenseSource>(new RealSenseSource(
      std::move(api), std::move(h), options, std::move(library)));
}

#undef BITEWISE_RS2_RESOLVE

RealSenseSource::RealSenseSource(std::unique_ptr<Api> api,
                                 std::unique_ptr<Handles> handles,
                                 const RealSenseOptions& options,
                                 std::string library)
    : api_(std::move(api)),
      handles_(std::move(handles)),
      options_(options),
      library_(std::move(library)) {}

RealSenseSource::~RealSenseSource() {
  handles_.reset();  // before the library is closed
}

std::string RealSenseSource::name() const {
  return absl::StrCat("realsense:", library_);
}

absl::Status RealSenseSource::Restart() {
  const Api& api = *api_;
  handles_->StopStreams();
  rs2_error* e = nullptr;
  handles_->profile =
      api.pipeline_start_with_config(handles_->pipeline, handles_->config, &e);
  if (absl::Status s = api.Check(e, "rs2_pipeline_start_with_config",
                                 absl::StatusCode::kUnavailable);
      !s.ok()) {
    handles_->profile = nullptr;
    return absl::UnavailableError(
        absl::StrCat("restarting the streams after \"", restart_reason_,
                     "\": ", s.message()));
  }
  // The device may count its frames from 1 again, or go on: the first
  // frame after the restart is published as the one after the last.
  rebase_ = true;
  ++restarts_;
  return absl::OkStatus();
}

absl::StatusOr<domain::RgbdFrame> RealSenseSource::Next() {
  const Api& api = *api_;
  if (!restart_reason_.empty()) {
    RETURN_IF_ERROR(Restart());
    restart_reason_.clear();
  }
  rs2_error* e = nullptr;
  rs2_frame* frames = api.pipeline_wait_for_frames(
      handles_->pipeline, static_cast<unsigned>(options_.timeout_ms), &e);
  if (absl::Status s = api.Check(e, "rs2_pipeline_wait_for_frames",
                                 absl::StatusCode::kUnavailable);
      !s.ok()) {
    // A timeout or a lost device. After a failed reconnect the SDK leaves
    // the pipeline stopped and fails every later wait at once, so the next
    // call starts the streams again (and keeps trying until the camera is
    // back).
    restart_reason_ = std::string(s.message());
    return s;
  }
  const double capture_s = SteadyNowS();
  // The align block takes ownership of the frameset.
  api.process_frame(handles_->align, frames, &e);
  RETURN_IF_ERROR(api.Check(e, "rs2_process_frame"));
  FrameRef aligned(
      &api, api.wait_for_frame(handles_->queue,
                               static_cast<unsigned>(options_.timeout_ms), &e));
  RETURN_IF_ERROR(api.Check(e, "rs2_wait_for_frame (aligned)",
                            absl::StatusCode::kUnavailable));
  const int count = api.embedded_frames_count(aligned.get(), &e);
  RETURN_IF_ERROR(api.Check(e, "rs2_embedded_frames_count"));
  domain::RgbdFrame out;
  bool have_colour = false, have_depth = false;
  for (int i = 0; i < count; ++i) {
    FrameRef frame(&api, api.extract_frame(aligned.get(), i, &e));
    RETURN_IF_ERROR(api.Check(e, "rs2_extract_frame"));
    const rs2_stream_profile* profile =
        api.get_frame_stream_profile(frame.get(), &e);
    RETURN_IF_ERROR(api.Check(e, "rs2_get_frame_stream_profile"));
    rs2_stream stream = RS2_STREAM_ANY;
    rs2_format format = RS2_FORMAT_ANY;
    int index = 0, unique_id = 0, rate = 0;
    api.get_stream_profile_data(profile, &stream, &format, &index, &unique_id,
                                &rate, &e);
    RETURN_IF_ERROR(api.Check(e, "rs2_get_stream_profile_data"));
    const int width = api.get_frame_width(frame.get(), &e);
    const int height = e == nullptr ? api.get_frame_height(frame.get(), &e) : 0;
    const int stride =
        e == nullptr ? api.get_frame_stride_in_bytes(frame.get(), &e) : 0;
    const auto* data =
        e == nullptr
            ? static_cast<const uint8_t*>(api.get_frame_data(frame.get(), &e))
            : nullptr;
    RETURN_IF_ERROR(api.Check(e, "reading a frame"));
    if (width != options_.width || height != options_.height ||
        data == nullptr) {
      return absl::FailedPreconditionError(absl::StrCat(
          "RealSense: a ", stream == RS2_STREAM_DEPTH ? "depth" : "colour",
          " frame of ", width, "x", height, "; configured ", options_.width,
          "x", options_.height));
    }
    if (stream == RS2_STREAM_COLOR && format == RS2_FORMAT_RGB8) {
      rs2_intrinsics k{};
      api.get_video_stream_intrinsics(profile, &k, &e);
      RETURN_IF_ERROR(api.Check(e, "rs2_get_video_stream_intrinsics"));
      out.intrinsics = {width, height, k.fx, k.fy, k.ppx, k.ppy};
      const uint64_t number = api.get_frame_number(frame.get(), &e);
      RETURN_IF_ERROR(api.Check(e, "rs2_get_frame_number"));
      if (rebase_) {  // unsigned: wraps as it must
        sequence_offset_ = last_sequence_ + 1 - number;
        rebase_ = false;
      }
      out.sequence = sequence_offset_ + number;
      out.rgb.resize(static_cast<size_t>(width) * height * 3);
      for (int row = 0; row < height; ++row) {
        std::memcpy(&out.rgb[static_cast<size_t>(row) * width * 3],
                    data + static_cast<size_t>(row) * stride,
                    static_cast<size_t>(width) * 3);
      }
      have_colour = true;
    } else if (stream == RS2_STREAM_DEPTH && format == RS2_FORMAT_Z16) {
      const float units_m = api.depth_frame_get_units(frame.get(), &e);
      RETURN_IF_ERROR(api.Check(e, "rs2_depth_frame_get_units"));
      if (!(units_m > 0.0f) || !std::isfinite(units_m)) {
        return absl::FailedPreconditionError(absl::StrCat(
            "RealSense: depth units of ", units_m, " m are not usable"));
      }
      const double to_mm = 1000.0 * units_m;
      out.depth_mm.resize(static_cast<size_t>(width) * height);
      for (int row = 0; row < height; ++row) {
        const uint8_t* src = data + static_cast<size_t>(row) * stride;
        for (int col = 0; col < width; ++col) {
          uint16_t raw;
          std::memcpy(&raw, src + 2 * col, 2);
          const double mm = std::round(raw * to_mm);
          out.depth_mm[static_cast<size_t>(row) * width + col] =
              static_cast<uint16_t>(std::min(mm, 65535.0));
        }
      }
      have_depth = true;
    }
  }
  if (!have_colour || !have_depth) {
    return absl::FailedPreconditionError(
        absl::StrCat("RealSense: a frameset of ", count, " frames without ",
                     have_colour ? "" : "an RGB8 colour frame",
                     !have_colour && !have_depth ? " and " : "",
                     have_depth ? "" : "a Z16 depth frame"));
  }
  out.capture_s = capture_s;
  last_sequence_ = out.sequence;
  return out;
}

}  // namespace bitewise::camera
