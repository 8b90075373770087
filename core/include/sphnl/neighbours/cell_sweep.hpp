#pragma once
// CellSweep: visits every home cell in key order (the sweep of §3.2) with its
// 13 forward neighbour cells (a half stencil: every pair of cells once), gathers
// their particles into a CellBuffer and hands it to a visitor. The cell-linked
// list evaluates pairs from it; Verlet lists build their lists from it.
// Threads take contiguous ranges of home cells holding equal shares of the
// fluid (split_keys: a static split of the key range would hand one thread the
// water and the other the empty upper half of the tank); each accumulates into
// private arrays that are summed afterwards in a fixed order, so results are
// deterministic for a fixed thread count. With `thread_updates=phased`
// (ThreadPhases) there are no private arrays: the home cells run in phases in
// which no two threads write one particle.
// With a periodic y (CellGrid::period_y) the stencil wraps across the seam and
// the gathered copies of the cells beyond it are shifted by the period, so the
// distance filter and the pair kernel see the nearest image and stay unchanged.
#include <omp.h>

#include <array>
#include <cstdint>
#include <span>
#include <stdexcept>
#include <vector>

#include "sphnl/grid.hpp"
#include "sphnl/gridders/gridder.hpp"
#include "sphnl/neighbours/cell_buffer.hpp"
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
    ThreadAccumulators private_acc;  // threads > 0
    ParticleView target;
  };

  /// Runs `visit(thread, buffer, n_home)` for every non-empty home cell; the
  /// first n_home buffer entries are the home cell's particles.
  /// `updates`: how threads > 1 keep from writing one particle at once.
  template <class Visit>
  void run(const CellGrid& grid, const CellOrder& order, const Gridder& gridder, ParticleSet& ps, unsigned mask,
           int threads, Visit&& visit, ThreadUpdates updates = ThreadUpdates::private_accumulators) {
    const unsigned outputs = mask & (fields::force_out | fields::kgc_m_out);
    sweep(grid, order, gridder, ps, mask, threads, /*gather=*/true, updates,
          [&](int t, Scratch& s, std::uint32_t key, CellOrder::Coords home) {
            std::uint32_t* idx = s.cell_index.data();
            const std::uint32_t n_home = gridder.gather_cell(key, idx);
            if (n_home == 0) return;
            std::uint32_t total = n_home;
            int n_seam = 0;  // neighbour cells across a periodic seam: gathered range and y shift
            std::array<SeamCell, kHalfStencil.size()> seam;
            for_each_stencil_cell(grid, order, home, kHalfStencil, [&](std::uint32_t k, double shift) {
              const std::uint32_t begin = total;
              total += gridder.gather_cell(k, idx + total);
              if (shift != 0 && total > begin) seam[n_seam++] = {begin, total, shift};
            });
            s.buffer.gather(ps, idx, total, mask);
            for (int k = 0; k < n_seam; ++k) s.buffer.shift_y(seam[k].begin, seam[k].end, seam[k].shift);
            visit(t, s, n_home);
            if (outputs) s.buffer.scatter_add(s.target, outputs);
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
  template <class Visit>
  void run_direct(const CellGrid& grid, const CellOrder& order, const Gridder& gridder, ParticleSet& ps,
                  unsigned mask, int threads, Visit&& visit,
                  ThreadUpdates updates = ThreadUpdates::private_accumulators) {
    if (grid.period_y > 0) throw std::logic_error("CellSweep::run_direct: a periodic grid needs the gather sweep");
    sweep(grid, order, gridder, ps, mask, threads, /*gather=*/false, updates,
          [&](int t, Scratch& s, std::uint32_t key, CellOrder::Coords home_coords) {
            std::uint32_t* idx = s.cell_index.data();  // gridder D writes its walks here
            const std::span<const std::uint32_t> home = gridder.cell_members(key, idx);
            if (home.empty()) return;
            std::uint32_t used = home.data() == idx ? static_cast<std::uint32_t>(home.size()) : 0;
            ForwardCells forward;
            for_each_stencil_cell(grid, order, home_coords, kHalfStencil, [&](std::uint32_t k, double) {
              const std::span<const std::uint32_t> cell = gridder.cell_members(k, idx + used);
              if (cell.empty()) return;
              if (cell.data() == idx + used) used += static_cast<std::uint32_t>(cell.size());
              forward.cells[forward.count++] = cell;
            });
            visit(t, s, home, forward);
          });
  }

  std::size_t bytes() const;

 private:
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
    split_keys(order, gridder, ps, threads);
    const std::uint64_t* coords = order.key_coords().data();
    if (phased) {
      phases_.plan(grid, order, thread_begin_, weight_, threads);
#pragma omp parallel num_threads(threads)
      {
        const int t = omp_get_thread_num();
        Scratch& s = scratch_[t];
        for (int p = 0; p < ThreadPhases::kParallelPhases; ++p) {
          for (const std::uint32_t key : phases_.keys(p, t)) home(t, s, key, CellOrder::unpack_coords(coords[key]));
#pragma omp barrier
        }
        if (t == 0)
          for (const std::uint32_t key : phases_.serial()) home(t, s, key, CellOrder::unpack_coords(coords[key]));
      }
      return;
    }
#pragma omp parallel num_threads(threads)
    {
      const int t = omp_get_thread_num();
      Scratch& s = scratch_[t];
      for (std::uint32_t key = thread_begin_[t]; key < thread_begin_[t + 1]; ++key) {
        const std::uint64_t c = coords[key];
        if (c != CellOrder::kNoCellCoords) home(t, s, key, CellOrder::unpack_coords(c));
      }
    }
    if (outputs) reduce(ps, outputs, threads);
  }
  /// gather = false (run_direct): no CellBuffer is allocated. private_outputs:
  /// threads > 0 write their outputs into private accumulators.
  void prepare(const Gridder& gridder, ParticleSet& ps, unsigned mask, int threads, bool gather,
               bool private_outputs);
  /// Fills thread_begin_: thread t sweeps keys [thread_begin_[t], thread_begin_[t+1]).
  void split_keys(const CellOrder& order, const Gridder& gridder, const ParticleSet& ps, int threads);
  std::vector<std::uint32_t> thread_begin_;
  std::vector<double> weight_;
  void reduce(ParticleSet& ps, unsigned outputs, int threads);
  std::vector<Scratch> scratch_;
  ThreadPhases phases_;
};

}  // namespace sphnl
