#include "sphnl/neighbours/uninit_buffer.hpp"

#include <cstddef>
#include <limits>

#if defined(__linux__)
#include <sys/mman.h>
#endif

namespace sphnl {

void* allocate_buffer(std::size_t bytes, bool huge_pages) {
  // No object may exceed PTRDIFF_MAX bytes, and rounding up to whole huge
  // pages must not wrap around: such a size is refused before any allocator
  // sees it.
  if (bytes > static_cast<std::size_t>(std::numeric_limits<std::ptrdiff_t>::max()) - kHugePageBytes)
    throw std::bad_alloc();
  if (bytes == 0) bytes = 1;
  if (!huge_pages || bytes < kHugePageMinBytes) {
    void* p = std::malloc(bytes);
    if (!p) throw std::bad_alloc();
    return p;
  }
  const std::size_t rounded = (bytes + kHugePageBytes - 1) / kHugePageBytes * kHugePageBytes;
  void* p = std::aligned_alloc(kHugePageBytes, rounded);
  if (!p) throw std::bad_alloc();
#if defined(MADV_HUGEPAGE)
  // Advice only: where it is refused the memory keeps base pages.
  (void)madvise(p, rounded, MADV_HUGEPAGE);
#endif
  return p;
}

}  // namespace sphnl
