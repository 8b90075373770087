#pragma once
// Gridder A, "sliding dynamic vector" (paper §2.3, Fig. 2), variant
// `gridder_a_variant=shift_all`: particles are inserted one by one into
// PartsSorted at the end of their cell, displacing every particle stored after
// that point by one slot, and CellsBegin of EVERY later cell of the grid is
// moved up by one. The displacements cost O(N) per insertion in scattered
// order and nothing in cell order, but the re-adjustment of CellsBegin costs
// O(cells) per insertion whatever the order. The paper's variant, whose
// insertions in cell order cost O(1), is SlidingVector (sliding_vector.hpp);
// this one is kept as an ablation (README.md, "Ablations").
#include <cstring>

#include "sphnl/gridders/sliding_vector_base.hpp"
#include "sphnl/orderings/cell_order.hpp"

namespace sphnl {

class SlidingVectorShiftAll final : public SlidingVectorBase {
 public:
  void build(std::span<const std::uint32_t> cell_key, std::uint32_t num_keys) override {
    num_keys_ = num_keys;
    const std::size_t n = cell_key.size();
    cells_begin_.assign(std::size_t{num_keys} + 1, 0);
    parts_sorted_.resize(n);  // capacity for every particle; `stored` is the used length
    std::uint32_t* parts = parts_sorted_.data();
    std::uint32_t* begin = cells_begin_.data();
    std::uint32_t stored = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const std::uint32_t c = cell_key[i];
      if (c == kNoCell) continue;
      // Insert at the end of cell c: slide PartsSorted[at, stored) one slot up...
      const std::uint32_t at = begin[c + 1];
      std::memmove(parts + at + 1, parts + at, std::size_t{stored - at} * sizeof(std::uint32_t));
      parts[at] = static_cast<std::uint32_t>(i);
      ++stored;
      // ...and re-adjust CellsBegin of every later cell.
      for (std::uint32_t k = c + 1; k <= num_keys; ++k) ++begin[k];
    }
    finish_build(stored);
  }
};

}  // namespace sphnl
