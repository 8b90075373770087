#pragma once
// ParticleGrid: the "neighbour list" phase shared by every pair source (paper
// Table I): cells division (CellGrid), cell index of every particle (CellOrder),
// particles in cells (Gridder), and optionally reordering the particle arrays
// into cell order (§2.4).
#include <cstdint>
#include <memory>
#include <vector>

#include "sphnl/grid.hpp"
#include "sphnl/gridders/gridder.hpp"
#include "sphnl/kinds.hpp"
#include "sphnl/neighbours/cell_sort.hpp"
#include "sphnl/orderings/cell_order.hpp"
#include "sphnl/particles.hpp"

namespace sphnl {

class ParticleGrid {
 public:
  /// period_y > 0: y is periodic (CellGrid::period_y); the cell sweep then
  /// wraps its stencil across the seam.
  ParticleGrid(const Box& domain, CellOrderKind order, GridderKind gridder, const GridderOptions& options,
               double period_y = 0);

  /// Grids `ps` with cells of side `cell_size`; when `reorder` is set, first
  /// permutes every particle array into cell order (out particles last) and
  /// grids again. Returns true when particles were permuted.
  /// A distributed run (parallel/domain_exchange.hpp) passes `owned`: particles
  /// [owned, size) are ghosts, and reordering keeps them after the owned ones
  /// (owned in cell order, owned out ones, then ghosts in cell order), so that
  /// the integrator's particles stay [0, owned).
  bool build(ParticleSet& ps, double cell_size, bool reorder, std::size_t owned = kAllOwned);
  /// Threads of the next builds: the cell keys of the particles and the
  /// permutation of their arrays are split over them (the same keys, order
  /// and bits for any count), and so is gridder B's counting sort (the same
  /// cells); the other gridders build on one thread.
  void set_threads(int threads) {
    threads_ = threads < 1 ? 1 : threads;
    gridder_->set_threads(threads_);
  }
  /// The order of each cell's particles in the next reorderings (kinds.hpp).
  void set_inner_order(InnerOrder order) { inner_order_ = order; }
  static constexpr std::size_t kAllOwned = ~std::size_t{0};
  /// First ghost index of the last build ([ghost_begin, size) are ghosts, in
  /// cells of other ranks), or CellSweep::kNoGhosts for a serial run: the
  /// cell sweep leaves out the pairs of two ghosts, which no rank integrates.
  std::uint32_t ghost_begin() const { return ghost_begin_; }
  /// New index -> old index of the last build that reordered.
  std::span<const std::uint32_t> permutation() const { return sort_.permutation(); }

  const CellGrid& grid() const { return grid_; }
  const CellOrder& order() const { return *order_; }
  const Gridder& gridder() const { return *gridder_; }
  std::span<const std::uint32_t> cell_keys() const { return sort_.keys(); }
  /// Bytes of the gridding structures: gridder, ordering tables, the key of
  /// every particle, and the reordering buffers once reordering has been used.
  std::size_t bytes() const;

 private:
  Box domain_;
  double period_y_ = 0;
  int threads_ = 1;
  InnerOrder inner_order_ = InnerOrder::index;
  std::uint32_t ghost_begin_ = ~std::uint32_t{0};
  CellGrid grid_;
  std::unique_ptr<CellOrder> order_;
  std::unique_ptr<Gridder> gridder_;
  CellSort sort_;
  // reordering buffers of the particle arrays (allocated on first use, reused afterwards)
  std::vector<std::uint32_t> u32_scratch_;
  std::vector<double> f64_scratch_;
};

}  // namespace sphnl
