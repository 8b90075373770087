// Z-order (Morton) keys of sort_xy and sort_xyz (paper §2.4): bit layouts for
// grids padded to powers of two per axis.
#include "sphnl/orderings/morton.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace sphnl {

namespace morton {

int make_layouts(const int* bits, int dims, AxisLayout* out) {
  int total = 0;
  for (int d = 0; d < dims; ++d) total += bits[d];
  if (total > 31)
    throw std::runtime_error("Z-order cell keys need " + std::to_string(total) +
                             " bits (cells padded to powers of two per axis), more than the 31 of a 32-bit key; "
                             "use a larger cell size or the cell order sort_x or hilbert");
  int order[3] = {0, 1, 2};
  std::stable_sort(order, order + dims, [&](int a, int b) { return bits[a] < bits[b]; });
  auto mask = [](int nbits) { return nbits > 0 ? (1u << nbits) - 1u : 0u; };
  for (int d = 0; d < dims; ++d) out[d] = AxisLayout{};
  if (dims == 3) {
    const int b0 = bits[order[0]], b1 = bits[order[1]], b2 = bits[order[2]];
    for (int d = 0; d < 3; ++d) {  // bits every axis has: 3-way interleave, x lowest
      out[d].mask3 = mask(b0);
      out[d].shift3 = d;
    }
    const int lo_axis = std::min(order[1], order[2]);
    for (int d : {order[1], order[2]}) {  // bits only the two longer axes have: 2-way
      out[d].mask2 = mask(b1 - b0);
      out[d].low = b0;
      out[d].shift2 = out[d].mask2 ? 3 * b0 + (d == lo_axis ? 0 : 1) : 0;
    }
    AxisLayout& longest = out[order[2]];  // the rest of the longest axis
    longest.mask1 = mask(b2 - b1);
    longest.mid = b1;
    longest.shift1 = longest.mask1 ? 3 * b0 + 2 * (b1 - b0) : 0;
  } else {
    const int b0 = bits[order[0]], b1 = bits[order[1]];
    for (int d = 0; d < 2; ++d) {  // bits both axes have: 2-way interleave, x lowest
      out[d].mask2 = mask(b0);
      out[d].shift2 = d;
    }
    AxisLayout& longest = out[order[1]];
    longest.mask1 = mask(b1 - b0);
    longest.mid = b0;
    longest.shift1 = longest.mask1 ? 2 * b0 : 0;
  }
  return total;
}

}  // namespace morton

std::uint32_t SortXY::prepare(const CellGrid& grid) {
  const int bits[2] = {morton::bits_for(grid.n[0]), morton::bits_for(grid.n[1])};
  const int plane_bits = morton::make_layouts(bits, 2, layout_);
  const double keys = std::ldexp(1.0, plane_bits) * grid.n[2];
  if (keys >= 4294967295.0)
    throw std::runtime_error("sort_xy: " + std::to_string(keys) +
                             " padded cells do not fit 32-bit keys; use a larger cell size or sort_x");
  plane_ = 1u << plane_bits;
  padded_[0] = 1 << bits[0];
  padded_[1] = 1 << bits[1];
  padded_[2] = grid.n[2];
  return plane_ * static_cast<std::uint32_t>(grid.n[2]);
}

std::uint32_t SortXYZ::prepare(const CellGrid& grid) {
  const int bits[3] = {morton::bits_for(grid.n[0]), morton::bits_for(grid.n[1]), morton::bits_for(grid.n[2])};
  const int total = morton::make_layouts(bits, 3, layout_);
  for (int d = 0; d < 3; ++d) padded_[d] = 1 << bits[d];
  return 1u << total;
}
}  // namespace sphnl
