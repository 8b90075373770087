#pragma once
// What both variants of gridder A (paper §2.3, sliding dynamic vector) store
// and how a cell is read from it: PartsSorted, the particle indices grouped by
// cell, and CellsBegin, the first slot of each cell plus the end. The
// variants differ only in how build() inserts (sliding_vector.hpp,
// sliding_vector_shift_all.hpp).
#include <algorithm>

#include "sphnl/gridders/gridder.hpp"

namespace sphnl {

class SlidingVectorBase : public Gridder {
 public:
  const char* name() const override { return "A"; }

  std::uint32_t gather_cell(std::uint32_t key, std::uint32_t* out) const override {
    const std::uint32_t b = cells_begin_[key], e = cells_begin_[key + 1];
    std::copy(parts_sorted_.begin() + b, parts_sorted_.begin() + e, out);
    return e - b;
  }

  std::span<const std::uint32_t> cell_members(std::uint32_t key, std::uint32_t*) const override {
    return {parts_sorted_.data() + cells_begin_[key], cells_begin_[key + 1] - cells_begin_[key]};
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
  /// After the insertions: the fullest cell and the particles stored.
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
