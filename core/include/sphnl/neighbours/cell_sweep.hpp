#pragma once
// CellSweep: visits every home cell in key order (the sweep of §3.2) with its
// 13 forward neighbour cells (a half stencil: every pair of cells once), gathers
// their particles into a CellBuffer and hands it to a visitor. The cell-linked
// list evaluates pairs from it; Verlet lists build their lists from it.
// Threads take contiguous ranges of home cells holding equal shares of the
// fluid (split_keys: a static split of the key range would hand one thread the
// water and the other the empty upper half of the tank), or with
// ThreadSplit::interactions equal shares of the estimated pair work
// (cell_work.hpp: the cells of the water over the floor bring more pairs per
// fluid particle than the walls and the splashes); each accumulates into
// private arrays that are summed afterwards in a fixed order, so results are
// deterministic for a fixed thread count. ThreadSplit::dynamic cuts nothing:
// the threads take chunks of keys as they finish, balanced whatever a cell
// costs, at the price of bits that vary between runs. With `thread_updates=phased`
// (ThreadPhases) there are no private arrays: the home cells run in phases in
// which no two threads write one particle.
// With a periodic y (CellGrid::period_y) the stencil wraps across the seam and
// the gathered copies of the cells beyond it are shifted by the period, so the
// distance filter and the pair kernel see the nearest image and stay unchanged.
// In a distributed run (`ghost_begin`: particles from there on are ghosts,
// whole cells of other ranks) a pair of two ghosts is never visited: a ghost
// home cell is swept with its owned forward cells only and its particles are
// not paired with each other. Such a pair is evaluated by the rank that owns
// one of them, and no rank integrates a ghost (docs/DESIGN.md, "The parallel
// layer").
#include <omp.h>

#include <array>
#include <cstdint>
#include <span>
#include <stdexcept>
#include <vector>

#include "sphnl/grid.hpp"
#include "sphnl/gridders/gridder.hpp"
#include "sphnl/neighbours/cell_buffer.hpp"
#include "sphnl/neighbours/cell_work.hpp"
#include "sphnl/neighbours/pair_filter.hpp"
#include "sphnl/neighbours/stencil.hpp"
#include "sphnl/neighbours/thread_accumulators.hpp"
#include "sphnl/neighbours/thread_phases.hpp"
#include "sphnl/orderings/cell_order.hpp"
#include "sphnl/particles.hpp"

namespace sphnl {

class CellSweep {
 public:
  /// Thread-private state: a gather buffer, the candidate indices of a home
  /// cell, survivors of the distance filter, and private accumulators.
  struct Scratch {
    CellBuffer buffer;
    std::vector<std::uint32_t> cell_index;
    std::vector<std::uint32_t> survivors;
    std::vector<std::uint32_t> fluid_slots;  // skip_boundary_pairs: fluid entries of the buffer
    std::vector<std::uint8_t> lanes;         // pair_loop=masked: lane masks of the j-blocks
    std::vector<std::uint32_t> block_pairs;  // pair_loop=masked: pairs of the blocks, for list-only operations
    /// Room for the lane masks of one home particle's blocks among `total` entries.
    std::uint8_t* block_lanes(std::uint32_t total) {
      if (lanes.size() < total / kPairBlock + 2) lanes.resize(total / kPairBlock + 2);
      return lanes.data();
    }
    ThreadAccumulators private_acc;  // threads > 0
    ParticleView target;
    /// First buffer entry a home particle is paired with beyond its own
    /// cell's later entries: 0, or n_home for a ghost home cell (its
    /// particles are ghosts: not paired with each other).
    std::uint32_t first_partner = 0;
    /// Seconds this thread spent in its home cells in the last sweep.
    double busy_seconds = 0;
  };

  /// ghost_begin of a run without ghosts.
  static constexpr std::uint32_t kNoGhosts = ~std::uint32_t{0};

