#pragma once
// UninitBuffer: a growable array that is never zero-filled, for neighbour
// lists. A list build writes up to a whole candidate range per point and keeps
// only the survivors, and a search of N points holds ~N * 70 entries: zeroing
// them first would touch every page twice (std::vector value-initialises).
#include <cstddef>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <new>
#include <type_traits>

namespace sphnl {

template <class T>
class UninitBuffer {
  static_assert(std::is_trivially_copyable_v<T>, "entries are moved with memcpy and never constructed");

 public:
  T* data() { return p_.get(); }
  const T* data() const { return p_.get(); }
  std::size_t capacity() const { return capacity_; }

  /// Makes room for at least `capacity` entries, keeping the first `keep`;
  /// never shrinks. New entries are uninitialised. Returns data().
  T* grow(std::size_t capacity, std::size_t keep) {
    if (capacity <= capacity_) return p_.get();
    T* q = static_cast<T*>(std::malloc(capacity * sizeof(T)));
    if (!q) throw std::bad_alloc();
    if (keep) std::memcpy(q, p_.get(), keep * sizeof(T));
    p_.reset(q);
    capacity_ = capacity;
    return q;
  }

 private:
  struct Free {
    void operator()(T* p) const { std::free(p); }
  };
  std::unique_ptr<T, Free> p_;
  std::size_t capacity_ = 0;
};

}  // namespace sphnl
