// The per-grid preparation common to every cell order (paper §2.4) and the
// run-time factory.
#include "sphnl/orderings/cell_order.hpp"

#include "sphnl/input_error.hpp"
#include "sphnl/orderings/hilbert.hpp"
#include "sphnl/orderings/morton.hpp"
#include "sphnl/orderings/sort_x.hpp"

namespace sphnl {

void CellOrder::setup(const CellGrid& grid) {
  num_keys_ = prepare(grid);
  // Padding keys (Z-order) keep kNoCellCoords: the sweep skips them.
  key_coords_.assign(num_keys_, kNoCellCoords);
  for (int cz = 0; cz < grid.n[2]; ++cz)
    for (int cy = 0; cy < grid.n[1]; ++cy)
      for (int cx = 0; cx < grid.n[0]; ++cx)
        key_coords_[key(cx, cy, cz)] = pack_coords(cx, cy, cz);
}

std::unique_ptr<CellOrder> make_cell_order(CellOrderKind kind) {
  switch (kind) {
    case CellOrderKind::sort_x: return std::make_unique<SortX>();
    case CellOrderKind::sort_xy: return std::make_unique<SortXY>();
    case CellOrderKind::sort_xyz: return std::make_unique<SortXYZ>();
    case CellOrderKind::hilbert: return std::make_unique<Hilbert>();
  }
  throw ConfigError("cell_order: unknown value; allowed: sort_x, sort_xy, sort_xyz, hilbert");
}
}  // namespace sphnl
