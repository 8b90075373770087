#include "sphnl/neighbours/cell_sort.hpp"

#include <omp.h>

#include <algorithm>
#include <cfloat>
#include <cmath>
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
  owned_ = owned;
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

namespace {

/// The sub-cell of coordinate v along one axis: its position inside the
/// cell-sized tile it falls in, in CellSort::kInnerDivisions steps.
unsigned sub_cell(double v, double lo, double inv_side) {
  const double u = (v - lo) * inv_side;
  const int s = static_cast<int>((u - std::floor(u)) * CellSort::kInnerDivisions);
  return static_cast<unsigned>(std::clamp(s, 0, CellSort::kInnerDivisions - 1));
}

/// Z-order (Morton) code of the sub-cell (sx, sy, sz), each below 4: 6 bits.
unsigned sub_cell_code(unsigned sx, unsigned sy, unsigned sz) {
  unsigned code = 0;
  for (int bit = 0; bit < 2; ++bit)
    code |= (((sx >> bit) & 1u) << (3 * bit)) | (((sy >> bit) & 1u) << (3 * bit + 1)) |
            (((sz >> bit) & 1u) << (3 * bit + 2));
  return code;
}
static_assert(CellSort::kInnerDivisions == 4, "sub_cell_code interleaves 2 bits per axis");

}  // namespace

void CellSort::order_within_cells(const CellGrid& grid, std::span<const double> x, std::span<const double> y,
                                  std::span<const double> z) {
  const std::size_t n = permutation_.size();
  const auto key_of = [&](std::size_t k) { return keys_[permutation_[k]]; };
  const auto owned_of = [&](std::size_t k) { return permutation_[k] < owned_; };
  std::size_t begin = 0;
  while (begin < n) {
    // One cell's run: the same key and the same side of the owned/ghost cut.
    std::size_t end = begin + 1;
    while (end < n && key_of(end) == key_of(begin) && owned_of(end) == owned_of(begin)) ++end;
    if (end - begin > 1 && key_of(begin) != kNoCell) {
      inner_keys_.clear();
      for (std::size_t k = begin; k < end; ++k) {
        const std::uint32_t i = permutation_[k];
        const unsigned code = sub_cell_code(sub_cell(x[i], grid.box.lo[0], grid.inv_cell_size),
                                            sub_cell(y[i], grid.box.lo[1], grid.inv_cell_size),
                                            sub_cell(z[i], grid.box.lo[2], grid.inv_cell_size));
        inner_keys_.push_back((std::uint64_t{code} << 32) | i);
      }
      // Insertion sort: the points of a cell come in index order, which is
      // the last reordering's sub-cell order, so few have moved out of place
      // and this costs about one comparison a point.
      for (std::size_t a = 1; a < inner_keys_.size(); ++a) {
        const std::uint64_t key = inner_keys_[a];
        std::size_t b = a;
        for (; b > 0 && inner_keys_[b - 1] > key; --b) inner_keys_[b] = inner_keys_[b - 1];
        inner_keys_[b] = key;
      }
      for (std::size_t k = begin; k < end; ++k)
        permutation_[k] = static_cast<std::uint32_t>(inner_keys_[k - begin]);
    }
    begin = end;
  }
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