  /// Runs `visit(thread, buffer, n_home)` for every non-empty home cell; the
  /// first n_home buffer entries are the home cell's particles.
  /// `updates`: how threads > 1 keep from writing one particle at once.
  /// `ghost_begin`: the first ghost particle (ParticleGrid::ghost_begin).
  template <class Visit>
  void run(const CellGrid& grid, const CellOrder& order, const Gridder& gridder, ParticleSet& ps, unsigned mask,
           int threads, Visit&& visit, ThreadUpdates updates = ThreadUpdates::private_accumulators,
           std::uint32_t ghost_begin = kNoGhosts) {
    const unsigned outputs = mask & (fields::force_out | fields::kgc_m_out);
    sweep(grid, order, gridder, ps, mask, threads, /*gather=*/true, updates,
          [&](int t, Scratch& s, std::uint32_t key, CellOrder::Coords home) {
            std::uint32_t* idx = s.cell_index.data();
            const std::uint32_t n_home = gridder.gather_cell(key, idx);
            if (n_home == 0) return;
            const bool ghost_home = ghost_begin != kNoGhosts && all_ghosts(idx, n_home, ghost_begin);
            std::uint32_t total = n_home;
            int n_seam = 0;  // neighbour cells across a periodic seam: gathered range and y shift
            std::array<SeamCell, kHalfStencil.size()> seam;
            for_each_stencil_cell(grid, order, home, kHalfStencil, [&](std::uint32_t k, double shift) {
              const std::uint32_t begin = total;
              total += gridder.gather_cell(k, idx + total);
              if (ghost_home && all_ghosts(idx + begin, total - begin, ghost_begin)) total = begin;
              if (shift != 0 && total > begin) seam[n_seam++] = {begin, total, shift};
            });
            // A ghost cell with only ghosts around is still visited (with no
            // candidate): a Verlet list gives every gridded particle its row
            // in key order, which its thread phases count on.
            s.first_partner = ghost_home ? n_home : 0;
            s.buffer.gather(ps, idx, total, mask);
            for (int k = 0; k < n_seam; ++k) s.buffer.shift_y(seam[k].begin, seam[k].end, seam[k].shift);
            if (mask & fields::float_copy) s.buffer.fill_float(mask);
            visit(t, s, n_home);
            if (outputs) s.buffer.scatter_add(s.target, outputs | (mask & fields::float_copy));
          });
  }

  /// The 13 forward neighbour cells of a home cell, read in place.
  struct ForwardCells {
    std::array<std::span<const std::uint32_t>, kHalfStencil.size()> cells;
    int count = 0;
  };

  /// `pair_loop=direct` (README.md, "Ablations"): no gather. Runs
  /// `visit(thread, scratch, home, forward)` for every non-empty home cell,
  /// with the particle indices of the home cell and of its forward cells as
  /// the gridder stores them (Gridder::cell_members), so the visitor reads the
  /// particle arrays in place, as the paper's code did. scratch.target views
  /// the particles, its accumulators private for threads > 0. Not for a
  /// periodic grid (no image shift without a copy).
  /// A ghost home cell (see run) comes with its owned forward cells only and
  /// scratch.first_partner > 0: the visitor skips the pairs inside it.
  template <class Visit>
  void run_direct(const CellGrid& grid, const CellOrder& order, const Gridder& gridder, ParticleSet& ps,
                  unsigned mask, int threads, Visit&& visit,
                  ThreadUpdates updates = ThreadUpdates::private_accumulators, std::uint32_t ghost_begin = kNoGhosts) {
    if (grid.period_y > 0) throw std::logic_error("CellSweep::run_direct: a periodic grid needs the gather sweep");
    sweep(grid, order, gridder, ps, mask, threads, /*gather=*/false, updates,
          [&](int t, Scratch& s, std::uint32_t key, CellOrder::Coords home_coords) {
            std::uint32_t* idx = s.cell_index.data();  // gridder D writes its walks here
            const std::span<const std::uint32_t> home = gridder.cell_members(key, idx);
            if (home.empty()) return;
            const bool ghost_home =
                ghost_begin != kNoGhosts && all_ghosts(home.data(), static_cast<std::uint32_t>(home.size()), ghost_begin);
            std::uint32_t used = home.data() == idx ? static_cast<std::uint32_t>(home.size()) : 0;
            ForwardCells forward;
            for_each_stencil_cell(grid, order, home_coords, kHalfStencil, [&](std::uint32_t k, double) {
              const std::span<const std::uint32_t> cell = gridder.cell_members(k, idx + used);
              if (cell.empty()) return;
              if (ghost_home && all_ghosts(cell.data(), static_cast<std::uint32_t>(cell.size()), ghost_begin)) return;
              if (cell.data() == idx + used) used += static_cast<std::uint32_t>(cell.size());
              forward.cells[forward.count++] = cell;
            });
            if (ghost_home && forward.count == 0) return;
            s.first_partner = ghost_home ? static_cast<std::uint32_t>(home.size()) : 0;
            visit(t, s, home, forward);
          });
  }

  /// How the next sweeps cut the home cells between threads (the cell-linked
  /// list sets it from its options each pass; a Verlet list's build keeps the
  /// default, its loop has a split of its own).
  void set_split(ThreadSplit split) { split_ = split; }
  /// The timing of the last sweep (PairCounts' busy, region and reduce seconds).
  double busy_seconds() const { return busy_seconds_; }
  double region_seconds() const { return region_seconds_; }
  double reduce_seconds() const { return reduce_seconds_; }

  std::size_t bytes() const;

