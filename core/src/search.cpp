#include "sphnl/search.hpp"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <new>
#include <stdexcept>
#include <string>

#include "sphnl/neighbours/coordinate_extent.hpp"
#include "sphnl/neighbours/distance.hpp"
#include "sphnl/neighbours/neighbour_search.hpp"
#include "sphnl/neighbours/uninit_buffer.hpp"

namespace sphnl {

bool huge_pages_by_default() {
  static const bool on = !free_memory_reported_to_host();
  return on;
}

namespace {

constexpr int kMaxCellsPerAxis = 1 << 21;

[[noreturn]] void fail(const std::string& what) { throw std::invalid_argument("sphnl::Search: " + what); }

void check_lengths(std::size_t nx, std::size_t ny, std::size_t nz, const char* what) {
  if (ny != nx || nz != nx)
    fail(std::string(what) + ": x, y and z must have the same length, got " + std::to_string(nx) + ", " +
         std::to_string(ny) + " and " + std::to_string(nz));
  if (nx >= std::size_t{0xFFFFFFFFu})
    throw std::length_error("sphnl::Search: " + std::to_string(nx) +
                            " points; indices are 32-bit, so at most 2^32 - 2 points per search (split the cloud)");
}

/// Throws naming the first non-finite coordinate; also refuses clouds whose
/// extent overflows a double (the cell grid could not be sized). Returns the
/// extents, which the engine then need not scan again.
CoordinateExtents check_finite(std::span<const double> x, std::span<const double> y, std::span<const double> z,
                               const char* what, int threads) {
  const CoordinateExtents extents = coordinate_extents(x, y, z, threads);
  const std::span<const double> axes[3] = {x, y, z};
  const char* names[3] = {"x", "y", "z"};
  for (int d = 0; d < 3; ++d) {
    const std::span<const double> v = axes[d];
    const CoordinateExtent& e = extents[d];
    if (!e.finite)  // the slow search for the message only when there is one
      for (std::size_t i = 0; i < v.size(); ++i)
        if (!std::isfinite(v[i]))
          fail(std::string(what) + ": " + names[d] + "[" + std::to_string(i) + "] is " + (std::isnan(v[i]) ? "NaN" : "infinite") +
               "; every coordinate must be finite (remove or fix that point)");
    const double lo = e.lo, hi = e.hi;
    if (!v.empty() && !std::isfinite(hi - lo))
      fail(std::string(what) + ": the " + names[d] + " coordinates span more than the largest double (" +
           std::to_string(lo) + " to " + std::to_string(hi) + "); shift or scale the cloud");
  }
  return extents;
}

template <class T>
void copy_columns(std::span<const T> x, std::span<const T> y, std::span<const T> z, std::vector<double>& ox,
                  std::vector<double>& oy, std::vector<double>& oz) {
  ox.assign(x.begin(), x.end());
  oy.assign(y.begin(), y.end());
  oz.assign(z.begin(), z.end());
}

template <class T>
void split_interleaved(std::span<const T> xyz, std::vector<double>& ox, std::vector<double>& oy, std::vector<double>& oz) {
  if (xyz.size() % 3 != 0)
    fail("build_interleaved: " + std::to_string(xyz.size()) + " values is not a multiple of 3 (x0 y0 z0 x1 y1 z1 ...)");
  const std::size_t n = xyz.size() / 3;
  ox.resize(n);
  oy.resize(n);
  oz.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    ox[i] = xyz[3 * i];
    oy[i] = xyz[3 * i + 1];
    oz[i] = xyz[3 * i + 2];
  }
}

}  // namespace

struct Search::Impl {
  double radius;
  Options options;
  NeighbourSearch engine;
  NeighbourLists lists;
  std::size_t n = 0;  // points of the last build
  // The coordinates of the last build in input order, where the engine
  // cannot be handed the caller's own: float or interleaved input (to be
  // converted), and reorder off (query() reads them after the caller's spans
  // are gone). Double input with reorder on is not copied: the engine keeps
  // the coordinates in cell order, and query() reads those.
  std::vector<double> x, y, z;
  bool built = false;

