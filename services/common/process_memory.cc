#include "services/common/process_memory.h"

#include <climits>

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace bitewise {

absl::Status RetainFreedMemory() {
#if defined(__GLIBC__)
  // Setting either fixes both thresholds (glibc stops adapting them), so
  // both are set: no mmap below the limit, and no trimming at all.
  if (mallopt(M_MMAP_THRESHOLD, kRetainedBlockMaxBytes) != 1) {
    return absl::InternalError(
        "malloc refused M_MMAP_THRESHOLD = 32 MB; the process returns freed "
        "memory to the kernel as before");
  }
  if (mallopt(M_TRIM_THRESHOLD, INT_MAX) != 1) {
    return absl::InternalError(
        "malloc refused M_TRIM_THRESHOLD; the process trims its heap as "
        "before");
  }
  return absl::OkStatus();
#else
  return absl::UnimplementedError(
      "RetainFreedMemory needs glibc's malloc (mallopt)");
#endif
}

}  // namespace bitewise