 private:
  /// Whether the n particles idx[0..n) are all ghosts (cells are whole: a
  /// cell of another rank holds ghosts only; checked, not assumed).
  static bool all_ghosts(const std::uint32_t* idx, std::uint32_t n, std::uint32_t ghost_begin) {
    std::uint32_t lowest = ~std::uint32_t{0};
    for (std::uint32_t k = 0; k < n; ++k) lowest = idx[k] < lowest ? idx[k] : lowest;
    return lowest >= ghost_begin;
  }
  struct SeamCell {
    std::uint32_t begin, end;
    double shift;
  };
  /// Prepares the threads' scratch, splits the keys between the threads,
  /// calls home(thread, scratch, key, coords) for every key of a real cell in
  /// each thread's range (phased: in the phases of ThreadPhases), then sums
  /// the private accumulators (private only).
  template <class Home>
  void sweep(const CellGrid& grid, const CellOrder& order, const Gridder& gridder, ParticleSet& ps, unsigned mask,
             int threads, bool gather, ThreadUpdates updates, Home&& home) {
    const unsigned outputs = mask & (fields::force_out | fields::kgc_m_out);
    const bool phased = updates == ThreadUpdates::phased && threads > 1 && outputs != 0;
    prepare(gridder, ps, mask, threads, gather, /*private_outputs=*/!phased);
    split_keys(grid, order, gridder, ps, threads);
    const std::uint64_t* coords = order.key_coords().data();
    reduce_seconds_ = 0;
    if (phased) {
      if (split_ == ThreadSplit::dynamic)
        throw std::logic_error("CellSweep: thread_split=dynamic with thread_updates=phased (phases need fixed key ranges)");
      phases_.plan(grid, order, thread_begin_, weight_, threads);
      const double region_start = omp_get_wtime();
#pragma omp parallel num_threads(threads)
      {
        const int t = omp_get_thread_num();
        Scratch& s = scratch_[t];
        s.busy_seconds = 0;
        for (int p = 0; p < ThreadPhases::kParallelPhases; ++p) {
          const double start = omp_get_wtime();
          for (const std::uint32_t key : phases_.keys(p, t)) home(t, s, key, CellOrder::unpack_coords(coords[key]));
          s.busy_seconds += omp_get_wtime() - start;
#pragma omp barrier
        }
        if (t == 0) {
          const double start = omp_get_wtime();
          for (const std::uint32_t key : phases_.serial()) home(t, s, key, CellOrder::unpack_coords(coords[key]));
          s.busy_seconds += omp_get_wtime() - start;
        }
      }
      finish_timing(region_start, threads);
      return;
    }
    const double region_start = omp_get_wtime();
    const bool dynamic = split_ == ThreadSplit::dynamic;
    const std::int64_t num_keys = static_cast<std::int64_t>(order.num_keys());
#pragma omp parallel num_threads(threads)
    {
      const int t = omp_get_thread_num();
      Scratch& s = scratch_[t];
      auto visit = [&](std::uint32_t key) {
        const std::uint64_t c = coords[key];
        if (c != CellOrder::kNoCellCoords) home(t, s, key, CellOrder::unpack_coords(c));
      };
      const double start = omp_get_wtime();
      if (dynamic) {
        // Chunks of consecutive keys keep a thread's cells near each other in
        // memory; a chunk costs one atomic fetch.
#pragma omp for schedule(dynamic, kDynamicChunk) nowait
        for (std::int64_t key = 0; key < num_keys; ++key) visit(static_cast<std::uint32_t>(key));
      } else {
        for (std::uint32_t key = thread_begin_[t]; key < thread_begin_[t + 1]; ++key) visit(key);
      }
      s.busy_seconds = omp_get_wtime() - start;
    }
    finish_timing(region_start, threads);
    if (outputs && threads > 1) {
      const double start = omp_get_wtime();
      reduce(ps, outputs, threads);
      reduce_seconds_ = omp_get_wtime() - start;
    }
  }

  /// gather = false (run_direct): no CellBuffer is allocated. private_outputs:
  /// threads > 0 write their outputs into private accumulators.
  void prepare(const Gridder& gridder, ParticleSet& ps, unsigned mask, int threads, bool gather,
               bool private_outputs);
  /// Fills thread_begin_: thread t sweeps keys [thread_begin_[t], thread_begin_[t+1]).
  void split_keys(const CellGrid& grid, const CellOrder& order, const Gridder& gridder, const ParticleSet& ps,
                  int threads);
  /// Keys per chunk of ThreadSplit::dynamic: a run of consecutive keys (empty
  /// cells included), neighbouring cells in memory, for one atomic fetch.
  static constexpr int kDynamicChunk = 64;
  void finish_timing(double region_start, int threads) {
    region_seconds_ = omp_get_wtime() - region_start;
    busy_seconds_ = 0;
    for (int t = 0; t < threads; ++t) busy_seconds_ += scratch_[static_cast<std::size_t>(t)].busy_seconds;
  }
  double busy_seconds_ = 0, region_seconds_ = 0, reduce_seconds_ = 0;
  ThreadSplit split_ = ThreadSplit::fluid;
  std::vector<std::uint32_t> thread_begin_;
  std::vector<double> weight_;
  std::vector<double> fluid_, boundary_;  // ThreadSplit::interactions: particles per key
  void reduce(ParticleSet& ps, unsigned outputs, int threads);
  std::vector<Scratch> scratch_;
  ThreadPhases phases_;
};

}  // namespace sphnl