  Impl(double r, const Options& o)
      : radius(r), options(o), engine([&] {
          SearchOptions s;
          s.gridder = o.gridder;
          s.order = o.cell_order;
          s.reorder = o.reorder;
          s.threads = o.threads;
          s.huge_pages = o.huge_pages;
          return s;
        }()) {}

  /// Runs the engine on x, y, z (length-checked).
  void run(std::span<const double> px, std::span<const double> py, std::span<const double> pz) {
    built = false;  // a failed build leaves no stale results
    const CoordinateExtents extents = check_finite(px, py, pz, "build", options.threads);
    try {
      engine.run(px, py, pz, radius, lists, &extents);
      // Cell coordinates are packed in 21 bits per axis (CellOrder::pack_coords):
      // a longer grid would silently lose pairs, so its lists are refused.
      const CellGrid& grid = engine.grid();
      for (int d = 0; d < 3; ++d)
        if (grid.n[d] > kMaxCellsPerAxis)
          throw std::length_error("sphnl::Search: the cloud needs " + std::to_string(grid.n[d]) + " cells of side " +
                                  std::to_string(grid.cell_size) + " along " + "xyz"[d] + ", more than the " +
                                  std::to_string(kMaxCellsPerAxis) +
                                  " cell coordinates can hold; use a larger radius or split the cloud along that axis");
    } catch (const std::bad_alloc&) {
      built = false;
      throw std::length_error("sphnl::Search: out of memory for the cells or lists of " + std::to_string(px.size()) +
                              " points at radius " + std::to_string(radius) +
                              " (a larger radius than intended, or split the cloud)");
    } catch (const std::logic_error&) {  // invalid_argument and length_error, ours or the engine's
      built = false;
      throw;
    } catch (const std::runtime_error& e) {  // the cell keys or a gridder's rows would overflow
      built = false;
      throw std::length_error(std::string("sphnl::Search: ") + e.what());
    }
    n = px.size();
    built = true;
  }
  /// Runs the engine on the converted copy x, y, z.
  void run_on_copy() { run(x, y, z); }
  /// Runs the engine on the caller's double coordinates, copying them only
  /// where query() will need them in input order (reorder off).
  void run_on(std::span<const double> px, std::span<const double> py, std::span<const double> pz) {
    if (!options.reorder) {
      copy_columns(px, py, pz, x, y, z);
      run_on_copy();
      return;
    }
    x.clear();
    y.clear();
    z.clear();
    run(px, py, pz);
  }

  /// Rows come in the order the engine swept the cells, one per point: row
  /// r's point is the r-th point in cell order.
  std::span<const std::uint32_t> cell_order() const { return lists.points(); }

  /// fn(point, row, kind) for every row of the lists, in cell order.
  template <class Fn>
  void each_row(Rows kind, Fn fn) const {
    for (std::size_t r = 0; r < lists.num_rows(); ++r) fn(lists.point(r), lists.row(r), kind);
  }
};

Search::Search(double radius, const Options& options) {
  if (!(radius > 0) || !std::isfinite(radius))
    fail("radius must be a positive finite number, got " + std::to_string(radius));
  if (options.threads < 1)
    fail("threads = " + std::to_string(options.threads) + ": pass 1 or more (the rows are split over that many threads)");
  impl_ = std::make_unique<Impl>(radius, options);
}

Search::Search(double radius) : Search(radius, Options{}) {}

Search::~Search() = default;
Search::Search(Search&&) noexcept = default;
Search& Search::operator=(Search&&) noexcept = default;

void Search::build(std::span<const double> x, std::span<const double> y, std::span<const double> z) {
  check_lengths(x.size(), y.size(), z.size(), "build");
  impl_->run_on(x, y, z);
}

void Search::build(std::span<const float> x, std::span<const float> y, std::span<const float> z) {
  check_lengths(x.size(), y.size(), z.size(), "build");
  copy_columns(x, y, z, impl_->x, impl_->y, impl_->z);
  impl_->run_on_copy();
}

void Search::build_interleaved(std::span<const double> xyz) {
  split_interleaved(xyz, impl_->x, impl_->y, impl_->z);
  check_lengths(impl_->x.size(), impl_->y.size(), impl_->z.size(), "build_interleaved");
  impl_->run_on_copy();
}

