#pragma once
// Cell-linked list (CLL, paper §2.5): no list at all. Every step, every home
// cell is swept with its forward neighbour cells, and the candidates are
// distance-tested right before the pair kernel runs on the survivors.
#include <vector>

#include "sphnl/neighbours/cell_sweep.hpp"
#include "sphnl/neighbours/pair_counts.hpp"
#include "sphnl/neighbours/pair_filter.hpp"
#include "sphnl/neighbours/pair_operation.hpp"
#include "sphnl/neighbours/particle_grid.hpp"

namespace sphnl {

class CellLinkedList {
 public:
  /// Runs ops[thread].interact on every pair with r^2 < support2 (once per pair).
  template <PairOperation Op>
  PairCounts for_each_pair(const ParticleGrid& pg, ParticleSet& ps, std::vector<Op>& ops, double support2) {
    const int threads = static_cast<int>(ops.size());
    counts_.assign(threads, PairCounts{});
    sweep_.run(pg.grid(), pg.order(), pg.gridder(), ps, Op::kFields, threads,
               [&](int t, CellSweep::Scratch& s, std::uint32_t n_home) {
                 const ParticleView v = s.buffer.view();
                 const std::uint32_t total = s.buffer.size();
                 std::uint32_t* survivors = s.survivors.data();
                 PairCounts& c = counts_[t];
                 for (std::uint32_t i = 0; i < n_home; ++i) {
                   const int m = filter_range(v, i, i + 1, total, support2, survivors);
                   ops[t].interact(v, i, survivors, m);
                   c.candidates += total - i - 1;
                   c.interactions += static_cast<std::uint64_t>(m);
                 }
               });
    PairCounts sum;
    for (const auto& c : counts_) sum += c;
    return sum;
  }

  std::size_t scratch_bytes() const { return sweep_.bytes(); }

 private:
  CellSweep sweep_;
  std::vector<PairCounts> counts_;
};

}  // namespace sphnl
