#include <gtest/gtest.h>

#include <malloc.h>

#include <cstdlib>
#include <cstring>

#include "heap_reuse.hpp"

namespace evar::app {
namespace {

// A frame-sized block freed by one frame is still in the process for the next: the heap's
// free bytes grow by at least its size instead of the block going back to the kernel.
TEST(HeapReuse, AFreedFrameSizedBlockStaysInTheHeapForTheNextFrame) {
  const HeapReuse policy = keep_freed_memory_for_reuse();
  if (policy == HeapReuse::not_applicable) GTEST_SKIP() << "a sanitizer's allocator is in use";
  ASSERT_EQ(policy, HeapReuse::kept);
  constexpr std::size_t kFrame = 4u << 20;  // a 1024 x 1024 float image
  void* block = std::malloc(kFrame);
  ASSERT_NE(block, nullptr);
  std::memset(block, 1, kFrame);  // touched, as a frame is
  const std::size_t free_before = mallinfo2().fordblks;
  std::free(block);
  EXPECT_GE(mallinfo2().fordblks, free_before + kFrame);
}

}  // namespace
}  // namespace evar::app
