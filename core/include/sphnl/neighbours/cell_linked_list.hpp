#pragma once
// Cell-linked list (CLL, paper §2.5): no list at all. Every step, every home
// cell is swept with its forward neighbour cells, and the candidates are
// distance-tested right before the pair kernel runs on the survivors.
// How the cells are read is an ablation (README.md, "Ablations"), decided
// once per pass: gathered into a CellBuffer (default) or read in place through
// the gridder (`pair_loop=direct`); the filter and the kernel are the same.
// `pair_loop=masked` reads the gathered cells too, but hands the kernel
// blocks of consecutive entries with a lane mask instead of a compacted list
// of survivors: more lanes evaluated, none gathered or scattered.
#include <algorithm>
#include <bit>
#include <vector>

#include "sphnl/neighbours/cell_sweep.hpp"
#include "sphnl/neighbours/home_candidates.hpp"
#include "sphnl/neighbours/pair_counts.hpp"
#include "sphnl/neighbours/pair_filter.hpp"
#include "sphnl/neighbours/pair_loop_options.hpp"
#include "sphnl/neighbours/pair_operation.hpp"
#include "sphnl/neighbours/particle_grid.hpp"

namespace sphnl {

class CellLinkedList {
 public:
  /// Runs ops[thread].interact on every pair with r^2 < support2 (once per pair).
  template <PairOperation Op>
  PairCounts for_each_pair(const ParticleGrid& pg, ParticleSet& ps, std::vector<Op>& ops, double support2,
                           const PairLoopOptions& options = {}) {
    counts_.assign(ops.size(), PairCounts{});
    sweep_.set_split(options.split);
    if (options.skip_boundary_pairs && options.loop != PairLoopKind::gather)
      throw std::logic_error("skip_boundary_pairs needs the gather loop (pair_loop=gather)");
    if (options.loop == PairLoopKind::direct) {
      if (options.simd) direct<true>(pg, ps, ops, support2, options.updates);
      else direct<false>(pg, ps, ops, support2, options.updates);
    } else if (options.loop == PairLoopKind::masked) {
      if (options.simd) masked<true>(pg, ps, ops, support2, options.updates);
      else masked<false>(pg, ps, ops, support2, options.updates);
    } else if (options.skip_boundary_pairs) {
      if (options.simd) gathered<true, true>(pg, ps, ops, support2, options.updates);
      else gathered<false, true>(pg, ps, ops, support2, options.updates);
    } else {
      if (options.simd) gathered<true, false>(pg, ps, ops, support2, options.updates);
      else gathered<false, false>(pg, ps, ops, support2, options.updates);
    }
    PairCounts sum;
    for (const auto& c : counts_) sum += c;
    sum.busy_seconds = sweep_.busy_seconds();
    sum.region_seconds = sweep_.region_seconds();
    sum.reduce_seconds = sweep_.reduce_seconds();
    return sum;
  }

  std::size_t scratch_bytes() const { return sweep_.bytes(); }

 private:
  template <bool Simd, bool SkipBoundaryPairs, PairOperation Op>
  void gathered(const ParticleGrid& pg, ParticleSet& ps, std::vector<Op>& ops, double support2, ThreadUpdates updates) {
    sweep_.run(pg.grid(), pg.order(), pg.gridder(), ps, Op::kFields, static_cast<int>(ops.size()),
               [&](int t, CellSweep::Scratch& s, std::uint32_t n_home) {
                 const ParticleView v = s.buffer.view();
                 HomeCandidates<Simd, SkipBoundaryPairs> home(v, s.buffer.size(), s.fluid_slots, s.first_partner);
                 std::uint32_t* survivors = s.survivors.data();
                 PairCounts& c = counts_[t];
                 // The filter reads the double copy; an operation asking for the
                 // float copy (precision=mixed) reads that one.
                 const ParticleViewF vf = s.buffer.float_view();
                 for (std::uint32_t i = 0; i < n_home; ++i) {
                   const int m = home.filter(i, support2, survivors, c.candidates);
                   if constexpr ((Op::kFields & fields::float_copy) != 0) ops[t].interact(vf, i, survivors, m);
                   else ops[t].interact(v, i, survivors, m);
                   c.interactions += static_cast<std::uint64_t>(m);
                 }
               },
               updates, pg.ghost_begin());
  }

