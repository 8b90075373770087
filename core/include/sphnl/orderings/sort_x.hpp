#pragma once
// SortX, the traditional order of SPHysics (paper eq. 8):
// icell = cz * ncx * ncy + cy * ncx + cx.
#include "sphnl/orderings/cell_order.hpp"

namespace sphnl {

class SortX final : public CellOrderWithKey<SortX> {
  friend class CellOrderWithKey<SortX>;
 public:
  const char* name() const override { return "sort_x"; }

 protected:
  std::uint32_t prepare(const CellGrid& grid) override {
    ncx_ = static_cast<std::uint32_t>(grid.n[0]);
    ncxy_ = ncx_ * static_cast<std::uint32_t>(grid.n[1]);
    return static_cast<std::uint32_t>(grid.num_cells());
  }

 private:
  std::uint32_t inline_key(int cx, int cy, int cz) const {
    return static_cast<std::uint32_t>(cz) * ncxy_ + static_cast<std::uint32_t>(cy) * ncx_ + static_cast<std::uint32_t>(cx);
  }
  std::uint32_t ncx_ = 0, ncxy_ = 0;
};

}  // namespace sphnl
