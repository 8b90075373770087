#pragma once
// gather_by: dst[k] = src[order[k]], the one way arrays are put into cell
// order (reordering, paper §2.4) — the particle arrays of a simulation and
// the coordinates of a neighbour search alike.
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace sphnl {

/// `threads` > 1 splits k into that many contiguous ranges, one OpenMP thread
/// each: every dst[k] is written once whatever the split, so the result is
/// the same bits.
template <class T, class Alloc>
void gather_by(std::span<const T> src, std::span<const std::uint32_t> order, std::vector<T, Alloc>& dst,
               int threads = 1) {
  const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(order.size());
  dst.resize(order.size());
  T* d = dst.data();
  const T* s = src.data();
  const std::uint32_t* o = order.data();
#pragma omp parallel for num_threads(threads) schedule(static) if (threads > 1)
  for (std::ptrdiff_t k = 0; k < n; ++k) d[k] = s[o[k]];
}

}  // namespace sphnl
