#include "sphnl/neighbours/neighbour_search.hpp"

#include <algorithm>
#include <stdexcept>
#include <string>

#include "sphnl/neighbours/pair_filter.hpp"
#include "sphnl/neighbours/stencil.hpp"
#include "sphnl/permutation.hpp"
#include "sphnl/timer.hpp"

namespace sphnl {

namespace {

struct Range {
  std::uint32_t begin, end;
};

}  // namespace

// ------------------------------------------------------------- NeighbourLists

std::uint32_t* NeighbourLists::reserve(std::uint64_t used, std::uint64_t more, std::size_t rows_done) {
  const std::uint64_t need = used + more + kFilterSlack;
  const std::uint64_t capacity = entries_.capacity();
  if (need <= capacity) return entries_.data();
  // Grow to the larger of 1.5x and the size the rows done so far project for
  // all rows, so a search of N points reallocates a few times at most.
  const double projected =
      rows_done ? 1.15 * static_cast<double>(used) * static_cast<double>(point_.size()) / static_cast<double>(rows_done) : 0.0;
  const std::uint64_t cap = std::max({need, capacity + capacity / 2, static_cast<std::uint64_t>(projected)});
  return entries_.grow(cap, used);
}

void NeighbourLists::counts(std::vector<std::uint32_t>& out) const {
  out.assign(point_.size(), 0);
  for (std::size_t r = 0; r < point_.size(); ++r)
    out[point_[r]] = static_cast<std::uint32_t>(offsets_[r + 1] - offsets_[r]);
}

// ------------------------------------------------------------ NeighbourSearch

NeighbourSearch::NeighbourSearch(const SearchOptions& options)
    : options_(options), order_(make_cell_order(options.order)), gridder_([&] {
        GridderOptions g;
        g.max_parts_in_cell = options.max_parts_in_cell;  // no lattice: C sizes rows from the first build
        return make_gridder(options.gridder, g);
      }()) {}

NeighbourSearch::~NeighbourSearch() = default;

std::size_t NeighbourSearch::bytes() const {
  const std::size_t u32 = cell_start_.capacity() + gather_index_.capacity();
  const std::size_t f64 = xs_.capacity() + ys_.capacity() + zs_.capacity() + gx_.capacity() + gy_.capacity() + gz_.capacity();
  return gridder_->bytes() + order_->bytes() + sort_.bytes() + u32 * sizeof(std::uint32_t) + f64 * sizeof(double);
}

void NeighbourSearch::build(std::span<const double> x, std::span<const double> y, std::span<const double> z,
                            double radius) {
  const std::size_t n = x.size();
  if (y.size() != n || z.size() != n) throw std::invalid_argument("NeighbourSearch: x, y, z differ in length");
  if (n >= 0xFFFFFFFFu) throw std::invalid_argument("NeighbourSearch: more than 2^32 - 2 points");
  if (!(radius > 0) || !std::isfinite(radius))
    throw std::invalid_argument("NeighbourSearch: radius must be a positive finite number, got " + std::to_string(radius));
  Box box{{0, 0, 0}, {0, 0, 0}};
  double max_abs = 0;
  if (n > 0) {
    for (int d = 0; d < 3; ++d) box.lo[d] = box.hi[d] = (d == 0 ? x : d == 1 ? y : z)[0];
    for (std::size_t i = 0; i < n; ++i) {
      const double p[3] = {x[i], y[i], z[i]};
      for (int d = 0; d < 3; ++d) {
        if (!std::isfinite(p[d]))
          throw std::invalid_argument("NeighbourSearch: point " + std::to_string(i) + " has a non-finite coordinate");
        box.lo[d] = std::min(box.lo[d], p[d]);
        box.hi[d] = std::max(box.hi[d], p[d]);
      }
    }
    for (int d = 0; d < 3; ++d) max_abs = std::max({max_abs, std::fabs(box.lo[d]), std::fabs(box.hi[d])});
  }
  // Cells of side R, widened by the round-off of the cell coordinate so a
  // pair the distance test accepts is never two cells apart, and enlarged
  // (still correct, more candidates) when a sparse cloud would need far more
  // cells than points.
  GridRequest request;
  request.box = box;
  request.min_side = radius;
  request.roundoff_margin = true;
  request.max_abs = max_abs;
  request.max_cells = std::max(64.0, 2.0 * static_cast<double>(n));
  fit_grid(request, grid_, *order_);

  // Cell index of every point (§2.4), then particles in cells (§2.3).
  sort_.place(grid_, *order_, *gridder_, x, y, z, nullptr);
  if (options_.reorder) {
    // Reordering: coordinates permuted into cell order; then only the first
    // particle of each cell needs to be known (§2.4).
    sort_.sort(*gridder_);
    gather_by<double>(x, sort_.permutation(), xs_);
    gather_by<double>(y, sort_.permutation(), ys_);
    gather_by<double>(z, sort_.permutation(), zs_);
    sort_.cell_starts(order_->num_keys(), cell_start_);
  } else {
    const std::size_t room = 27 * std::size_t{gridder_->max_cell_count()} + kFilterSlack;
    if (gather_index_.size() < room) {
      gather_index_.resize(room);
      gx_.resize(room);
      gy_.resize(room);
      gz_.resize(room);
    }
  }
}

void NeighbourSearch::run(std::span<const double> x, std::span<const double> y, std::span<const double> z,
                          double radius, NeighbourLists& out) {
  Stopwatch sw;
  build(x, y, z, radius);
  times_.build = sw.lap();
  out.point_.resize(x.size());
  out.offsets_.resize(x.size() + 1);
  out.offsets_[0] = 0;
  if (options_.reorder)
    search_sorted(radius * radius, out);
  else
    search_gathered(x, y, z, radius * radius, out);
  times_.search = sw.lap();
}

void NeighbourSearch::search_sorted(double radius2, NeighbourLists& out) {
  const std::uint32_t num_keys = order_->num_keys();
  const std::uint64_t* coords = order_->key_coords().data();
  const std::uint32_t* start = cell_start_.data();
  const double* x = xs_.data();
  const double* y = ys_.data();
  const double* z = zs_.data();
  const std::uint32_t* id = sort_.permutation().data();
  std::uint32_t* point = out.point_.data();
  std::uint64_t* offsets = out.offsets_.data();
  std::uint64_t used = 0;
  {
    // Room for the expected entries up front (growing means copying and
    // touching fresh pages): if the 27 cells around a cell were as full as the
    // cell, its points would see 27 n_k candidates, of which the fraction
    // (4/3 pi R^3) / (3 side)^3 lies within R.
    const double side = grid_.cell_size, r3 = radius2 * std::sqrt(radius2);
    const double within = 4.18879020478639 * r3 / (27 * side * side * side);
    double expected = 0;
    for (std::uint32_t key = 0; key < num_keys; ++key) {
      const double nk = start[key + 1] - start[key];
      expected += 27 * within * nk * nk;
    }
    out.reserve(0, static_cast<std::uint64_t>(1.1 * expected), 0);
  }
  Range ranges[27];
  for (std::uint32_t key = 0; key < num_keys; ++key) {
    const std::uint32_t b = start[key], e = start[key + 1];
    if (b == e) continue;
    // The 27 cells as runs of consecutive sorted points; cells adjacent in key
    // order merge (the 3 cells along x of sort_x are one run).
    int nr = 0;
    std::uint64_t candidates = 0;
    for_each_stencil_cell(grid_, *order_, CellOrder::unpack_coords(coords[key]), kFullStencil, [&](std::uint32_t k, double) {
      const std::uint32_t rb = start[k], re = start[k + 1];
      if (rb == re) return;
      candidates += re - rb;
      if (nr > 0 && ranges[nr - 1].end == rb)
        ranges[nr - 1].end = re;
      else if (nr > 0 && ranges[nr - 1].begin == re)
        ranges[nr - 1].begin = rb;
      else
        ranges[nr++] = {rb, re};
    });
    std::uint32_t* base = out.reserve(used, std::uint64_t{e - b} * candidates, b);
    for (std::uint32_t i = b; i < e; ++i) {
      std::uint32_t* w = base + used;
      for (int r = 0; r < nr; ++r) {
        const std::uint32_t rb = ranges[r].begin;
        const std::uint32_t self = i - rb;  // >= count (no self) unless i lies in this run
        w = append_within(x[i], y[i], z[i], x + rb, y + rb, z + rb, id + rb, ranges[r].end - rb, self, radius2, w);
      }
      used = static_cast<std::uint64_t>(w - base);
      point[i] = id[i];
      offsets[i + 1] = used;
    }
  }
}

void NeighbourSearch::search_gathered(std::span<const double> xin, std::span<const double> yin,
                                      std::span<const double> zin, double radius2, NeighbourLists& out) {
  const std::uint32_t num_keys = order_->num_keys();
  const std::uint64_t* coords = order_->key_coords().data();
  const Gridder& gridder = *gridder_;
  std::uint32_t* idx = gather_index_.data();
  double* x = gx_.data();
  double* y = gy_.data();
  double* z = gz_.data();
  std::uint32_t* point = out.point_.data();
  std::uint64_t* offsets = out.offsets_.data();
  std::uint64_t used = 0;
  std::size_t row = 0;
  for (std::uint32_t key = 0; key < num_keys; ++key) {
    const std::uint64_t c = coords[key];
    if (c == CellOrder::kNoCellCoords) continue;
    const std::uint32_t n_home = gridder.gather_cell(key, idx);
    if (n_home == 0) continue;
    // The home cell first, then its 26 neighbours, gathered into contiguous
    // buffers: particle data stay in input order, so this is where scattered
    // memory is read (what reordering removes).
    std::uint32_t total = n_home;
    for_each_stencil_cell(grid_, *order_, CellOrder::unpack_coords(c), kFullStencil, [&](std::uint32_t k, double) {
      if (k != key) total += gridder.gather_cell(k, idx + total);
    });
    for (std::uint32_t k = 0; k < total; ++k) {
      x[k] = xin[idx[k]];
      y[k] = yin[idx[k]];
      z[k] = zin[idx[k]];
    }
    std::uint32_t* base = out.reserve(used, std::uint64_t{n_home} * total, row);
    for (std::uint32_t h = 0; h < n_home; ++h) {
      std::uint32_t* w = append_within(x[h], y[h], z[h], x, y, z, idx, total, h, radius2, base + used);
      used = static_cast<std::uint64_t>(w - base);
      point[row] = idx[h];
      offsets[++row] = used;
    }
  }
}

}  // namespace sphnl
