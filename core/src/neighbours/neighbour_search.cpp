#include "sphnl/neighbours/neighbour_search.hpp"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <exception>
#include <stdexcept>
#include <string>
#include <vector>

#include "sphnl/neighbours/coordinate_extent.hpp"
#include "sphnl/neighbours/pair_filter.hpp"
#include "sphnl/neighbours/stencil.hpp"
#include "sphnl/permutation.hpp"
#include "sphnl/timer.hpp"

namespace sphnl {

namespace {

struct Range {
  std::uint32_t begin, end;
};

/// The box of the points from their extents; throws std::invalid_argument
/// naming the first point with a non-finite coordinate. An empty cloud has
/// the box {0, 0}.
Box bounding_box(std::span<const double> x, std::span<const double> y, std::span<const double> z,
                 const CoordinateExtents& extents) {
  Box box{{0, 0, 0}, {0, 0, 0}};
  for (int d = 0; d < 3; ++d) {
    if (!extents[d].finite)
      for (std::size_t i = 0; i < x.size(); ++i)
        if (!std::isfinite(x[i]) || !std::isfinite(y[i]) || !std::isfinite(z[i]))
          throw std::invalid_argument("NeighbourSearch: point " + std::to_string(i) + " has a non-finite coordinate");
    box.lo[d] = extents[d].lo;
    box.hi[d] = extents[d].hi;
  }
  return box;
}

}  // namespace

// ------------------------------------------------------------- NeighbourLists

std::uint32_t* NeighbourLists::Segment::reserve(std::uint64_t used, std::uint64_t more, std::size_t rows_done) {
  const std::uint64_t need = used + more + kFilterSlack;
  const std::uint64_t capacity = entries.capacity();
  if (need <= capacity) return entries.data();
  // Grow to the larger of 1.5x and the size the rows done so far project for
  // all the segment's rows, so a segment reallocates a few times at most.
  const double projected =
      rows_done ? 1.15 * static_cast<double>(used) * static_cast<double>(rows) / static_cast<double>(rows_done) : 0.0;
  const std::uint64_t cap = std::max({need, capacity + capacity / 2, static_cast<std::uint64_t>(projected)});
  return entries.grow(cap, used);
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
      }()) {
  gridder_->set_threads(options.threads);
  use_huge_pages(xs_, options.huge_pages);
  use_huge_pages(ys_, options.huge_pages);
  use_huge_pages(zs_, options.huge_pages);
}

NeighbourSearch::~NeighbourSearch() = default;

std::size_t NeighbourSearch::bytes() const {
  std::size_t b = (cell_start_.capacity() + key_bounds_.capacity()) * sizeof(std::uint32_t) +
                  key_work_.capacity() * sizeof(std::uint64_t) +
                  (xs_.capacity() + ys_.capacity() + zs_.capacity()) * sizeof(double);
  for (const Gather& g : gather_)
    b += g.index.capacity() * sizeof(std::uint32_t) + (g.x.capacity() + g.y.capacity() + g.z.capacity()) * sizeof(double);
  return gridder_->bytes() + order_->bytes() + sort_.bytes() + b;
}

void NeighbourSearch::build(std::span<const double> x, std::span<const double> y, std::span<const double> z,
                            double radius, const CoordinateExtents* known) {
  const std::size_t n = x.size();
  if (y.size() != n || z.size() != n) throw std::invalid_argument("NeighbourSearch: x, y, z differ in length");
  if (n >= 0xFFFFFFFFu) throw std::invalid_argument("NeighbourSearch: more than 2^32 - 2 points");
  if (!(radius > 0) || !std::isfinite(radius))
    throw std::invalid_argument("NeighbourSearch: radius must be a positive finite number, got " + std::to_string(radius));
  const int threads = std::max(1, options_.threads);
  const Box box = bounding_box(x, y, z, known ? *known : coordinate_extents(x, y, z, threads));
  double max_abs = 0;
  for (int d = 0; d < 3; ++d) max_abs = std::max({max_abs, std::fabs(box.lo[d]), std::fabs(box.hi[d])});
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
  sort_.place(grid_, *order_, *gridder_, x, y, z, nullptr, threads);
  sort_.cell_starts(*gridder_, order_->num_keys(), cell_start_);
  if (options_.reorder) {
    // Reordering: coordinates permuted into cell order; then only the first
    // particle of each cell needs to be known (§2.4).
    sort_.sort(*gridder_);
    gather_by<double>(x, sort_.permutation(), xs_, threads);
    gather_by<double>(y, sort_.permutation(), ys_, threads);
    gather_by<double>(z, sort_.permutation(), zs_, threads);
  } else {
    const std::size_t room = 27 * std::size_t{gridder_->max_cell_count()} + kFilterSlack;
    gather_.resize(static_cast<std::size_t>(threads));
    for (Gather& g : gather_)
      if (g.index.size() < room) {
        g.index.resize(room);
        g.x.resize(room);
        g.y.resize(room);
        g.z.resize(room);
      }
  }
}

