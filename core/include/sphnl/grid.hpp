#pragma once
// CellGrid: the division of the domain into cubic cells (paper §2.5 (a)): side
// 2h for the cell-linked list, 2H = 2h + dh for Verlet lists.
#include <algorithm>
#include <cmath>
#include <cstdint>

namespace sphnl {

struct Box {
  double lo[3] = {0, 0, 0};
  double hi[3] = {0, 0, 0};
  bool contains(double x, double y, double z) const {
    return x >= lo[0] && x <= hi[0] && y >= lo[1] && y <= hi[1] && z >= lo[2] && z <= hi[2];
  }
};

struct CellGrid {
  Box box;
  double cell_size = 0, inv_cell_size = 0;
  int n[3] = {0, 0, 0};  // ncx, ncy, ncz

  CellGrid() = default;
  CellGrid(const Box& b, double size) : box(b), cell_size(size), inv_cell_size(1.0 / size) {
    for (int d = 0; d < 3; ++d)
      n[d] = std::max(1, static_cast<int>(std::ceil((b.hi[d] - b.lo[d]) * inv_cell_size)));
  }
  long num_cells() const { return static_cast<long>(n[0]) * n[1] * n[2]; }
  /// Cell coordinate of a position along axis d, clamped into the grid (the
  /// caller guarantees the position is inside the box).
  int coord(double v, int d) const {
    const int c = static_cast<int>((v - box.lo[d]) * inv_cell_size);
    return std::clamp(c, 0, n[d] - 1);
  }
};

}  // namespace sphnl
