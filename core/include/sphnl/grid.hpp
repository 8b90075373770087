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
  /// > 0: y is periodic with this period, box.lo[1] <= y < box.lo[1] + period_y.
  /// The period holds a whole number n[1] of cells (the last one is wider, up
  /// to two cell sizes), so a neighbour cell across the seam is cell 0 or n[1]-1.
  double period_y = 0;

  CellGrid() = default;
  CellGrid(const Box& b, double size, double period = 0)
      : box(b), cell_size(size), inv_cell_size(1.0 / size), period_y(period) {
    for (int d = 0; d < 3; ++d)
      n[d] = std::max(1, static_cast<int>(std::ceil((b.hi[d] - b.lo[d]) * inv_cell_size)));
    if (period_y > 0) {
      // Floor, not ceil: every cell at least `size` wide, so pairs closer than
      // `size` are in the same or adjacent cells also across the seam.
      n[1] = static_cast<int>(std::floor(period_y * inv_cell_size * (1 + 1e-12)));
      box.hi[1] = box.lo[1] + period_y;
    }
  }
  /// Fewer than three cells across the period would make a cell its own
  /// neighbour (or one neighbour twice) through the seam.
  static constexpr int kMinPeriodicCells = 3;
  long num_cells() const { return static_cast<long>(n[0]) * n[1] * n[2]; }
  /// Cells a grid of side `size` over `b` would have (non-periodic), counted in
  /// double so that a side far below the box cannot overflow: lets a caller
  /// choose the side before building the grid.
  static double cells_needed(const Box& b, double size) {
    double cells = 1;
    for (int d = 0; d < 3; ++d) cells *= std::max(1.0, std::ceil((b.hi[d] - b.lo[d]) / size));
    return cells;
  }
  /// Cell coordinate of a position along axis d, clamped into the grid (the
  /// caller guarantees the position is inside the box).
  int coord(double v, int d) const {
    const int c = static_cast<int>((v - box.lo[d]) * inv_cell_size);
    return std::clamp(c, 0, n[d] - 1);
  }
};

}  // namespace sphnl
