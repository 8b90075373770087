#pragma once
// CellSweep: visits every home cell in key order (the sweep of §3.2) with its
// 13 forward neighbour cells (a half stencil: every pair of cells once), gathers
// their particles into a CellBuffer and hands it to a visitor. The cell-linked
// list evaluates pairs from it; Verlet lists build their lists from it.
// Threads take contiguous ranges of home cells; each accumulates into private
// arrays that are summed afterwards in a fixed order (deterministic results).
#include <omp.h>

#include <array>
#include <cstdint>
#include <vector>

#include "sphnl/grid.hpp"
#include "sphnl/gridders/gridder.hpp"
#include "sphnl/neighbours/cell_buffer.hpp"
#include "sphnl/neighbours/pair_filter.hpp"
#include "sphnl/orderings/cell_order.hpp"
#include "sphnl/particles.hpp"

namespace sphnl {

/// The 13 cell offsets lexicographically after (0,0,0) in (dz, dy, dx).
inline constexpr std::array<std::array<int, 3>, 13> kHalfStencil = {{
    {1, 0, 0},  {-1, 1, 0}, {0, 1, 0},  {1, 1, 0},  {-1, -1, 1}, {0, -1, 1}, {1, -1, 1},
    {-1, 0, 1}, {0, 0, 1},  {1, 0, 1},  {-1, 1, 1}, {0, 1, 1},   {1, 1, 1},
}};

class CellSweep {
 public:
  /// Thread-private state: a gather buffer, the candidate indices of a home
  /// cell, survivors of the distance filter, and private accumulators.
  struct Scratch {
    CellBuffer buffer;
    std::vector<std::uint32_t> cell_index;
    std::vector<std::uint32_t> survivors;
    std::vector<double> acc[13];  // ax ay az drho ux uy uz m0..m5 for threads > 0
    ParticleView target;
  };

  /// Runs `visit(thread, buffer, n_home)` for every non-empty home cell; the
  /// first n_home buffer entries are the home cell's particles.
  template <class Visit>
  void run(const CellGrid& grid, const CellOrder& order, const Gridder& gridder, ParticleSet& ps, unsigned mask,
           int threads, Visit&& visit) {
    prepare(gridder, ps, mask, threads);
    const std::uint32_t num_keys = order.num_keys();
    const std::uint64_t* coords = order.key_coords().data();
    const unsigned outputs = mask & (fields::force_out | fields::kgc_m_out);
#pragma omp parallel num_threads(threads)
    {
      const int t = omp_get_thread_num();
      Scratch& s = scratch_[t];
      std::uint32_t* idx = s.cell_index.data();
#pragma omp for schedule(static)
      for (std::uint32_t key = 0; key < num_keys; ++key) {
        const std::uint64_t c = coords[key];
        if (c == CellOrder::kNoCellCoords) continue;
        const std::uint32_t n_home = gridder.gather_cell(key, idx);
        if (n_home == 0) continue;
        const int cx = static_cast<int>(c & 0x1FFFFF), cy = static_cast<int>((c >> 21) & 0x1FFFFF),
                  cz = static_cast<int>(c >> 42);
        std::uint32_t total = n_home;
        for (const auto& o : kHalfStencil) {
          const int nx = cx + o[0], ny = cy + o[1], nz = cz + o[2];
          if (nx < 0 || ny < 0 || nx >= grid.n[0] || ny >= grid.n[1] || nz >= grid.n[2]) continue;
          total += gridder.gather_cell(order.key(nx, ny, nz), idx + total);
        }
        s.buffer.gather(ps, idx, total, mask);
        visit(t, s, n_home);
        if (outputs) s.buffer.scatter_add(s.target, outputs);
      }
    }
    if (outputs) reduce(ps, outputs, threads);
  }

  std::size_t bytes() const;

 private:
  void prepare(const Gridder& gridder, ParticleSet& ps, unsigned mask, int threads);
  void reduce(ParticleSet& ps, unsigned outputs, int threads);
  std::vector<Scratch> scratch_;
};

}  // namespace sphnl
