#pragma once
// UninitBuffer: a growable array that is never zero-filled, for neighbour
// lists. A list build writes up to a whole candidate range per point and keeps
// only the survivors, and a search of N points holds ~N * 70 entries: zeroing
// them first would touch every page twice (std::vector value-initialises).
//
// Huge pages (set_huge_pages): a first call writes hundreds of MB of lists
// into fresh memory, and on a virtual machine each 4 KiB page's first-touch
// fault costs ~10 µs, more than writing the page. With huge pages on, a
// buffer of at least kHugePageMinBytes lies in whole 2 MiB pages advised as
// transparent huge pages (Linux, THP in `madvise` or `always` mode), so it
// faults once per 2 MiB. Where the kernel declines (THP `never`, other
// systems), the buffer is the same memory with base pages.
#include <cstddef>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <new>
#include <type_traits>
#include <utility>
#include <vector>

namespace sphnl {

/// Whether this machine is a virtual machine whose kernel reports free memory
/// to its host: a virtio balloon device (device id 0x0005 under
/// `sysfs_root`/bus/virtio/devices) that offers free page reporting (feature
/// bit 5, VIRTIO_BALLOON_F_REPORTING). There memory freed for a few seconds is
/// handed back, and a first build on huge pages of it took twice as long as
/// on memory just freed while base pages cost the same either way
/// (docs/FINDINGS.md, "Huge pages on idle memory"). False where unreadable.
bool free_memory_reported_to_host(const char* sysfs_root = "/sys");

/// Bytes of one transparent huge page (x86-64, arm64 with 4 KiB base pages).
inline constexpr std::size_t kHugePageBytes = std::size_t{2} << 20;
/// Smaller buffers keep base pages: rounding them up to 2 MiB would waste more
/// than their faults cost.
inline constexpr std::size_t kHugePageMinBytes = std::size_t{4} << 20;
/// Every buffer starts on a cache line.
inline constexpr std::size_t kBufferAlignment = 64;
/// A huge-page buffer does not start at its huge page's first byte but
/// 1..kHugePageColours steps of kHugePageColourStep (8 KiB and one cache
/// line) into it, in turn. Buffers that all start at 2 MiB boundaries share
/// their low 21 address bits: element i of the x, y and z coordinates and of
/// the row offsets then falls on the same cache sets, and a warm search of
/// 10^6 points ran 10-13 % slower on huge pages than on base pages on one
/// machine (Intel Xeon, model 207); started at staggered offsets, as fast
/// (docs/FINDINGS.md, "Peers and threads").
inline constexpr std::size_t kHugePageColourStep = 8192 + kBufferAlignment;
inline constexpr std::size_t kHugePageColours = 16;

/// `bytes` of uninitialised memory, 64-byte aligned, for free_buffer; with
/// `huge_pages` and at least kHugePageMinBytes, inside whole 2 MiB pages
/// advised as huge, starting at a staggered offset (kHugePageColourStep).
/// Throws std::bad_alloc.
void* allocate_buffer(std::size_t bytes, bool huge_pages);
/// Frees what allocate_buffer returned (nullptr: nothing).
void free_buffer(void* buffer) noexcept;

/// std::vector's allocator for the large arrays of a search (coordinates in
/// cell order, row offsets): memory from allocate_buffer, on huge pages when
/// asked, and elements default-initialised, so resize() does not zero what
/// is overwritten anyway (a second touch of every page). Any instance frees
/// any other's memory (free_buffer needs no flag), so all compare equal; the
/// flag travels with moves and swaps.
template <class T>
struct BufferAllocator {
  static_assert(std::is_trivially_copyable_v<T> && alignof(T) <= alignof(std::max_align_t));
  using value_type = T;
  using is_always_equal = std::true_type;
  using propagate_on_container_move_assignment = std::true_type;
  using propagate_on_container_copy_assignment = std::true_type;
  using propagate_on_container_swap = std::true_type;
  bool huge_pages = false;

  BufferAllocator() = default;
  explicit BufferAllocator(bool huge) : huge_pages(huge) {}
  template <class U>
  BufferAllocator(const BufferAllocator<U>& other) : huge_pages(other.huge_pages) {}

  T* allocate(std::size_t n) { return static_cast<T*>(allocate_buffer(n * sizeof(T), huge_pages)); }
  void deallocate(T* p, std::size_t) { free_buffer(p); }
  template <class U>
  void construct(U* p) {
    ::new (static_cast<void*>(p)) U;  // default-initialised: no zeroing
  }
  template <class U, class... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
  template <class U>
  friend bool operator==(const BufferAllocator&, const BufferAllocator<U>&) {
    return true;
  }
};

template <class T>
using BufferVector = std::vector<T, BufferAllocator<T>>;

/// `v` empty and allocating with huge pages or not, as asked (its memory is
/// kept when the choice is already that).
template <class T>
void use_huge_pages(BufferVector<T>& v, bool huge_pages) {
  if (v.get_allocator().huge_pages != huge_pages) v = BufferVector<T>(BufferAllocator<T>(huge_pages));
}

template <class T>
class UninitBuffer {
  static_assert(std::is_trivially_copyable_v<T>, "entries are moved with memcpy and never constructed");

 public:
  T* data() { return p_.get(); }
  const T* data() const { return p_.get(); }
  std::size_t capacity() const { return capacity_; }
  /// Whether the next growth asks for huge pages (off by default).
  void set_huge_pages(bool on) { huge_pages_ = on; }

  /// Makes room for at least `capacity` entries, keeping the first `keep`;
  /// never shrinks. New entries are uninitialised. Returns data().
  T* grow(std::size_t capacity, std::size_t keep) {
    if (capacity <= capacity_) return p_.get();
    T* q = static_cast<T*>(allocate_buffer(capacity * sizeof(T), huge_pages_));
    if (keep) std::memcpy(q, p_.get(), keep * sizeof(T));
    p_.reset(q);
    capacity_ = capacity;
    return q;
  }

 private:
  struct Free {
    void operator()(T* p) const { free_buffer(p); }
  };
  std::unique_ptr<T, Free> p_;
  std::size_t capacity_ = 0;
  bool huge_pages_ = false;
};

}  // namespace sphnl
