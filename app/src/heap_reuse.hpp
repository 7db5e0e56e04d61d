#pragma once
// The node allocates the same frame-sized buffers (a 1024 x 1024 float image is 4 MB) for
// every frame it segments and composites. glibc returns blocks that large to the kernel
// on free (mmap, or trimming the heap top), so the next frame faults every page in again
// and has it zeroed: measured, 17 % of a 1024 x 1024 segmentation. Keeping freed memory
// for reuse costs a plateau of resident memory, not growth.

namespace evar::app {

enum class HeapReuse {
  kept,           ///< glibc keeps freed blocks up to 32 MB and up to 256 MB of free heap
  refused,        ///< glibc refused a setting (mallopt returned 0)
  not_applicable  ///< a sanitizer's allocator is in use; it has its own policy
};

/// Blocks up to 32 MB come from the heap (glibc's largest threshold), and up to 256 MB of
/// free heap is kept instead of trimmed.
HeapReuse keep_freed_memory_for_reuse();

}  // namespace evar::app
