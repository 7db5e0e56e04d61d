#include "heap_reuse.hpp"

#include <malloc.h>

#if defined(__SANITIZE_ADDRESS__)
#define EVAR_SANITIZER_ALLOCATOR 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(memory_sanitizer) || __has_feature(thread_sanitizer)
#define EVAR_SANITIZER_ALLOCATOR 1
#endif
#endif

namespace evar::app {

HeapReuse keep_freed_memory_for_reuse() {
#ifdef EVAR_SANITIZER_ALLOCATOR
  return HeapReuse::not_applicable;
#else
  // Fixed values also switch off glibc's dynamic threshold, which would otherwise settle
  // only after the first frames have paid for their pages.
  const bool mmap_ok = mallopt(M_MMAP_THRESHOLD, 32 << 20) == 1;
  const bool trim_ok = mallopt(M_TRIM_THRESHOLD, 256 << 20) == 1;
  return mmap_ok && trim_ok ? HeapReuse::kept : HeapReuse::refused;
#endif
}

}  // namespace evar::app
