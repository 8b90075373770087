#pragma once
// The stencil walk of every neighbour path: the cells around a home cell that
// can hold a point closer than one cell side, clipped to the grid and, where
// y is periodic (CellGrid::period_y), wrapped across the seam.
//   kFullStencil  the 27 cells (home included), for full lists
//                 (NeighbourSearch: each pair seen from both points);
//   kHalfStencil  the 13 cells after the home cell, for each pair of cells
//                 once (the cell sweep of §3.2: CLL and Verlet-list builds).
#include <array>

#include "sphnl/grid.hpp"
#include "sphnl/orderings/cell_order.hpp"

namespace sphnl {

using CellOffset = std::array<int, 3>;  // (dx, dy, dz) in cells

/// The 13 cell offsets lexicographically after (0,0,0) in (dz, dy, dx).
inline constexpr std::array<CellOffset, 13> kHalfStencil = {{
    {1, 0, 0},  {-1, 1, 0}, {0, 1, 0},  {1, 1, 0},  {-1, -1, 1}, {0, -1, 1}, {1, -1, 1},
    {-1, 0, 1}, {0, 0, 1},  {1, 0, 1},  {-1, 1, 1}, {0, 1, 1},   {1, 1, 1},
}};

/// The 27 cell offsets in (dz, dy, dx) lexicographic order; (0,0,0) is entry 13.
inline constexpr std::array<CellOffset, 27> kFullStencil = [] {
  std::array<CellOffset, 27> s{};
  int k = 0;
  for (int dz = -1; dz <= 1; ++dz)
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) s[k++] = {dx, dy, dz};
  return s;
}();

/// Calls visit(key, y_shift) for every cell home + offset of `stencil` that
/// lies in the grid, in stencil order. Across a periodic seam the cell is the
/// image on the other side and y_shift (+-period_y) is what must be added to
/// its points' y to bring them next to the home cell; 0 elsewhere.
template <std::size_t N, class Visit>
inline void for_each_stencil_cell(const CellGrid& grid, const CellOrder& order, CellOrder::Coords home,
                                  const std::array<CellOffset, N>& stencil, Visit&& visit) {
  const bool periodic = grid.period_y > 0;
  for (const CellOffset& o : stencil) {
    const int nx = home.x + o[0], nz = home.z + o[2];
    int ny = home.y + o[1];
    double shift = 0;
    if (periodic && (ny < 0 || ny >= grid.n[1])) {  // the image across the seam
      shift = ny < 0 ? -grid.period_y : grid.period_y;
      ny -= ny < 0 ? -grid.n[1] : grid.n[1];
    }
    if (nx < 0 || ny < 0 || nz < 0 || nx >= grid.n[0] || ny >= grid.n[1] || nz >= grid.n[2]) continue;
    visit(order.key(nx, ny, nz), shift);
  }
}

}  // namespace sphnl
