#pragma once
// Domain decomposition along the space-filling curve of the cell order
// (docs/DESIGN.md, "The parallel layer"): rank r owns the cells whose keys lie
// in one contiguous range [begin(r), end(r)), the ranges chosen so that each
// holds about the same work. The curve keeps a range compact in space (Hilbert
// best, paper §2.4), so few of its cells border another rank's. Pure serial
// code: the same on every rank, tested without MPI.
#include <cstdint>
#include <span>
#include <vector>

#include "sphnl/grid.hpp"
#include "sphnl/neighbours/cell_work.hpp"
#include "sphnl/orderings/cell_order.hpp"

namespace sphnl {

/// P contiguous key ranges covering [0, num_keys).
class KeyPartition {
 public:
  KeyPartition() = default;
  /// Ranges of about equal total weight (weights[key] >= 0), cut where the
  /// running sum crosses total r / P. Throws std::invalid_argument when there
  /// are more ranks than keys.
  static KeyPartition balanced(std::span<const double> weights, int ranks);
  /// Explicit ranges: begins[r] is the first key of rank r, begins.back() the key count.
  explicit KeyPartition(std::vector<std::uint32_t> begins) : begin_(std::move(begins)) {}

  int ranks() const { return static_cast<int>(begin_.size()) - 1; }
  std::uint32_t begin(int r) const { return begin_[r]; }
  std::uint32_t end(int r) const { return begin_[r + 1]; }
  std::uint32_t num_keys() const { return begin_.empty() ? 0 : begin_.back(); }
  /// The rank owning `key` (< num_keys()).
  int owner(std::uint32_t key) const;
  /// Total weight of each rank's range.
  std::vector<double> rank_weights(std::span<const double> weights) const;
  bool empty() const { return begin_.size() < 2; }

 private:
  std::vector<std::uint32_t> begin_;
};

/// Largest rank weight over the mean, minus one (0: perfectly balanced; 0 when
/// there is no weight at all).
double imbalance(std::span<const double> rank_weights);

/// Which cells each rank needs from the others: with cells of side >= the
/// interaction radius (2h for the cell-linked list, 2H for Verlet lists), every
/// partner of a particle lies in its cell or one of the 26 around it, so the
/// halo of a rank is one layer of cells (wrapped across a periodic y seam as the
/// stencil walk wraps).
class Decomposition {
 public:
  Decomposition(const CellGrid& grid, const CellOrder& order, const KeyPartition& partition)
      : grid_(&grid), order_(&order), partition_(&partition) {}
  /// Ranks other than the owner of `key` owning a cell next to it: they get
  /// this cell's particles as ghosts. Sorted, without repeats; appended to `out` after clearing it.
  void ghost_destinations(std::uint32_t key, std::vector<int>& out) const;
  /// Keys of the cells rank `rank` receives as ghosts (next to one of its cells,
  /// owned by another rank), sorted.
  std::vector<std::uint32_t> halo_cells(int rank) const;
  /// The ranks owning a cell next to one of `rank`'s cells, occupied or not
  /// (the owners of its halo cells), sorted: its neighbour-exchange partners.
  /// Symmetric (q is r's partner exactly when r is q's), and a superset of
  /// every destination ghost_destinations gives `rank`'s cells.
  std::vector<int> partners(int rank) const;

 private:
  const CellGrid* grid_;
  const CellOrder* order_;
  const KeyPartition* partition_;
};

}  // namespace sphnl
