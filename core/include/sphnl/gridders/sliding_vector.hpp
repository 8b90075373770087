#pragma once
// Gridder A, "sliding dynamic vector" (paper §2.3, Fig. 2): particles are
// inserted one by one into PartsSorted at the end of their cell, displacing
// the particles stored after that point by one slot, and CellsBegin is
// re-adjusted to point at the beginning of each cell. PartsSorted grows like
// a dynamic vector: CellsBegin is kept only up to the last cell that holds a
// particle so far (every cell after it starts at the end of the vector), so
// an insertion costs the particles it displaces plus the occupied cells after
// its own. Particles arriving in cell order (after reordering, §2.4) are
// appended at O(1) each; particles arriving in scattered order cost O(N) per
// insertion. That cost is what Figs. 6 and 8 measure: it is deliberately not
// replaced by a counting sort (that is gridder B). The variant that
// re-adjusts CellsBegin of every later cell of the grid on every insertion is
// SlidingVectorShiftAll (`gridder_a_variant=shift_all`).
#include <cstring>

#include "sphnl/gridders/sliding_vector_base.hpp"
#include "sphnl/orderings/cell_order.hpp"

namespace sphnl {

class SlidingVector final : public SlidingVectorBase {
 public:
  void build(std::span<const std::uint32_t> cell_key, std::uint32_t num_keys) override {
    num_keys_ = num_keys;
    const std::size_t n = cell_key.size();
    cells_begin_.resize(std::size_t{num_keys} + 1);
    parts_sorted_.resize(n);  // capacity for every particle; `stored` is the used length
    std::uint32_t* parts = parts_sorted_.data();
    std::uint32_t* begin = cells_begin_.data();
    std::uint32_t stored = 0;
    // Cells [0, occupied) have their CellsBegin; begin[occupied] = stored and
    // every cell after it is (still) empty at the end of the vector.
    std::uint32_t occupied = 0;
    begin[0] = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const std::uint32_t c = cell_key[i];
      if (c == kNoCell) continue;
      if (c >= occupied) {  // the vector grows: empty cells up to c start at its end
        for (std::uint32_t k = occupied + 1; k <= c + 1; ++k) begin[k] = stored;
        occupied = c + 1;
      }
      // Insert at the end of cell c: slide PartsSorted[at, stored) one slot up...
      const std::uint32_t at = begin[c + 1];
      std::memmove(parts + at + 1, parts + at, std::size_t{stored - at} * sizeof(std::uint32_t));
      parts[at] = static_cast<std::uint32_t>(i);
      ++stored;
      // ...and re-adjust CellsBegin of the later occupied cells.
      for (std::uint32_t k = c + 1; k <= occupied; ++k) ++begin[k];
    }
    for (std::uint32_t k = occupied + 1; k <= num_keys; ++k) begin[k] = stored;
    finish_build(stored);
  }
};

}  // namespace sphnl
