// A fake RealSense SDK 2.0 shared library for the RealSenseSource tests:
// the hardware boundary, so a fake is legitimate here. It exports the C
// functions the driver resolves, with the types of
// services/camera/realsense_api.h, and behaves as the SDK documents them:
// errors through rs2_error** (freed by rs2_free_error), framesets whose
// extracted frames are new references to release, an align block that
// takes ownership of the frameset it is given and delivers it on a frame
// queue. Frames are a deterministic pattern: colour (x, y, 7 * number) mod
// 256, depth a plane at 400 mm with a 20 mm step on the right half, in the
// configured depth units. The test steers it and reads what happened
// through the FakeRealSense_* functions (found with dlsym).
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "services/camera/realsense_api.h"

#define EXPORT extern "C" __attribute__((visibility("default")))

// The SDK's opaque types, completed here as the fake's own.
namespace bitewise::camera::rs2 {

struct rs2_error {
  std::string message;
};
struct rs2_context {};
struct rs2_config {
  int width = 0, height = 0, fps = 0;
  bool colour = false, depth = false;
};
struct rs2_pipeline {
  rs2_config config;
  bool started = false;
};
struct rs2_pipeline_profile {};
struct rs2_stream_profile {
  rs2_stream stream = RS2_STREAM_ANY;
  rs2_format format = RS2_FORMAT_ANY;
  int width = 0, height = 0, fps = 0;
};
struct rs2_frame {
  int refs = 1;
  rs2_stream_profile profile;
  std::vector<uint8_t> data;
  int stride = 0;
  unsigned long long number = 0;  // NOLINT: the SDK's type
  float units = 0.001f;
  bool aligned = false;
  std::vector<rs2_frame*> children;  // a frameset
};
struct rs2_processing_block {
  rs2_frame_queue* queue = nullptr;
};
struct rs2_frame_queue {
  std::mutex mu;
  std::vector<rs2_frame*> frames;
};

}  // namespace bitewise::camera::rs2

using namespace bitewise::camera::rs2;  // NOLINT: the SDK's names

namespace {

std::mutex mu;
std::string calls;
bool no_device = false;
bool stalled = false;
int wait_calls = 0;
int start_calls = 0;
unsigned long long next_number = 1;  // NOLINT
float depth_units = 0.001f;
std::atomic<int> live_frames{0};
std::atomic<int> live_errors{0};

void Fail(rs2_error** error, const std::string& message) {
  ++live_errors;
  *error = new rs2_error{message};
}

void Record(const char* name) {
  std::lock_guard<std::mutex> lock(mu);
  calls += name;
  calls += ';';
}

rs2_frame* NewFrame() {
  ++live_frames;
  return new rs2_frame;
}

void Release(rs2_frame* frame) {
  if (frame == nullptr || --frame->refs > 0) return;
  for (rs2_frame* child : frame->children) Release(child);
  --live_frames;
  delete frame;
}

rs2_frame* MakeFrameset(const rs2_config& c,
                        unsigned long long number) {  // NOLINT
  rs2_frame* colour = NewFrame();
  colour->profile = {RS2_STREAM_COLOR, RS2_FORMAT_RGB8, c.width, c.height,
                     c.fps};
  colour->stride = c.width * 3 + 16;  // padded rows, as USB frames can be
  colour->data.assign(static_cast<size_t>(colour->stride) * c.height, 0xEE);
  colour->number = number;
  for (int y = 0; y < c.height; ++y) {
    for (int x = 0; x < c.width; ++x) {
      uint8_t* p =
          &colour->data[static_cast<size_t>(y) * colour->stride + 3 * x];
      p[0] = static_cast<uint8_t>(x);
      p[1] = static_cast<uint8_t>(y);
      p[2] = static_cast<uint8_t>(7 * number);
    }
  }
  rs2_frame* depth = NewFrame();
  depth->profile = {RS2_STREAM_DEPTH, RS2_FORMAT_Z16, c.width, c.height, c.fps};
  depth->stride = c.width * 2;
  depth->units = depth_units;
  depth->number = number;
  depth->data.resize(static_cast<size_t>(depth->stride) * c.height);
  for (int y = 0; y < c.height; ++y) {
    for (int x = 0; x < c.width; ++x) {
      const double m = x < c.width / 2 ? 0.400 : 0.380;
      const auto raw = static_cast<uint16_t>(std::lround(m / depth_units));
      std::memcpy(&depth->data[static_cast<size_t>(y) * depth->stride + 2 * x],
                  &raw, 2);
    }
  }
  rs2_frame* set = NewFrame();
  set->number = number;
  set->children = {depth, colour};
  return set;
}

}  // namespace

// --- The SDK's functions -------------------------------------------------

