#include "sphnl/neighbours/uninit_buffer.hpp"

#include <atomic>
#include <cstddef>
#include <limits>

#if defined(__linux__)
#include <sys/mman.h>
#endif

namespace sphnl {

namespace {

/// Where the next huge-page buffer starts inside its first huge page:
/// 1..kHugePageColours steps of kHugePageColourStep, in turn.
std::size_t next_colour() {
  static std::atomic<std::size_t> count{0};
  return (1 + count.fetch_add(1, std::memory_order_relaxed) % kHugePageColours) * kHugePageColourStep;
}

}  // namespace

void* allocate_buffer(std::size_t bytes, bool huge_pages) {
  // No object may exceed PTRDIFF_MAX bytes, and rounding up to whole huge
  // pages (plus the offset) must not wrap around: such a size is refused
  // before any allocator sees it.
  if (bytes > static_cast<std::size_t>(std::numeric_limits<std::ptrdiff_t>::max()) - 2 * kHugePageBytes)
    throw std::bad_alloc();
  if (bytes == 0) bytes = 1;
  // The block std::aligned_alloc returned is kept in the
  // pointer-sized slot just before the buffer, so free_buffer needs neither
  // the size nor the choice of pages.
  std::size_t offset = kBufferAlignment;
  std::size_t total = (bytes + offset + kBufferAlignment - 1) / kBufferAlignment * kBufferAlignment;
  std::size_t alignment = kBufferAlignment;
  const bool huge = huge_pages && bytes >= kHugePageMinBytes;
  if (huge) {
    offset = next_colour();
    total = (bytes + offset + kHugePageBytes - 1) / kHugePageBytes * kHugePageBytes;
    alignment = kHugePageBytes;
  }
  void* block = std::aligned_alloc(alignment, total);
  if (!block) throw std::bad_alloc();
#if defined(MADV_HUGEPAGE)
  // Advice only: where it is refused the memory keeps base pages.
  if (huge) (void)madvise(block, total, MADV_HUGEPAGE);
#endif
  void* buffer = static_cast<unsigned char*>(block) + offset;
  static_cast<void**>(buffer)[-1] = block;
  return buffer;
}

void free_buffer(void* buffer) noexcept {
  if (buffer) std::free(static_cast<void**>(buffer)[-1]);
}

}  // namespace sphnl
