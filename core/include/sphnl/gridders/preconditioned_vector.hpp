#pragma once
// Gridder B, "preconditioned dynamic vector" (paper §2.3): count the particles
// of every cell first, prefix-sum the counts into CellsBegin, then place each
// particle straight into its slot of PartsSorted — no shifting.
#include <algorithm>

#include "sphnl/gridders/gridder.hpp"
#include "sphnl/orderings/cell_order.hpp"

namespace sphnl {

class PreconditionedVector final : public Gridder {
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
  }

  std::uint32_t gather_cell(std::uint32_t key, std::uint32_t* out) const override {
    const std::uint32_t b = cells_begin_[key], e = cells_begin_[key + 1];
    std::copy(parts_sorted_.begin() + b, parts_sorted_.begin() + e, out);
    return e - b;
  }

  std::span<const std::uint32_t> cell_members(std::uint32_t key, std::uint32_t*) const override {
    return {parts_sorted_.data() + cells_begin_[key], cells_begin_[key + 1] - cells_begin_[key]};
  }

  void cell_order_permutation(std::vector<std::uint32_t>& order) const override {
    order.assign(parts_sorted_.begin(), parts_sorted_.end());
  }

  void renumber(std::span<const std::uint32_t> new_index_of_old) override {
    for (auto& p : parts_sorted_) p = new_index_of_old[p];
  }

  std::size_t bytes() const override {
    return (cells_begin_.capacity() + cursor_.capacity() + parts_sorted_.capacity()) * sizeof(std::uint32_t);
  }

 private:
  std::vector<std::uint32_t> cells_begin_;   // CellsBegin: first slot of each cell, plus the end
  std::vector<std::uint32_t> cursor_;        // next free slot per cell while placing
  std::vector<std::uint32_t> parts_sorted_;  // PartsSorted: particle indices grouped by cell
};

}  // namespace sphnl