void Search::build_interleaved(std::span<const float> xyz) {
  split_interleaved(xyz, impl_->x, impl_->y, impl_->z);
  check_lengths(impl_->x.size(), impl_->y.size(), impl_->z.size(), "build_interleaved");
  impl_->run_on_copy();
}

void Search::update(std::span<const double> x, std::span<const double> y, std::span<const double> z) {
  if (x.size() != size())
    fail("update: " + std::to_string(x.size()) + " points, but the last build had " + std::to_string(size()) +
         "; call build() for a cloud of another size");
  build(x, y, z);
}

void Search::update(std::span<const float> x, std::span<const float> y, std::span<const float> z) {
  if (x.size() != size())
    fail("update: " + std::to_string(x.size()) + " points, but the last build had " + std::to_string(size()) +
         "; call build() for a cloud of another size");
  build(x, y, z);
}

std::size_t Search::size() const { return impl_->built ? impl_->n : 0; }
double Search::radius() const { return impl_->radius; }
const Search::Options& Search::options() const { return impl_->options; }

std::uint64_t Search::num_entries(Rows kind) const {
  if (!impl_->built) return 0;
  if (kind == Rows::full) return impl_->lists.num_entries();
  // Each pair is in the rows of both its points (the lists are symmetric:
  // r^2 of (i, j) and of (j, i) are the same operations on negated
  // differences), and once in the half rows.
  return impl_->lists.num_entries() / 2;
}

