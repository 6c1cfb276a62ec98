// How a service process keeps the memory it frees, for services whose every
// request allocates and frees buffers of a frame's size.
//
// glibc's malloc serves a large block (from 128 kB at first; the bound rises
// with the largest block freed) with an mmap of its own and returns it to the
// kernel on free, and it returns the heap's free top beyond a threshold. A
// block served afresh costs a page fault for every page touched. DetectFood
// allocates 30-100 blocks of 0.1-1.8 MB per frame (16-31 MB in all, on the
// blind plates), and with other allocations between two frames (the next
// request's 1.5 MB) much of that is served afresh each time: measured, 2-3 ms
// of the median and 2-6 ms of the 95th percentile. RetainFreedMemory keeps
// it: blocks below 32 MB come from the heap, and the heap is never trimmed,
// so the process keeps its largest working set and reuses it. For the
// PerceptionService that is about 40 MB more resident memory
// (docs/benchmarks.md, "DetectFood through the service").
#ifndef BITEWISE_SERVICES_COMMON_PROCESS_MEMORY_H_
#define BITEWISE_SERVICES_COMMON_PROCESS_MEMORY_H_

#include "absl/status/status.h"

namespace bitewise {

// Blocks below this size come from the heap (glibc's largest allowed
// M_MMAP_THRESHOLD on 64-bit).
inline constexpr int kRetainedBlockMaxBytes = 32 << 20;

// Sets malloc's policy for this process as above. UNIMPLEMENTED without
// glibc, INTERNAL if malloc refuses a setting; the policy is then as before.
absl::Status RetainFreedMemory();

}  // namespace bitewise

#endif  // BITEWISE_SERVICES_COMMON_PROCESS_MEMORY_H_
