// The part of the Intel RealSense SDK 2.0 C API (librealsense2, rs.h and
// its h/*.h headers) that RealSenseSource uses, declared here because the
// SDK is loaded at run time (dlopen), as the Kinova SDK is, so that
// bitewise builds and runs without it. Written from the published headers
// of librealsense 2.50-2.56 (see docs/hardware.md); enum values and the
// layout of rs2_intrinsics are part of the SDK's stable C ABI and are
// pinned below with static_asserts.
#ifndef BITEWISE_SERVICES_CAMERA_REALSENSE_API_H_
#define BITEWISE_SERVICES_CAMERA_REALSENSE_API_H_

#include <cstddef>

namespace bitewise::camera::rs2 {

// Opaque handles.
struct rs2_error;
struct rs2_context;
struct rs2_pipeline;
struct rs2_config;
struct rs2_pipeline_profile;
struct rs2_frame;
struct rs2_stream_profile;
struct rs2_processing_block;
struct rs2_frame_queue;

// rs_sensor.h / rs_frame.h enums (C enums: int-sized).
enum rs2_stream : int {
  RS2_STREAM_ANY = 0,
  RS2_STREAM_DEPTH = 1,
  RS2_STREAM_COLOR = 2
};
enum rs2_format : int {
  RS2_FORMAT_ANY = 0,
  RS2_FORMAT_Z16 = 1,
  RS2_FORMAT_RGB8 = 5,
  RS2_FORMAT_BGR8 = 6,
};
enum rs2_distortion : int { RS2_DISTORTION_NONE = 0 };

// rs_types.h.
struct rs2_intrinsics {
  int width;
  int height;
  float ppx;
  float ppy;
  float fx;
  float fy;
  rs2_distortion model;
  float coeffs[5];
};
static_assert(sizeof(rs2_intrinsics) == 48, "rs2_intrinsics layout");
static_assert(offsetof(rs2_intrinsics, ppx) == 8, "rs2_intrinsics layout");
static_assert(offsetof(rs2_intrinsics, fx) == 16, "rs2_intrinsics layout");
static_assert(offsetof(rs2_intrinsics, model) == 24, "rs2_intrinsics layout");
static_assert(offsetof(rs2_intrinsics, coeffs) == 28, "rs2_intrinsics layout");
using rs2_time_t = double;  // milliseconds

// RS2_API_VERSION of the oldest SDK this declaration matches (2.50.0):
// major * 10000 + minor * 100 + patch. rs2_create_context refuses a
// library older than the version it is given.
constexpr int kApiVersion = 2 * 10000 + 50 * 100 + 0;

// The functions, as function-pointer types (names as in the SDK).
using CreateContextFn = rs2_context* (*)(int, rs2_error**);
using DeleteContextFn = void (*)(rs2_context*);
using CreatePipelineFn = rs2_pipeline* (*)(rs2_context*, rs2_error**);
using DeletePipelineFn = void (*)(rs2_pipeline*);
using CreateConfigFn = rs2_config* (*)(rs2_error**);
using DeleteConfigFn = void (*)(rs2_config*);
using ConfigEnableStreamFn = void (*)(rs2_config*, rs2_stream, int, int, int,
                                      rs2_format, int, rs2_error**);
using PipelineStartWithConfigFn = rs2_pipeline_profile* (*)(rs2_pipeline*,
                                                            rs2_config*,
                                                            rs2_error**);
using PipelineStopFn = void (*)(rs2_pipeline*, rs2_error**);
using DeletePipelineProfileFn = void (*)(rs2_pipeline_profile*);
using PipelineWaitForFramesFn = rs2_frame* (*)(rs2_pipeline*, unsigned int,
                                               rs2_error**);
using EmbeddedFramesCountFn = int (*)(rs2_frame*, rs2_error**);
using ExtractFrameFn = rs2_frame* (*)(rs2_frame*, int, rs2_error**);
using ReleaseFrameFn = void (*)(rs2_frame*);
using GetFrameStreamProfileFn = const rs2_stream_profile* (*)(const rs2_frame*,
                                                              rs2_error**);
using GetStreamProfileDataFn = void (*)(const rs2_stream_profile*, rs2_stream*,
                                        rs2_format*, int*, int*, int*,
                                        rs2_error**);
using GetVideoStreamIntrinsicsFn = void (*)(const rs2_stream_profile*,
                                            rs2_intrinsics*, rs2_error**);
using GetFrameDataFn = const void* (*)(const rs2_frame*, rs2_error**);
using GetFrameIntFn = int (*)(const rs2_frame*, rs2_error**);
using GetFrameNumberFn = unsigned long long (*)(const rs2_frame*,  // NOLINT
                                                rs2_error**);
using DepthFrameGetUnitsFn = float (*)(const rs2_frame*, rs2_error**);
using CreateAlignFn = rs2_processing_block* (*)(rs2_stream, rs2_error**);
using DeleteProcessingBlockFn = void (*)(rs2_processing_block*);
using CreateFrameQueueFn = rs2_frame_queue* (*)(int, rs2_error**);
using DeleteFrameQueueFn = void (*)(rs2_frame_queue*);
using StartProcessingQueueFn = void (*)(rs2_processing_block*, rs2_frame_queue*,
                                        rs2_error**);
using ProcessFrameFn = void (*)(rs2_processing_block*, rs2_frame*, rs2_error**);
using WaitForFrameFn = rs2_frame* (*)(rs2_frame_queue*, unsigned int,
                                      rs2_error**);
using GetErrorMessageFn = const char* (*)(const rs2_error*);
using FreeErrorFn = void (*)(rs2_error*);

}  // namespace bitewise::camera::rs2

#endif  // BITEWISE_SERVICES_CAMERA_REALSENSE_API_H_