void Search::rows_into(Rows kind, std::span<std::int64_t> offsets, std::span<std::uint32_t> indices) const {
  const std::size_t n = size();
  if (offsets.size() != n + 1)
    fail("rows_into: offsets has " + std::to_string(offsets.size()) + " elements, needs size() + 1 = " + std::to_string(n + 1));
  const std::uint64_t entries = num_entries(kind);
  if (indices.size() != entries)
    fail("rows_into: indices has " + std::to_string(indices.size()) + " elements, needs num_entries() = " +
         std::to_string(entries));
  offsets[0] = 0;
  if (n == 0) return;
  // A transpose instead of a sort: the engine's rows are read in input order
  // (sources i = 0, 1, 2, ...) and i is appended to the output row of each of
  // its neighbours j. The lists are symmetric (i is in row j iff j is in row
  // i), so output row j receives exactly its neighbours, in increasing order:
  // no row needs sorting, and every entry is moved once (a sort of each row
  // costs ~ log2(row) compares per entry, most of them mispredicted
  // branches). A half row j keeps the i > j.
  //
  // Threads split the sources into contiguous ranges: thread t writes the
  // entries i of its range into every row they belong to, after those of
  // the ranges before. Where they start in row j is known from row j itself
  // (by symmetry, its entries in range t are what range t sends to it), so
  // one counting pass over the rows (split by rows) gives every thread its
  // own write positions, and then every entry is read and written once, by
  // one thread.
  const Impl& s = *impl_;
  const NeighbourLists& lists = s.lists;
  const bool half = kind == Rows::half;
  const int threads = static_cast<int>(std::min<std::size_t>(static_cast<std::size_t>(s.options.threads), n));
  const std::ptrdiff_t rows = static_cast<std::ptrdiff_t>(n);
  // Source ranges of about equal entries (from the full row lengths).
  std::vector<std::uint32_t> source_begin(static_cast<std::size_t>(threads) + 1, 0);
  source_begin[threads] = static_cast<std::uint32_t>(n);
  if (threads > 1) {
    std::vector<std::uint64_t> full_before(n + 1, 0);
    for (std::size_t r = 0; r < n; ++r) full_before[lists.point(r) + 1] = lists.row(r).size();
    for (std::size_t i = 0; i < n; ++i) full_before[i + 1] += full_before[i];
    for (int t = 1; t < threads; ++t) {
      const std::uint64_t want = full_before[n] * static_cast<std::uint64_t>(t) / static_cast<std::uint64_t>(threads);
      source_begin[t] = static_cast<std::uint32_t>(std::lower_bound(full_before.begin(), full_before.end() - 1, want) -
                                                   full_before.begin());
    }
  }
  // next[t * n + j]: where range t writes its next entry of row j; first the
  // count of row j's entries in range t, then (below) the position.
  std::vector<std::int64_t> next(static_cast<std::size_t>(threads) * n);
  std::int64_t* const count = next.data();
#pragma omp parallel for num_threads(threads) schedule(static) if (threads > 1)
  for (std::ptrdiff_t r = 0; r < rows; ++r) {
    const std::uint32_t j = lists.point(static_cast<std::size_t>(r));
    const std::span<const std::uint32_t> row = lists.row(static_cast<std::size_t>(r));
    if (threads == 1 && !half) {
      count[j] = static_cast<std::int64_t>(row.size());
      continue;
    }
    std::int64_t total = static_cast<std::int64_t>(row.size());
    if (half) {
      total = 0;
      for (const std::uint32_t i : row) total += i > j;
    }
    // The entries in every source range but the last; the last by difference.
    std::int64_t before_last = 0;
    for (int t = 0; t + 1 < threads; ++t) {
      const std::uint32_t lo = std::max(source_begin[t], half ? j + 1 : 0u), hi = source_begin[t + 1];
      std::int64_t c = 0;
      for (const std::uint32_t i : row) c += (i >= lo) & (i < hi);
      count[static_cast<std::size_t>(t) * n + j] = c;
      before_last += c;
    }
    count[static_cast<std::size_t>(threads - 1) * n + j] = total - before_last;
    offsets[std::size_t{j} + 1] = total;
  }
  if (threads == 1 && !half)
    for (std::size_t j = 0; j < n; ++j) offsets[j + 1] = count[j];
  for (std::size_t j = 0; j < n; ++j) offsets[j + 1] += offsets[j];
#pragma omp parallel for num_threads(threads) schedule(static) if (threads > 1)
  for (std::ptrdiff_t j = 0; j < rows; ++j) {
    std::int64_t at = offsets[j];
    for (int t = 0; t < threads; ++t) {
      std::int64_t& slot = next[static_cast<std::size_t>(t) * n + static_cast<std::size_t>(j)];
      const std::int64_t c = slot;
      slot = at;
      at += c;
    }
  }
  // Input point -> engine row (the inverse of cell_order).
  std::vector<std::uint32_t> row_of(n);
  const std::span<const std::uint32_t> point_of_row = s.cell_order();
#pragma omp parallel for num_threads(threads) schedule(static) if (threads > 1)
  for (std::ptrdiff_t r = 0; r < rows; ++r) row_of[point_of_row[r]] = static_cast<std::uint32_t>(r);
  std::uint32_t* const out = indices.data();
#pragma omp parallel num_threads(threads) if (threads > 1)
  {
    const int team = omp_get_num_threads();
    for (int t = omp_get_thread_num(); t < threads; t += team) {
      std::int64_t* const at = next.data() + static_cast<std::size_t>(t) * n;
      for (std::uint32_t i = source_begin[t]; i < source_begin[t + 1]; ++i) {
        const std::span<const std::uint32_t> row = lists.row(row_of[i]);
        if (half) {
          for (const std::uint32_t j : row)
            if (i > j) out[at[j]++] = i;
        } else {
          for (const std::uint32_t j : row) out[at[j]++] = i;
        }
      }
    }
  }
}

CompressedRows Search::rows(Rows kind) const {
  CompressedRows out;
  out.offsets.resize(size() + 1);
  out.indices.resize(num_entries(kind));
  rows_into(kind, out.offsets, out.indices);
  return out;
}

void Search::visit_pairs(PairVisitor visit, void* ctx) const {
  if (!impl_->built) return;
  impl_->each_row(Rows::half, [&](std::uint32_t i, std::span<const std::uint32_t> row, Rows) {
    for (std::uint32_t j : row)
      if (j > i) visit(ctx, i, j);
  });
}

void Search::visit_rows(RowVisitor visit, void* ctx) const {
  if (!impl_->built) return;
  impl_->each_row(Rows::full, [&](std::uint32_t i, std::span<const std::uint32_t> row, Rows) {
    visit(ctx, i, row.data(), row.size());
  });
}

std::span<const std::uint32_t> Search::cell_order() const {
  if (!impl_->built) return {};
  return impl_->cell_order();
}

