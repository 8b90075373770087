#pragma once
// gather_by: dst[k] = src[order[k]], the one way arrays are put into cell
// order (reordering, paper §2.4) — the particle arrays of a simulation and
// the coordinates of a neighbour search alike.
#include <cstdint>
#include <span>
#include <vector>

namespace sphnl {

template <class T>
void gather_by(std::span<const T> src, std::span<const std::uint32_t> order, std::vector<T>& dst) {
  const std::size_t n = order.size();
  dst.resize(n);
  T* d = dst.data();
  const T* s = src.data();
  const std::uint32_t* o = order.data();
  for (std::size_t k = 0; k < n; ++k) d[k] = s[o[k]];
}

}  // namespace sphnl
