#include "sphnl/neighbours/cell_sort.hpp"

#include <omp.h>

#include <cfloat>
#include <stdexcept>
#include <string>

namespace sphnl {

namespace {

/// The grid `request` would give is the one `grid` already is (a periodic
/// grid moves box.hi[1] to lo + period, so y's upper bound is not compared).
bool same_grid(const GridRequest& request, double side, const CellGrid& grid) {
  if (side != grid.cell_size || request.period_y != grid.period_y) return false;
  for (int d = 0; d < 3; ++d) {
    if (request.box.lo[d] != grid.box.lo[d]) return false;
    if (!(d == 1 && request.period_y > 0) && request.box.hi[d] != grid.box.hi[d]) return false;
  }
  return true;
}

}  // namespace

bool fit_grid(const GridRequest& request, CellGrid& grid, CellOrder& order) {
  double side = request.min_side;
  if (request.roundoff_margin) side = side * (1 + 1e-9) + 16 * DBL_EPSILON * request.max_abs;
  if (request.max_cells > 0)
    while (CellGrid::cells_needed(request.box, side) > request.max_cells) side *= 1.25;
  if (same_grid(request, side, grid)) return false;
  grid = CellGrid(request.box, side, request.period_y);
  if (request.period_y > 0 && grid.n[1] < CellGrid::kMinPeriodicCells)
    throw std::invalid_argument("a periodic y of " + std::to_string(request.period_y) + " m holds " +
                                std::to_string(grid.n[1]) + " cells of " + std::to_string(side) +
                                " m; it must hold at least 3: widen the slab to >= 3 cell sizes (6h)");
  order.setup(grid);
  return true;
}

void CellSort::place(const CellGrid& grid, const CellOrder& order, Gridder& gridder, std::span<const double> x,
                     std::span<const double> y, std::span<const double> z, const ParticleType* type, int threads) {
  const std::size_t n = x.size();
  keys_.resize(n);
  if (threads <= 1) {
    order.compute_keys(grid, x, y, z, type, keys_);
  } else {
#pragma omp parallel num_threads(threads)
    {
      const std::size_t t = static_cast<std::size_t>(omp_get_thread_num());
      const std::size_t team = static_cast<std::size_t>(omp_get_num_threads());
      const std::size_t b = n * t / team, count = n * (t + 1) / team - b;
      order.compute_keys(grid, x.subspan(b, count), y.subspan(b, count), z.subspan(b, count),
                         type ? type + b : nullptr, std::span<std::uint32_t>(keys_).subspan(b, count));
    }
  }
  gridder.build(keys_, order.num_keys());
}

void CellSort::sort(const Gridder& gridder, std::size_t owned) {
  gridder.cell_order_permutation(permutation_);
  ghosts_.clear();
  if (owned < keys_.size()) {
    // A distributed run: the owned particles first and the ghosts after them,
    // each in cell order (stable), so [0, owned) stays the rank's own.
    std::size_t kept = 0;
    for (const std::uint32_t i : permutation_) {
      if (i < owned)
        permutation_[kept++] = i;
      else
        ghosts_.push_back(i);
    }
    permutation_.resize(kept);
  }
  if (permutation_.size() + ghosts_.size() != keys_.size())
    for (std::size_t i = 0; i < keys_.size(); ++i)
      if (keys_[i] == kNoCell) permutation_.push_back(static_cast<std::uint32_t>(i));
  permutation_.insert(permutation_.end(), ghosts_.begin(), ghosts_.end());
}

void CellSort::cell_starts(const Gridder& gridder, std::uint32_t num_keys, std::vector<std::uint32_t>& start) const {
  const std::span<const std::uint32_t> begin = gridder.cells_begin();
  if (begin.size() == std::size_t{num_keys} + 1) {
    start.assign(begin.begin(), begin.end());
    return;
  }
  // Count per key, shifted by one, then a running sum.
  start.assign(std::size_t{num_keys} + 1, 0);
  for (const std::uint32_t key : keys_)
    if (key != kNoCell) ++start[std::size_t{key} + 1];
  for (std::uint32_t k = 0; k < num_keys; ++k) start[k + 1] += start[k];
}

void CellSort::permute_keys() {
  scratch_.resize(keys_.size());
  for (std::size_t k = 0; k < keys_.size(); ++k) scratch_[k] = keys_[permutation_[k]];
  keys_.swap(scratch_);
}

std::span<const std::uint32_t> CellSort::inverse_permutation() {
  scratch_.resize(permutation_.size());
  for (std::size_t k = 0; k < permutation_.size(); ++k) scratch_[permutation_[k]] = static_cast<std::uint32_t>(k);
  return scratch_;
}

}  // namespace sphnl