void NeighbourSearch::run(std::span<const double> x, std::span<const double> y, std::span<const double> z,
                          double radius, NeighbourLists& out, const CoordinateExtents* known) {
  Stopwatch sw;
  build(x, y, z, radius, known);
  times_.build = sw.lap();
  use_huge_pages(out.point_, options_.huge_pages);
  use_huge_pages(out.offsets_, options_.huge_pages);
  out.point_.resize(x.size());
  out.offsets_.resize(x.size() + 1);
  out.offsets_[0] = 0;
  if (options_.reorder)
    search_sorted(radius * radius, out);
  else
    search_gathered(x, y, z, radius * radius, out);
  times_.search = sw.lap();
}

template <class Sweep>
void NeighbourSearch::split_rows(NeighbourLists& out, Sweep&& sweep) {
  const std::uint32_t num_keys = order_->num_keys();
  const int threads = std::max(1, options_.threads);
  // Key ranges of about equal work: a cell of n_k points costs about n_k^2
  // distance tests against neighbours as full as itself, so the cut is by the
  // running sum of n_k^2, not of points (by points, the threads' sweeps on a
  // 10^6-point lattice were 0.92 balanced: search_busy_fraction).
  key_bounds_.resize(static_cast<std::size_t>(threads) + 1);
  key_bounds_[0] = 0;
  if (threads > 1) {
    key_work_.resize(std::size_t{num_keys} + 1);
    key_work_[0] = 0;
    for (std::uint32_t k = 0; k < num_keys; ++k) {
      const std::uint64_t nk = cell_start_[k + 1] - cell_start_[k];
      key_work_[k + 1] = key_work_[k] + nk * nk;
    }
    const std::uint64_t total = key_work_[num_keys];
    for (int t = 1; t < threads; ++t) {
      const std::uint64_t want = total * static_cast<std::uint64_t>(t) / static_cast<std::uint64_t>(threads);
      const auto it = std::lower_bound(key_work_.begin() + key_bounds_[t - 1], key_work_.begin() + num_keys, want);
      key_bounds_[t] = static_cast<std::uint32_t>(it - key_work_.begin());
    }
  }
  key_bounds_[threads] = num_keys;
  if (out.segments_.size() < static_cast<std::size_t>(threads)) out.segments_.resize(static_cast<std::size_t>(threads));
  out.num_segments_ = static_cast<std::size_t>(threads);
  for (int t = 0; t < threads; ++t) {
    NeighbourLists::Segment& s = out.segments_[t];
    s.first_row = cell_start_[key_bounds_[t]];
    s.rows = cell_start_[key_bounds_[t + 1]] - s.first_row;
    s.base = 0;
    s.entries.set_huge_pages(options_.huge_pages);
  }
  if (threads == 1) {
    const double start = omp_get_wtime();
    sweep(0, 0u, num_keys, out.segments_[0]);
    times_.sweep_max = times_.sweep_sum = omp_get_wtime() - start;
    return;
  }
  std::exception_ptr failure;
  std::vector<std::uint64_t> used(static_cast<std::size_t>(threads), 0);
  double sweep_max = 0, sweep_sum = 0;
#pragma omp parallel num_threads(threads) reduction(max : sweep_max) reduction(+ : sweep_sum)
  {
    const int t = omp_get_thread_num();
    const int team = omp_get_num_threads();
    const double start = omp_get_wtime();
    // A smaller team than asked for: thread t also sweeps the ranges t + team, ...
    for (int k = t; k < threads; k += team) {
      try {
        used[k] = sweep(k, key_bounds_[k], key_bounds_[k + 1], out.segments_[k]);
      } catch (...) {
#pragma omp critical(sphnl_neighbour_search_failure)
        if (!failure) failure = std::current_exception();
      }
    }
    const double busy = omp_get_wtime() - start;
    sweep_max = busy;
    sweep_sum = busy;
#pragma omp barrier
    // Offsets were written from 0 within each segment: add the entries of the
    // segments before (each thread its own rows, which it wrote).
    for (int k = t; k < threads; k += team) {
      std::uint64_t base = 0;
      for (int j = 0; j < k; ++j) base += used[j];
      NeighbourLists::Segment& s = out.segments_[k];
      s.base = base;
      if (base)
        for (std::size_t r = s.first_row; r < s.first_row + s.rows; ++r) out.offsets_[r + 1] += base;
    }
  }
  times_.sweep_max = sweep_max;
  times_.sweep_sum = sweep_sum;
  if (failure) std::rethrow_exception(failure);
}

