// Run-time factories for cell orders and gridders, and the shared defaults.
#include <stdexcept>
#include <string>

#include "sphnl/gridders/gridder.hpp"
#include "sphnl/gridders/preconditioned_vector.hpp"
#include "sphnl/orderings/cell_order.hpp"
#include "sphnl/orderings/sort_x.hpp"

namespace sphnl {

void CellOrder::setup(const CellGrid& grid) {
  num_keys_ = prepare(grid);
  key_coords_.assign(num_keys_, kNoCellCoords);
  for (int cz = 0; cz < grid.n[2]; ++cz)
    for (int cy = 0; cy < grid.n[1]; ++cy)
      for (int cx = 0; cx < grid.n[0]; ++cx)
        key_coords_[key(cx, cy, cz)] = static_cast<std::uint64_t>(cx) | (static_cast<std::uint64_t>(cy) << 21) |
                                       (static_cast<std::uint64_t>(cz) << 42);
}

std::unique_ptr<CellOrder> make_cell_order(CellOrderKind kind) {
  switch (kind) {
    case CellOrderKind::sort_x: return std::make_unique<SortX>();
    default: break;
  }
  throw ConfigError(std::string("cell_order '") + to_string(kind) + "' is not implemented yet; use sort_x");
}

void Gridder::cell_order_permutation(std::vector<std::uint32_t>& order) const {
  order.resize(0);
  std::vector<std::uint32_t> cell(max_cell_count_);
  for (std::uint32_t k = 0; k < num_keys_; ++k) {
    const std::uint32_t count = gather_cell(k, cell.data());
    order.insert(order.end(), cell.begin(), cell.begin() + count);
  }
}

std::unique_ptr<Gridder> make_gridder(GridderKind kind, const GridderOptions& /*options*/) {
  switch (kind) {
    case GridderKind::B: return std::make_unique<PreconditionedVector>();
    default: break;
  }
  throw ConfigError(std::string("gridder '") + to_string(kind) + "' is not implemented yet; use B");
}

}  // namespace sphnl