void Search::check_field_size(std::size_t src, std::size_t dst) const {
  if (src != size() || dst != size())
    fail("apply_cell_order: the field has " + std::to_string(src) + " elements (output " + std::to_string(dst) +
         "), the search " + std::to_string(size()) + " points; pass one value per point of the last build");
}

CompressedRows Search::query(std::span<const double> qx, std::span<const double> qy, std::span<const double> qz) const {
  if (!impl_->built) throw std::logic_error("sphnl::Search::query: call build() first");
  check_lengths(qx.size(), qy.size(), qz.size(), "query");
  const std::size_t nq = qx.size();
  const Impl& s = *impl_;
  const CellGrid& grid = s.engine.grid();
  const CellOrder& order = s.engine.order();
  const Gridder& gridder = s.engine.gridder();
  const double radius2 = s.radius * s.radius;
  // With reorder on the engine holds the coordinates in cell order (the
  // build did not copy the caller's); with it off, s.x, s.y, s.z, and each
  // cell is gathered through the gridder into `cell`.
  const std::span<const std::uint32_t> start = s.engine.cell_start(), point = s.cell_order();
  const std::span<const double> xs = s.engine.coordinate_in_cell_order(0), ys = s.engine.coordinate_in_cell_order(1),
                                zs = s.engine.coordinate_in_cell_order(2);
  const bool in_cell_order = !start.empty();
  std::vector<std::uint32_t> cell(in_cell_order ? 0 : std::max<std::size_t>(1, gridder.max_cell_count()));
  CompressedRows out;
  out.offsets.assign(nq + 1, 0);
  for (std::size_t q = 0; q < nq; ++q) {
    const double p[3] = {qx[q], qy[q], qz[q]};
    for (int d = 0; d < 3; ++d)
      if (!std::isfinite(p[d]))
        fail(std::string("query: ") + "xyz"[d] + std::string("[") + std::to_string(q) + "] is not finite; every query coordinate must be finite");
    const std::size_t row_begin = out.indices.size();
    // Cells have side >= radius (the engine sizes them so, round-off
    // included), so a point closer than radius lies in one of the 27 cells
    // around the query's; a query beyond the grid's ring of cells has none.
    int lo[3], hi[3];
    bool outside = false;
    for (int d = 0; d < 3; ++d) {
      const double c = std::floor((p[d] - grid.box.lo[d]) * grid.inv_cell_size);
      if (c < -1.0 || c > grid.n[d]) {
        outside = true;
        break;
      }
      lo[d] = std::max(0, static_cast<int>(c) - 1);
      hi[d] = std::min(grid.n[d] - 1, static_cast<int>(c) + 1);
    }
    if (!outside && s.n > 0) {
      for (int cz = lo[2]; cz <= hi[2]; ++cz)
        for (int cy = lo[1]; cy <= hi[1]; ++cy)
          for (int cx = lo[0]; cx <= hi[0]; ++cx) {
            const std::uint32_t key = order.key(cx, cy, cz);
            if (in_cell_order) {  // the cell's points are consecutive positions
              for (std::uint32_t r = start[key]; r < start[key + 1]; ++r)
                if (distance2(xs[r] - p[0], ys[r] - p[1], zs[r] - p[2]) < radius2) out.indices.push_back(point[r]);
              continue;
            }
            const std::uint32_t count = gridder.gather_cell(key, cell.data());
            for (std::uint32_t k = 0; k < count; ++k) {
              const std::uint32_t j = cell[k];
              if (distance2(s.x[j] - p[0], s.y[j] - p[1], s.z[j] - p[2]) < radius2) out.indices.push_back(j);
            }
          }
      std::sort(out.indices.begin() + static_cast<std::ptrdiff_t>(row_begin), out.indices.end());
    }
    out.offsets[q + 1] = static_cast<std::int64_t>(out.indices.size());
  }
  return out;
}

CompressedRows Search::query(std::span<const float> qx, std::span<const float> qy, std::span<const float> qz) const {
  std::vector<double> x, y, z;
  check_lengths(qx.size(), qy.size(), qz.size(), "query");
  copy_columns(qx, qy, qz, x, y, z);
  return query(std::span<const double>(x), std::span<const double>(y), std::span<const double>(z));
}

}  // namespace sphnl
