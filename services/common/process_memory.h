// How a service process keeps the memory it frees, for services whose every
// request allocates and frees buffers of a frame's size.
//
// glibc's malloc serves a large block (from 128 kB at first; the bound rises
// with the largest mapped block freed) with an mmap of its own and returns it
// to the kernel on free, and it returns the heap's free top beyond a
// threshold. A block served afresh costs a page fault for every page touched.
// DetectFood allocates 30-100 blocks of 0.1-1.8 MB per frame (16-31 MB in all,
// six blind plates counted), and in the PerceptionService with the default
// featurizer that cost about 1,150 minor page faults per call.
// RetainFreedMemory keeps the memory: blocks below 32 MB come from the heap,
// and the heap is never trimmed, so the process keeps its largest working set
// and reuses it: 67 faults per call, and DetectFood 2-3 ms faster at the
// median, for about 37 MiB more resident memory with the default featurizer
// (docs/benchmarks.md, "DetectFood through the service").
#ifndef BITEWISE_SERVICES_COMMON_PROCESS_MEMORY_H_
#define BITEWISE_SERVICES_COMMON_PROCESS_MEMORY_H_

#include "absl/status/status.h"

namespace bitewise {

// Blocks below this size come from the heap (glibc's largest allowed
// M_MMAP_THRESHOLD on 64-bit).
inline constexpr int kRetainedBlockMaxBytes = 32 << 20;

// Sets malloc's policy for this process as above. UNIMPLEMENTED without
// glibc; INTERNAL if malloc refuses a setting (if it refuses the first, the
// policy is as before; if the second, the mmap bound is set and no longer
// adapts, but the heap is still trimmed).
absl::Status RetainFreedMemory();

}  // namespace bitewise

#endif  // BITEWISE_SERVICES_COMMON_PROCESS_MEMORY_H_
