// RetainFreedMemory (process_memory.h): after it, a frame-sized block comes
// from the heap, not from its own mmap, and freeing it leaves the heap as
// large as it was. In a fresh process glibc would map a 4 MB block by itself
// (its first threshold is 128 kB), so the first test fails without the call
// (the block is mapped, and not kept after free); the second checks the
// bound, which holds either way. Its own binary: the policy is the whole
// process's. Under AddressSanitizer, whose allocator replaces glibc's, there is
// nothing to measure.
#include "services/common/process_memory.h"

#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include <cstdlib>
#include <cstring>

#include "gtest/gtest.h"

#if defined(__SANITIZE_ADDRESS__)
#define BITEWISE_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define BITEWISE_ASAN 1
#endif
#endif

namespace bitewise {
namespace {

#if defined(BITEWISE_ASAN)
#define SKIP_UNDER_ASAN() \
  GTEST_SKIP() << "AddressSanitizer's allocator replaces glibc's malloc"
#else
#define SKIP_UNDER_ASAN() (void)0
#endif

#if defined(__GLIBC__)

// Through volatile pointers, so the compiler cannot drop the pair.
void* (*volatile allocate)(size_t) = std::malloc;
void (*volatile release)(void*) = std::free;

TEST(ProcessMemoryTest, AFrameSizedBlockComesFromTheHeapAndStaysThere) {
  SKIP_UNDER_ASAN();
  ASSERT_TRUE(RetainFreedMemory().ok());
  constexpr size_t kBlock = 4 << 20;
  const size_t mapped_before = mallinfo2().hblkhd;
  void* block = allocate(kBlock);
  ASSERT_NE(block, nullptr);
  std::memset(block, 1, kBlock);
  const struct mallinfo2 with_block = mallinfo2();
  EXPECT_EQ(with_block.hblkhd, mapped_before) << "the block was mmapped";
  release(block);
  const struct mallinfo2 after = mallinfo2();
  EXPECT_GE(after.arena, with_block.arena) << "the heap was trimmed";
  EXPECT_GE(after.fordblks, kBlock) << "the freed block is not kept";
}

TEST(ProcessMemoryTest, BlocksAboveTheLimitAreStillMapped) {
  SKIP_UNDER_ASAN();
  ASSERT_TRUE(RetainFreedMemory().ok());
  const size_t mapped_before = mallinfo2().hblkhd;
  void* block = allocate(kRetainedBlockMaxBytes + (1 << 20));
  ASSERT_NE(block, nullptr);
  EXPECT_GT(mallinfo2().hblkhd, mapped_before);
  release(block);
  EXPECT_EQ(mallinfo2().hblkhd, mapped_before);
}

#endif  // __GLIBC__ (mallinfo2); elsewhere RetainFreedMemory is UNIMPLEMENTED

}  // namespace
}  // namespace bitewise
