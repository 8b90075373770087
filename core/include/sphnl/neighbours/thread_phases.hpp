#pragma once
// ThreadPhases: `thread_updates=phased` (README.md, "Configuration"). A pair
// pass updates both particles of a pair, so a home cell of the half-stencil
// sweep writes the particles of its own cell and of its occupied forward
// cells: its write set. With the default (`private`) every thread but the first
// writes into private copies of the accumulators that are summed afterwards;
// here no copy exists, and the home cells are instead put into phases so that
// within a phase no two threads write the same cell:
//
//   cells are owned by the thread whose key range holds them (CellSweep's
//   split). An "export" cell writes a cell of another thread; a cell written
//   by another thread's export is "foreign"; an own-only cell whose write set
//   holds a foreign cell is "contested".
//   phase 1 (parallel)  exports, and own-only cells that are not contested;
//   phase 2 (parallel)  contested cells (they write only their own thread's
//                       cells, while no export runs), plus enough not
//                       contested own-only cells to even out the two phases;
//   serial              exports that would meet another thread's export in
//                       phase 1 (short ranges, a periodic seam): run by one
//                       thread after the parallel phases.
// Every particle's sums are then made by one thread in a fixed order, so
// results are deterministic for a fixed thread count (and differ from the
// `private` way only by the order of the sums). Valid for any cell order: the
// write sets are walked, not assumed from the key order.
#include <cstdint>
#include <span>
#include <utility>
#include <vector>

#include "sphnl/grid.hpp"
#include "sphnl/orderings/cell_order.hpp"

namespace sphnl {

/// Cuts the keys into `threads` contiguous ranges of about equal total
/// weight: thread t gets [begin[t], begin[t+1]). The split of CellSweep (by
/// fluid weight) and of a Verlet list's phased loop (by list entries).
void cut_key_ranges(std::span<const double> weight, int threads, std::vector<std::uint32_t>& begin);

class ThreadPhases {
 public:
  static constexpr int kParallelPhases = 2;

  /// Plans the phases for `threads` > 1 key ranges thread_begin[t] ..
  /// thread_begin[t+1] over the keys of `order`; weight[key] > 0 marks an
  /// occupied cell and is its work (the balance of the two phases).
  void plan(const CellGrid& grid, const CellOrder& order, std::span<const std::uint32_t> thread_begin,
            std::span<const double> weight, int threads);

  /// Home-cell keys of thread t in parallel phase p, in key order.
  std::span<const std::uint32_t> keys(int phase, int thread) const {
    const auto& v = keys_[static_cast<std::size_t>(phase * threads_ + thread)];
    return {v.data(), v.size()};
  }
  /// Keys run by one thread after the parallel phases, in key order.
  std::span<const std::uint32_t> serial() const { return serial_; }

  std::size_t bytes() const;

 private:
  int threads_ = 0;
  std::vector<std::vector<std::uint32_t>> keys_;  // [phase * threads + thread]
  std::vector<std::uint32_t> serial_;
  std::vector<std::int16_t> owner_;   // per key: thread of the key range; -1 empty
  std::vector<std::uint8_t> state_;   // per key: kInterior, kExport, kSerial | kForeign | kContested
  std::vector<std::int16_t> stamp_;   // per key: the thread whose phase-1 export writes it; -1 none
  std::vector<std::uint32_t> occupied_;      // occupied keys, in key order
  std::vector<std::uint32_t> write_begin_;   // per occupied key: its write set in writes_
  std::vector<std::uint32_t> writes_;        // the write sets, one after the other
};

}  // namespace sphnl
