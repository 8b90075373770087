#pragma once
// The two steps every neighbour structure starts with, shared by the
// simulation's ParticleGrid (cell-linked list, Verlet lists) and the point-cloud
// NeighbourSearch:
//
//   fit_grid    the cells division (§2.5 (a)): a CellGrid over a box with cells
//               at least a given side, optionally widened by the round-off of
//               the cell coordinate and enlarged for sparse clouds; the cell
//               order's tables follow the grid (§2.4).
//   CellSort    particles in cells and reordering (§2.3, §2.4): the cell key
//               of every point, the gridder built on them, and, when
//               reordering, the permutation into cell order (gridded points
//               by key, out points last) with the keys in that order.
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "sphnl/grid.hpp"
#include "sphnl/gridders/gridder.hpp"
#include "sphnl/orderings/cell_order.hpp"

namespace sphnl {

/// What a grid must satisfy.
struct GridRequest {
  Box box;               ///< every gridded point lies inside
  double min_side = 0;   ///< cells at least this wide (> 0)
  double period_y = 0;   ///< > 0: y is periodic (CellGrid::period_y)
  /// When set, the side grows by a relative 1e-9 and by the round-off of
  /// (x - lo) / side at `max_abs` (the largest |coordinate|), so a pair closer
  /// than min_side is never put two cells apart: a cloud of arbitrary
  /// coordinates needs this; the simulation's domain, starting at 0 with
  /// cells of 2h, does not use it.
  bool roundoff_margin = false;
  double max_abs = 0;
  /// > 0: cells are enlarged (x 1.25 at a time) until the grid has at most
  /// this many (a sparse cloud would need far more cells than points).
  double max_cells = 0;
};

/// Sizes `grid` for `request` and sets `order` up for it; both are left
/// untouched when the grid would be the same (so tables are built once for a
/// fixed domain). Returns true when the grid changed. Throws
/// std::invalid_argument when a periodic y holds fewer than
/// CellGrid::kMinPeriodicCells cells.
bool fit_grid(const GridRequest& request, CellGrid& grid, CellOrder& order);

/// Cell keys, gridder and the reordering permutation of one build; the
/// buffers are kept between builds.
class CellSort {
 public:
  /// Keys of the points (x[i], y[i], z[i]) in `grid` (kNoCell where `type` is
  /// given and type[i] is out; computed by `threads` threads), then `gridder`
  /// built on them.
  void place(const CellGrid& grid, const CellOrder& order, Gridder& gridder, std::span<const double> x,
             std::span<const double> y, std::span<const double> z, const ParticleType* type, int threads = 1);
  /// Reordering (§2.4): permutation() becomes new index -> old index (gridded
  /// points in cell-key order, each cell's in increasing index, then the out
  /// points). keys() stay in input order until permute_keys(). With `owned`
  /// below the number of points (a distributed run), points from `owned` on
  /// are ghosts: they come last, after the out points, in cell order.
  void sort(const Gridder& gridder, std::size_t owned = ~std::size_t{0});
  /// After sort(), for InnerOrder::morton: each cell's points in
  /// permutation() re-sorted by the Z-order of their sub-cell in a
  /// kInnerDivisions^3 division of the cell (ties by index), so that
  /// consecutive points of a cell are spatial clusters. Cells stay where
  /// sort() put them; owned points and ghosts are never mixed.
  void order_within_cells(const CellGrid& grid, std::span<const double> x, std::span<const double> y,
                          std::span<const double> z);
  static constexpr int kInnerDivisions = 4;
  /// After place(): start[k] = the points of keys below k (the first point of
  /// key k in cell order), for every key and one past the last (num_keys + 1
  /// entries; out points are not counted). Copied from the gridder's
  /// CellsBegin where it keeps one (A, B), counted from the keys otherwise.
  void cell_starts(const Gridder& gridder, std::uint32_t num_keys, std::vector<std::uint32_t>& start) const;
  /// After sort(): keys() put into cell order (for a caller that permuted its
  /// own arrays and keeps the keys beside them).
  void permute_keys();
  /// After permute_keys(): the inverse permutation (old index -> new index),
  /// written into the scratch the key permutation freed; valid until the
  /// next place().
  std::span<const std::uint32_t> inverse_permutation();

  std::span<const std::uint32_t> keys() const { return keys_; }
  std::span<const std::uint32_t> permutation() const { return permutation_; }
  std::size_t bytes() const {
    return (keys_.capacity() + permutation_.capacity() + scratch_.capacity() + ghosts_.capacity()) *
               sizeof(std::uint32_t) +
           inner_keys_.capacity() * sizeof(std::uint64_t);
  }

 private:
  std::vector<std::uint32_t> keys_, permutation_, scratch_, ghosts_;
  std::size_t owned_ = ~std::size_t{0};  // the `owned` of the last sort()
  std::vector<std::uint64_t> inner_keys_;  // order_within_cells: sub-cell code << 32 | index, one cell at a time
};

}  // namespace sphnl