void NeighbourSearch::search_sorted(double radius2, NeighbourLists& out) {
  const std::uint64_t* coords_in = order_->key_coords().data();
  const std::uint32_t* start_in = cell_start_.data();
  const double* x_in = xs_.data();
  const double* y_in = ys_.data();
  const double* z_in = zs_.data();
  const std::uint32_t* id_in = sort_.permutation().data();
  std::uint32_t* point_in = out.point_.data();
  std::uint64_t* offsets_in = out.offsets_.data();
  // Expected entries of a key range: if the 27 cells around a cell were as
  // full as the cell, its points would see 27 n_k candidates, of which the
  // fraction (4/3 pi R^3) / (3 side)^3 lies within R.
  const double side = grid_.cell_size, r3 = radius2 * std::sqrt(radius2);
  const double within = 4.18879020478639 * r3 / (27 * side * side * side);
  split_rows(out, [&](int, std::uint32_t key_begin, std::uint32_t key_end, NeighbourLists::Segment& segment) {
    // The hot loop reads its own copies, not the enclosing function's locals
    // through the closure (an extra load each, and a barrier to hoisting).
    const std::uint64_t* const coords = coords_in;
    const std::uint32_t* const start = start_in;
    const double* const x = x_in;
    const double* const y = y_in;
    const double* const z = z_in;
    const std::uint32_t* const id = id_in;
    std::uint32_t* const point = point_in;
    std::uint64_t* const offsets = offsets_in;
    std::uint64_t used = 0;
    {
      // Room for the expected entries up front: growing means copying and
      // touching fresh pages; the thread that fills them touches them first.
      double expected = 0;
      for (std::uint32_t key = key_begin; key < key_end; ++key) {
        const double nk = start[key + 1] - start[key];
        expected += 27 * within * nk * nk;
      }
      segment.reserve(0, static_cast<std::uint64_t>(1.1 * expected), 0);
    }
    const std::uint32_t first = start[key_begin];
    Range ranges[27];
    for (std::uint32_t key = key_begin; key < key_end; ++key) {
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
      std::uint32_t* base = segment.reserve(used, std::uint64_t{e - b} * candidates, b - first);
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
    return used;
  });
}

void NeighbourSearch::search_gathered(std::span<const double> xin, std::span<const double> yin,
                                      std::span<const double> zin, double radius2, NeighbourLists& out) {
  const std::uint64_t* coords = order_->key_coords().data();
  const Gridder& gridder = *gridder_;
  std::uint32_t* point = out.point_.data();
  std::uint64_t* offsets = out.offsets_.data();
  split_rows(out, [&](int thread, std::uint32_t key_begin, std::uint32_t key_end, NeighbourLists::Segment& segment) {
    Gather& g = gather_[thread];
    std::uint32_t* idx = g.index.data();
    double* x = g.x.data();
    double* y = g.y.data();
    double* z = g.z.data();
    std::uint64_t used = 0;
    std::size_t row = segment.first_row;
    for (std::uint32_t key = key_begin; key < key_end; ++key) {
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
      std::uint32_t* base = segment.reserve(used, std::uint64_t{n_home} * total, row - segment.first_row);
      for (std::uint32_t h = 0; h < n_home; ++h) {
        std::uint32_t* w = append_within(x[h], y[h], z[h], x, y, z, idx, total, h, radius2, base + used);
        used = static_cast<std::uint64_t>(w - base);
        point[row] = idx[h];
        offsets[++row] = used;
      }
    }
    return used;
  });
}

}  // namespace sphnl
