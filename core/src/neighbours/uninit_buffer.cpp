#include "sphnl/neighbours/uninit_buffer.hpp"

#include <atomic>
#include <cstddef>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>

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

bool free_memory_reported_to_host(const char* sysfs_root) {
  constexpr std::size_t kBalloonFreePageReporting = 5;  // VIRTIO_BALLOON_F_REPORTING
  std::error_code ec;
  const std::filesystem::path devices = std::filesystem::path(sysfs_root) / "bus" / "virtio" / "devices";
  for (std::filesystem::directory_iterator it(devices, ec), end; !ec && it != end; it.increment(ec)) {
    std::ifstream device(it->path() / "device");
    std::string id;
    if (!(device >> id) || id != "0x0005") continue;  // not a balloon
    // features: one character '0' or '1' per feature bit, bit 0 first
    std::ifstream features(it->path() / "features");
    std::string bits;
    if (features >> bits && bits.size() > kBalloonFreePageReporting && bits[kBalloonFreePageReporting] == '1')
      return true;
  }
  return false;
}

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
