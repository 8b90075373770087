// Run-time factories for cell orders and gridders, the per-grid preparation of
// each cell order (paper §2.4) and the parts of the gridders (§2.3) that are
// not inline.
#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>
#include <string>

#include "sphnl/gridders/gridder.hpp"
#include "sphnl/gridders/linked_list.hpp"
#include "sphnl/gridders/preconditioned_vector.hpp"
#include "sphnl/gridders/sliding_vector.hpp"
#include "sphnl/gridders/static_matrix.hpp"
#include "sphnl/orderings/cell_order.hpp"
#include "sphnl/orderings/hilbert.hpp"
#include "sphnl/orderings/morton.hpp"
#include "sphnl/orderings/sort_x.hpp"

namespace sphnl {

// ---------------------------------------------------------------- cell orders

void CellOrder::setup(const CellGrid& grid) {
  num_keys_ = prepare(grid);
  // Padding keys (Z-order) keep kNoCellCoords: the sweep skips them.
  key_coords_.assign(num_keys_, kNoCellCoords);
  for (int cz = 0; cz < grid.n[2]; ++cz)
    for (int cy = 0; cy < grid.n[1]; ++cy)
      for (int cx = 0; cx < grid.n[0]; ++cx)
        key_coords_[key(cx, cy, cz)] = pack_coords(cx, cy, cz);
}

std::unique_ptr<CellOrder> make_cell_order(CellOrderKind kind) {
  switch (kind) {
    case CellOrderKind::sort_x: return std::make_unique<SortX>();
    case CellOrderKind::sort_xy: return std::make_unique<SortXY>();
    case CellOrderKind::sort_xyz: return std::make_unique<SortXYZ>();
    case CellOrderKind::hilbert: return std::make_unique<Hilbert>();
  }
  throw ConfigError("cell_order: unknown value; allowed: sort_x, sort_xy, sort_xyz, hilbert");
}

namespace morton {

int make_layouts(const int* bits, int dims, AxisLayout* out) {
  int total = 0;
  for (int d = 0; d < dims; ++d) total += bits[d];
  if (total > 31)
    throw std::runtime_error("Z-order cell keys need " + std::to_string(total) +
                             " bits (cells padded to powers of two per axis), more than the 31 of a 32-bit key; "
                             "use a larger cell size or the cell order sort_x or hilbert");
  int order[3] = {0, 1, 2};
  std::stable_sort(order, order + dims, [&](int a, int b) { return bits[a] < bits[b]; });
  auto mask = [](int nbits) { return nbits > 0 ? (1u << nbits) - 1u : 0u; };
  for (int d = 0; d < dims; ++d) out[d] = AxisLayout{};
  if (dims == 3) {
    const int b0 = bits[order[0]], b1 = bits[order[1]], b2 = bits[order[2]];
    for (int d = 0; d < 3; ++d) {  // bits every axis has: 3-way interleave, x lowest
      out[d].mask3 = mask(b0);
      out[d].shift3 = d;
    }
    const int lo_axis = std::min(order[1], order[2]);
    for (int d : {order[1], order[2]}) {  // bits only the two longer axes have: 2-way
      out[d].mask2 = mask(b1 - b0);
      out[d].low = b0;
      out[d].shift2 = out[d].mask2 ? 3 * b0 + (d == lo_axis ? 0 : 1) : 0;
    }
    AxisLayout& longest = out[order[2]];  // the rest of the longest axis
    longest.mask1 = mask(b2 - b1);
    longest.mid = b1;
    longest.shift1 = longest.mask1 ? 3 * b0 + 2 * (b1 - b0) : 0;
  } else {
    const int b0 = bits[order[0]], b1 = bits[order[1]];
    for (int d = 0; d < 2; ++d) {  // bits both axes have: 2-way interleave, x lowest
      out[d].mask2 = mask(b0);
      out[d].shift2 = d;
    }
    AxisLayout& longest = out[order[1]];
    longest.mask1 = mask(b1 - b0);
    longest.mid = b0;
    longest.shift1 = longest.mask1 ? 2 * b0 : 0;
  }
  return total;
}

}  // namespace morton

std::uint32_t SortXY::prepare(const CellGrid& grid) {
  const int bits[2] = {morton::bits_for(grid.n[0]), morton::bits_for(grid.n[1])};
  const int plane_bits = morton::make_layouts(bits, 2, layout_);
  const double keys = std::ldexp(1.0, plane_bits) * grid.n[2];
  if (keys >= 4294967295.0)
    throw std::runtime_error("sort_xy: " + std::to_string(keys) +
                             " padded cells do not fit 32-bit keys; use a larger cell size or sort_x");
  plane_ = 1u << plane_bits;
  padded_[0] = 1 << bits[0];
  padded_[1] = 1 << bits[1];
  padded_[2] = grid.n[2];
  return plane_ * static_cast<std::uint32_t>(grid.n[2]);
}

std::uint32_t SortXYZ::prepare(const CellGrid& grid) {
  const int bits[3] = {morton::bits_for(grid.n[0]), morton::bits_for(grid.n[1]), morton::bits_for(grid.n[2])};
  const int total = morton::make_layouts(bits, 3, layout_);
  for (int d = 0; d < 3; ++d) padded_[d] = 1 << bits[d];
  return 1u << total;
}

namespace hilbert {

std::uint64_t index(std::uint32_t x, std::uint32_t y, std::uint32_t z, int bits) {
  // Skilling's AxestoTranspose: undo the excess work of the inverse, then Gray-encode.
  std::uint32_t X[3] = {x, y, z};
  const std::uint32_t M = 1u << (bits - 1);
  for (std::uint32_t Q = M; Q > 1; Q >>= 1) {
    const std::uint32_t P = Q - 1;
    for (int i = 0; i < 3; ++i) {
      if (X[i] & Q) {
        X[0] ^= P;
      } else {
        const std::uint32_t t = (X[0] ^ X[i]) & P;
        X[0] ^= t;
        X[i] ^= t;
      }
    }
  }
  for (int i = 1; i < 3; ++i) X[i] ^= X[i - 1];
  std::uint32_t t = 0;
  for (std::uint32_t Q = M; Q > 1; Q >>= 1)
    if (X[2] & Q) t ^= Q - 1;
  for (int i = 0; i < 3; ++i) X[i] ^= t;
  // The transposed index: bit q of X[i] is bit 3q + (2 - i) of the index.
  std::uint64_t h = 0;
  for (int q = bits - 1; q >= 0; --q)
    for (int i = 0; i < 3; ++i) h = (h << 1) | ((X[i] >> q) & 1u);
  return h;
}

}  // namespace hilbert

std::uint32_t Hilbert::prepare(const CellGrid& grid) {
  const int bits = std::max({1, morton::bits_for(grid.n[0]), morton::bits_for(grid.n[1]), morton::bits_for(grid.n[2])});
  ncx_ = static_cast<std::size_t>(grid.n[0]);
  ncxy_ = ncx_ * static_cast<std::size_t>(grid.n[1]);
  const std::size_t cells = static_cast<std::size_t>(grid.num_cells());
  // Sort the real cells by their index on the padded cube; rank = key.
  std::vector<std::pair<std::uint64_t, std::uint32_t>> curve(cells);
  for (int cz = 0; cz < grid.n[2]; ++cz)
    for (int cy = 0; cy < grid.n[1]; ++cy)
      for (int cx = 0; cx < grid.n[0]; ++cx) {
        const std::size_t c = static_cast<std::size_t>(cz) * ncxy_ + static_cast<std::size_t>(cy) * ncx_ + static_cast<std::size_t>(cx);
        curve[c] = {hilbert::index(static_cast<std::uint32_t>(cx), static_cast<std::uint32_t>(cy),
                                   static_cast<std::uint32_t>(cz), bits),
                    static_cast<std::uint32_t>(c)};
      }
  std::sort(curve.begin(), curve.end());
  rank_.resize(cells);
  for (std::size_t r = 0; r < cells; ++r) rank_[curve[r].second] = static_cast<std::uint32_t>(r);
  return static_cast<std::uint32_t>(cells);
}

// ------------------------------------------------------------------- gridders

void Gridder::cell_order_permutation(std::vector<std::uint32_t>& order) const {
  // Gathers straight into `order` (no temporary): its capacity, kept between
  // builds, is the only memory this needs.
  order.resize(0);
  for (std::uint32_t k = 0; k < num_keys_; ++k) {
    const std::size_t at = order.size();
    order.resize(at + max_cell_count_);
    order.resize(at + gather_cell(k, order.data() + at));
  }
}

int default_max_parts_in_cell(const GridderOptions& o) {
  if (!(o.dx > 0) || !(o.h > 0)) return 0;
  const double side = 2.2 * o.h;  // 2h plus a Verlet skin allowance
  const double planes = std::floor(side / o.dx + 1e-6) + 1;  // lattice planes a cell of that side can cut
  return static_cast<int>(std::ceil(1.3 * o.particles_per_dx3 * planes * planes * planes));
}

StaticMatrix::StaticMatrix(const GridderOptions& options) {
  if (options.max_parts_in_cell < 0)
    throw ConfigError("max_parts_in_cell must be >= 0 (0 = sized from h/dx), got " +
                      std::to_string(options.max_parts_in_cell));
  const int rows = options.max_parts_in_cell > 0 ? options.max_parts_in_cell : default_max_parts_in_cell(options);
  max_parts_ = static_cast<std::uint32_t>(rows);
}

void StaticMatrix::build(std::span<const std::uint32_t> cell_key, std::uint32_t num_keys) {
  num_keys_ = num_keys;
  const std::size_t n = cell_key.size();
  n_parts_in_cell_.assign(num_keys, 0);
  if (max_parts_ == 0) {
    // No lattice to size from (a bare point cloud): twice the fullest cell of the first build.
    for (std::size_t i = 0; i < n; ++i)
      if (cell_key[i] != kNoCell) ++n_parts_in_cell_[cell_key[i]];
    const std::uint32_t fullest = num_keys ? *std::max_element(n_parts_in_cell_.begin(), n_parts_in_cell_.end()) : 0;
    max_parts_ = std::max(1u, 2 * fullest);
    std::fill(n_parts_in_cell_.begin(), n_parts_in_cell_.end(), 0u);
  }
  parts_in_cell_.resize(std::size_t{num_keys} * max_parts_);
  const std::uint32_t row = max_parts_;
  std::uint32_t* parts = parts_in_cell_.data();
  std::uint32_t* count = n_parts_in_cell_.data();
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint32_t c = cell_key[i];
    if (c == kNoCell) continue;
    const std::uint32_t slot = count[c]++;
    if (slot < row) parts[std::size_t{c} * row + slot] = static_cast<std::uint32_t>(i);
  }
  std::uint32_t max_count = 0, fullest_key = 0;
  for (std::uint32_t k = 0; k < num_keys; ++k)
    if (count[k] > max_count) { max_count = count[k]; fullest_key = k; }
  max_cell_count_ = max_count;
  if (max_count > row)
    throw std::runtime_error("gridder C (static matrix): cell " + std::to_string(fullest_key) + " holds " +
                             std::to_string(max_count) + " particles, more than MaxPartsInCell = " +
                             std::to_string(row) + "; raise the config key max_parts_in_cell (e.g. --set "
                             "max_parts_in_cell=" + std::to_string(2 * max_count) + ") or use gridder B");
}

std::unique_ptr<Gridder> make_gridder(GridderKind kind, const GridderOptions& options) {
  switch (kind) {
    case GridderKind::A: return std::make_unique<SlidingVector>();
    case GridderKind::B: return std::make_unique<PreconditionedVector>();
    case GridderKind::C: return std::make_unique<StaticMatrix>(options);
    case GridderKind::D: return std::make_unique<LinkedList>();
  }
  throw ConfigError("gridder: unknown value; allowed: A, B, C, D");
}

}  // namespace sphnl
