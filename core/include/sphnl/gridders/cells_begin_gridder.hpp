#pragma once
// What gridders A and B (paper §2.3) both produce, and how a cell is read
// from it: PartsSorted, the particle indices grouped by cell, and CellsBegin,
// the first slot of each cell plus the end. A and B differ only in how
// build() fills them (sliding_vector*.hpp insert, preconditioned_vector.hpp
// counts first).
#include <algorithm>

#include "sphnl/gridders/gridder.hpp"

namespace sphnl {

class CellsBeginGridder : public Gridder {
 public:
  std::uint32_t gather_cell(std::uint32_t key, std::uint32_t* out) const override {
    const std::uint32_t b = cells_begin_[key], e = cells_begin_[key + 1];
    std::copy(parts_sorted_.begin() + b, parts_sorted_.begin() + e, out);
    return e - b;
  }

  std::span<const std::uint32_t> cell_members(std::uint32_t key, std::uint32_t*) const override {
    return {parts_sorted_.data() + cells_begin_[key], cells_begin_[key + 1] - cells_begin_[key]};
  }

  std::span<const std::uint32_t> cells_begin() const override {
    if (cells_begin_.empty()) return {};
    return {cells_begin_.data(), std::size_t{num_keys_} + 1};
  }

  void cell_order_permutation(std::vector<std::uint32_t>& order) const override {
    order.assign(parts_sorted_.begin(), parts_sorted_.begin() + stored_);
  }

  void renumber(std::span<const std::uint32_t> new_index_of_old) override {
    for (std::uint32_t k = 0; k < stored_; ++k) parts_sorted_[k] = new_index_of_old[parts_sorted_[k]];
  }

  std::size_t bytes() const override {
    return (cells_begin_.capacity() + parts_sorted_.capacity()) * sizeof(std::uint32_t);
  }

 protected:
  /// After build() has filled both arrays: the fullest cell and the
  /// particles stored (those outside the grid are not).
  void finish_build(std::uint32_t stored) {
    std::uint32_t max_count = 0;
    for (std::uint32_t k = 0; k < num_keys_; ++k)
      max_count = std::max(max_count, cells_begin_[k + 1] - cells_begin_[k]);
    max_cell_count_ = max_count;
    stored_ = stored;
  }

  std::vector<std::uint32_t> cells_begin_;   // CellsBegin: first slot of each cell, plus the end
  std::vector<std::uint32_t> parts_sorted_;  // PartsSorted: particle indices grouped by cell
  std::uint32_t stored_ = 0;                 // gridded particles (out ones are not stored)
};

}  // namespace sphnl
