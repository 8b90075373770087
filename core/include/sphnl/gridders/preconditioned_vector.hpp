#pragma once
// Gridder B, "preconditioned dynamic vector" (paper §2.3): count the particles
// of every cell first, prefix-sum the counts into CellsBegin, then place each
// particle straight into its slot of PartsSorted — no shifting.
#include <algorithm>

#include "sphnl/gridders/cells_begin_gridder.hpp"
#include "sphnl/orderings/cell_order.hpp"

namespace sphnl {

class PreconditionedVector final : public CellsBeginGridder {
 public:
  const char* name() const override { return "B"; }

  void build(std::span<const std::uint32_t> cell_key, std::uint32_t num_keys) override {
    num_keys_ = num_keys;
    const std::size_t n = cell_key.size();
    cells_begin_.assign(std::size_t{num_keys} + 1, 0);
    // Pass 1: particles per cell (the "extra arrays" that precondition the vector).
    for (std::size_t i = 0; i < n; ++i)
      if (cell_key[i] != kNoCell) ++cells_begin_[cell_key[i] + 1];
    std::uint32_t max_count = 0;
    for (std::uint32_t k = 0; k < num_keys; ++k) {
      max_count = std::max(max_count, cells_begin_[k + 1]);
      cells_begin_[k + 1] += cells_begin_[k];
    }
    max_cell_count_ = max_count;
    // Pass 2: place particles; `cursor_` is where the next particle of a cell goes.
    cursor_.assign(cells_begin_.begin(), cells_begin_.end() - 1);
    parts_sorted_.resize(cells_begin_[num_keys]);
    for (std::size_t i = 0; i < n; ++i)
      if (cell_key[i] != kNoCell) parts_sorted_[cursor_[cell_key[i]]++] = static_cast<std::uint32_t>(i);
    stored_ = cells_begin_[num_keys];
  }

  std::size_t bytes() const override {
    return CellsBeginGridder::bytes() + cursor_.capacity() * sizeof(std::uint32_t);
  }

 private:
  std::vector<std::uint32_t> cursor_;        // next free slot per cell while placing
};

}  // namespace sphnl