EXPORT rs2_context* rs2_create_context(int api_version, rs2_error** error) {
  Record("rs2_create_context");
  if (api_version / 10000 != 2) {
    Fail(error, "API version mismatch");
    return nullptr;
  }
  return new rs2_context;
}
EXPORT void rs2_delete_context(rs2_context* c) {
  Record("rs2_delete_context");
  delete c;
}
EXPORT rs2_pipeline* rs2_create_pipeline(rs2_context*, rs2_error**) {
  return new rs2_pipeline;
}
EXPORT void rs2_delete_pipeline(rs2_pipeline* p) { delete p; }
EXPORT rs2_config* rs2_create_config(rs2_error**) { return new rs2_config; }
EXPORT void rs2_delete_config(rs2_config* c) { delete c; }
EXPORT void rs2_config_enable_stream(rs2_config* c, rs2_stream stream, int,
                                     int width, int height, rs2_format format,
                                     int fps, rs2_error** error) {
  if ((stream == RS2_STREAM_COLOR && format != RS2_FORMAT_RGB8) ||
      (stream == RS2_STREAM_DEPTH && format != RS2_FORMAT_Z16)) {
    Fail(error, "unsupported format");
    return;
  }
  c->width = width;
  c->height = height;
  c->fps = fps;
  (stream == RS2_STREAM_COLOR ? c->colour : c->depth) = true;
}
EXPORT rs2_pipeline_profile* rs2_pipeline_start_with_config(rs2_pipeline* p,
                                                            rs2_config* c,
                                                            rs2_error** error) {
  Record("rs2_pipeline_start_with_config");
  bool unplugged;
  {
    std::lock_guard<std::mutex> lock(mu);
    ++start_calls;
    unplugged = no_device;
  }
  if (unplugged) {
    Fail(error, "No device connected");
    return nullptr;
  }
  if (!c->colour || !c->depth || c->width > 1280 || c->fps > 90) {
    Fail(error, "Couldn't resolve requests");
    return nullptr;
  }
  p->config = *c;
  p->started = true;
  {
    std::lock_guard<std::mutex> lock(mu);
    next_number = 1;  // a device started again counts from 1 again
  }
  return new rs2_pipeline_profile;
}
EXPORT void rs2_pipeline_stop(rs2_pipeline* p, rs2_error**) {
  Record("rs2_pipeline_stop");
  p->started = false;
}
EXPORT void rs2_delete_pipeline_profile(rs2_pipeline_profile* p) { delete p; }
EXPORT rs2_frame* rs2_pipeline_wait_for_frames(rs2_pipeline* p,
                                               unsigned int timeout_ms,
                                               rs2_error** error) {
  bool stall, unplugged;
  unsigned long long number;  // NOLINT
  {
    std::lock_guard<std::mutex> lock(mu);
    ++wait_calls;
    stall = stalled;
    unplugged = no_device;
    number = next_number++;
  }
  // As librealsense's pipeline::wait_for_frames: a stopped pipeline fails
  // at once; a device gone is found after the timeout, and a failed
  // reconnect leaves the pipeline stopped.
  if (!p->started) {
    Fail(error, "wait_for_frames cannot be called before start()");
    return nullptr;
  }
  if (stall || unplugged) {
    std::this_thread::sleep_for(std::chrono::milliseconds(timeout_ms));
    if (unplugged) {
      p->started = false;
      Fail(error,
           "Device disconnected. Failed to recconect: No device "
           "connected" +
               std::to_string(timeout_ms));
      return nullptr;
    }
    Fail(error, "Frame didn't arrive within " + std::to_string(timeout_ms));
    return nullptr;
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(1000 / p->config.fps));
  return MakeFrameset(p->config, number);
}
EXPORT int rs2_embedded_frames_count(rs2_frame* f, rs2_error**) {
  return static_cast<int>(f->children.size());
}
EXPORT rs2_frame* rs2_extract_frame(rs2_frame* f, int index,
                                    rs2_error** error) {
  if (index < 0 || index >= static_cast<int>(f->children.size())) {
    Fail(error, "out of range");
    return nullptr;
  }
  ++f->children[index]->refs;
  return f->children[index];
}
EXPORT void rs2_release_frame(rs2_frame* f) { Release(f); }
EXPORT const rs2_stream_profile* rs2_get_frame_stream_profile(
    const rs2_frame* f, rs2_error**) {
  return &f->profile;
}
EXPORT void rs2_get_stream_profile_data(const rs2_stream_profile* p,
                                        rs2_stream* stream, rs2_format* format,
                                        int* index, int* unique_id,
                                        int* framerate, rs2_error**) {
  *stream = p->stream;
  *format = p->format;
  *index = 0;
  *unique_id = static_cast<int>(p->stream);
  *framerate = p->fps;
}
EXPORT void rs2_get_video_stream_intrinsics(const rs2_stream_profile* p,
                                            rs2_intrinsics* k, rs2_error**) {
  const float s = p->width / 640.0f;
  *k = {p->width,   p->height,  321.4f * s,          238.9f * s,
        612.3f * s, 611.8f * s, RS2_DISTORTION_NONE, {0, 0, 0, 0, 0}};
}
EXPORT const void* rs2_get_frame_data(const rs2_frame* f, rs2_error**) {
  return f->data.data();
}
EXPORT int rs2_get_frame_width(const rs2_frame* f, rs2_error**) {
  return f->profile.width;
}
EXPORT int rs2_get_frame_height(const rs2_frame* f, rs2_error**) {
  return f->profile.height;
}
EXPORT int rs2_get_frame_stride_in_bytes(const rs2_frame* f, rs2_error**) {
  return f->stride;
}
EXPORT unsigned long long rs2_get_frame_number(const rs2_frame* f,  // NOLINT
                                               rs2_error**) {
  return f->number;
}
EXPORT float rs2_depth_frame_get_units(const rs2_frame* f, rs2_error** error) {
  if (f->profile.stream != RS2_STREAM_DEPTH) {
    Fail(error, "not a depth frame");
    return 0;
  }
  if (!f->aligned) Record("unaligned depth read");
  return f->units;
}
EXPORT rs2_processing_block* rs2_create_align(rs2_stream to,
                                              rs2_error** error) {
  if (to != RS2_STREAM_COLOR) {
    Fail(error, "fake aligns to colour only");
    return nullptr;
  }
  return new rs2_processing_block;
}
EXPORT void rs2_delete_processing_block(rs2_processing_block* b) { delete b; }
EXPORT rs2_frame_queue* rs2_create_frame_queue(int, rs2_error**) {
  return new rs2_frame_queue;
}
EXPORT void rs2_delete_frame_queue(rs2_frame_queue* q) {
  for (rs2_frame* f : q->frames) Release(f);
  delete q;
}
EXPORT void rs2_start_processing_queue(rs2_processing_block* b,
                                       rs2_frame_queue* q, rs2_error**) {
  b->queue = q;
}
EXPORT void rs2_process_frame(rs2_processing_block* b, rs2_frame* f,
                              rs2_error**) {
  Record("rs2_process_frame");
  for (rs2_frame* child : f->children) {
    if (child->profile.stream == RS2_STREAM_DEPTH) child->aligned = true;
  }
  std::lock_guard<std::mutex> lock(b->queue->mu);
  b->queue->frames.push_back(f);  // ownership moves to the queue
}
EXPORT rs2_frame* rs2_wait_for_frame(rs2_frame_queue* q, unsigned int,
                                     rs2_error** error) {
  std::lock_guard<std::mutex> lock(q->mu);
  if (q->frames.empty()) {
    Fail(error, "Frame did not arrive in time!");
    return nullptr;
  }
  rs2_frame* f = q->frames.front();
  q->frames.erase(q->frames.begin());
  return f;
}
EXPORT const char* rs2_get_error_message(const rs2_error* e) {
  return e->message.c_str();
}
EXPORT void rs2_free_error(rs2_error* e) {
  --live_errors;
  delete e;
}