  /// `pair_loop=masked`: the pairs of the gathered home cell as j-blocks
  /// (filter_blocks); candidates counted as the gather loop counts them.
  template <bool Simd, PairOperation Op>
  void masked(const ParticleGrid& pg, ParticleSet& ps, std::vector<Op>& ops, double support2, ThreadUpdates updates) {
    sweep_.run(pg.grid(), pg.order(), pg.gridder(), ps, Op::kFields, static_cast<int>(ops.size()),
               [&](int t, CellSweep::Scratch& s, std::uint32_t n_home) {
                 const ParticleView v = s.buffer.view();
                 const std::uint32_t total = s.buffer.size();
                 std::uint32_t* first = s.survivors.data();
                 std::uint8_t* lanes = s.block_lanes(total);
                 PairCounts& c = counts_[t];
                 const ParticleViewF vf = s.buffer.float_view();
                 for (std::uint32_t i = 0; i < n_home; ++i) {
                   const std::uint32_t j0 = std::max(i + 1, s.first_partner);
                   if (j0 >= total) continue;
                   c.candidates += total - j0;
                   const int blocks = filter_blocks<Simd>(v, i, j0, total, support2, first, lanes);
                   std::uint64_t pairs = 0;
                   for (int b = 0; b < blocks; ++b) pairs += static_cast<unsigned>(std::popcount(unsigned{lanes[b]}));
                   c.interactions += pairs;
                   c.idle_lanes += static_cast<std::uint64_t>(blocks) * kPairBlock - pairs;
                   if constexpr ((Op::kFields & fields::float_copy) != 0) run_blocks(ops[t], vf, i, first, lanes, blocks, s);
                   else run_blocks(ops[t], v, i, first, lanes, blocks, s);
                 }
               },
               updates, pg.ghost_begin());
  }

  /// An operation without interact_blocks gets the blocks' pairs as a list
  /// (in the same order), collected in the thread's `block_pairs`.
  template <PairOperation Op, class View>
  static void run_blocks(Op& op, const View& v, std::uint32_t i, const std::uint32_t* first, const std::uint8_t* lanes,
                         int blocks, CellSweep::Scratch& s) {
    if constexpr (BlockPairOperation<Op, View>) {
      op.interact_blocks(v, i, first, lanes, blocks);
    } else {
      std::vector<std::uint32_t>& list = s.block_pairs;
      list.clear();
      for (int b = 0; b < blocks; ++b)
        for (int k = 0; k < kPairBlock; ++k)
          if ((lanes[b] >> k) & 1u) list.push_back(first[b] + static_cast<std::uint32_t>(k));
      op.interact(v, i, list.data(), static_cast<int>(list.size()));
    }
  }

  /// Candidates of one cell read in place: a contiguous index range (B and A
  /// after reordering: cells are ranges of the reordered arrays) takes the
  /// range filter, anything else the list filter; both drop boundary pairs.
  template <bool Simd>
  static int filter_cell(const ParticleView& v, std::uint32_t i, std::span<const std::uint32_t> cell, double support2,
                         std::uint32_t* out) {
    if (cell.empty()) return 0;
    if (cell.back() - cell.front() == cell.size() - 1)  // increasing indices: contiguous
      return filter_range<Simd>(v, i, cell.front(), cell.back() + 1, support2, out);
    return filter_list<Simd, true>(v, i, cell.data(), static_cast<int>(cell.size()), support2, out);
  }

  template <bool Simd, PairOperation Op>
  void direct(const ParticleGrid& pg, ParticleSet& ps, std::vector<Op>& ops, double support2, ThreadUpdates updates) {
    sweep_.run_direct(pg.grid(), pg.order(), pg.gridder(), ps, Op::kFields, static_cast<int>(ops.size()),
                      [&](int t, CellSweep::Scratch& s, std::span<const std::uint32_t> home,
                          const CellSweep::ForwardCells& forward) {
                        const ParticleView& v = s.target;
                        std::uint32_t* survivors = s.survivors.data();
                        PairCounts& c = counts_[t];
                        const bool home_pairs = s.first_partner == 0;  // not in a ghost home cell
                        for (std::size_t a = 0; a < home.size(); ++a) {
                          const std::uint32_t i = home[a];
                          int m = home_pairs ? filter_cell<Simd>(v, i, home.subspan(a + 1), support2, survivors) : 0;
                          std::uint64_t tested = home_pairs ? home.size() - a - 1 : 0;
                          for (int k = 0; k < forward.count; ++k) {
                            m += filter_cell<Simd>(v, i, forward.cells[k], support2, survivors + m);
                            tested += forward.cells[k].size();
                          }
                          ops[t].interact(v, i, survivors, m);
                          c.candidates += tested;
                          c.interactions += static_cast<std::uint64_t>(m);
                        }
                      },
                      updates, pg.ghost_begin());
  }

  CellSweep sweep_;
  std::vector<PairCounts> counts_;
};

}  // namespace sphnl