// --- The test's handles --------------------------------------------------

EXPORT void FakeRealSense_Reset() {
  std::lock_guard<std::mutex> lock(mu);
  calls.clear();
  no_device = false;
  stalled = false;
  wait_calls = 0;
  start_calls = 0;
  next_number = 1;
  depth_units = 0.001f;
}
EXPORT void FakeRealSense_SetNoDevice(bool v) {
  std::lock_guard<std::mutex> lock(mu);
  no_device = v;
}
EXPORT void FakeRealSense_SetStalled(bool v) {
  std::lock_guard<std::mutex> lock(mu);
  stalled = v;
}
EXPORT void FakeRealSense_DropFrames(int n) {
  std::lock_guard<std::mutex> lock(mu);
  next_number += n;
}
EXPORT void FakeRealSense_SetDepthUnits(float units) {
  std::lock_guard<std::mutex> lock(mu);
  depth_units = units;
}
EXPORT int FakeRealSense_WaitCalls() {
  std::lock_guard<std::mutex> lock(mu);
  return wait_calls;
}
EXPORT int FakeRealSense_StartCalls() {
  std::lock_guard<std::mutex> lock(mu);
  return start_calls;
}
EXPORT int FakeRealSense_LiveFrames() { return live_frames; }
EXPORT int FakeRealSense_LiveErrors() { return live_errors; }
EXPORT const char* FakeRealSense_Calls() {
  static std::string copy;
  std::lock_guard<std::mutex> lock(mu);
  copy = calls;
  return copy.c_str();
}
