#pragma once
// NeighbourSearch: full neighbour lists (every point j != i with |x_j - x_i| < R,
// strictly) of an arbitrary point cloud, found with any gridder (§2.3), cell
// order (§2.4) and reorder choice: the kernel of `sphnl neighbours` and of the
// `search/...` benchmark family.
//
// Cells have side R (slightly more, so that round-off can never put two points
// closer than R two cells apart), and every point tests the 27 cells around
// its own. With reorder on, the coordinates are permuted into cell order so the
// candidates of a point are a few contiguous runs (3-cell runs along x for
// sort_x); with reorder off, each home cell gathers its 27 cells through the
// gridder into a small contiguous buffer. Either way the distance filter of
// pair_filter.hpp tests the candidates and compacts the survivors straight
// into the CSR output.
//
// Threads: the cells are split into `threads` contiguous key ranges of about
// equal work (the sum of n_k^2 over their cells); each thread sweeps its
// range and writes its rows into its own segment of the output, which it
// allocates (once, from the expected count of its cells) and so
// first-touches itself. The rows are
// those of one thread, in the same order: only where their entries live
// differs. The grid, the cell keys, the gridders, the reordering
// permutation, the stencil walk and the filter are those of the cell-linked
// list and the Verlet lists; only the cell side (fitted to the cloud) and the
// full 27-cell stencil are this search's own.
#include <cmath>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "sphnl/grid.hpp"
#include "sphnl/gridders/gridder.hpp"
#include "sphnl/kinds.hpp"
#include "sphnl/neighbours/cell_sort.hpp"
#include "sphnl/neighbours/coordinate_extent.hpp"
#include "sphnl/neighbours/distance.hpp"
#include "sphnl/neighbours/uninit_buffer.hpp"
#include "sphnl/orderings/cell_order.hpp"

namespace sphnl {

struct SearchOptions {
  GridderKind gridder = GridderKind::B;
  CellOrderKind order = CellOrderKind::sort_x;
  bool reorder = true;
  int max_parts_in_cell = 0;  // gridder C; 0 = twice the fullest cell
  int threads = 1;            // rows split over this many OpenMP threads
  /// The lists, their row offsets and the coordinates in cell order on
  /// transparent huge pages (uninit_buffer.hpp): a first call faults once
  /// per 2 MiB of them instead of once per 4 KiB.
  bool huge_pages = true;
};

/// Full neighbour lists in compressed-row form. Rows come in the order the
/// search swept the cells; point(r) is the input index whose neighbours row r
/// holds, and the neighbours are input indices (in no particular order). The
/// entries lie in one segment per thread of the search (offsets are global:
/// row r holds offsets[r + 1] - offsets[r] entries, the rows of all segments
/// together num_entries()).
class NeighbourLists {
 public:
  std::size_t num_rows() const { return point_.size(); }
  std::uint64_t num_entries() const { return offsets_.empty() ? 0 : offsets_.back(); }
  std::uint32_t point(std::size_t r) const { return point_[r]; }
  /// point(r) of every row r: the input points in the order of the rows.
  std::span<const std::uint32_t> points() const { return {point_.data(), point_.size()}; }
  std::span<const std::uint32_t> row(std::size_t r) const {
    const Segment& s = segment_of(r);
    return {s.entries.data() + (offsets_[r] - s.base), static_cast<std::size_t>(offsets_[r + 1] - offsets_[r])};
  }
  /// Neighbour count of every input point, in input order.
  void counts(std::vector<std::uint32_t>& out) const;
  std::size_t bytes() const {
    std::size_t b = offsets_.capacity() * sizeof(std::uint64_t) + point_.capacity() * sizeof(std::uint32_t);
    for (const Segment& s : segments_) b += s.entries.capacity() * sizeof(std::uint32_t);
    return b;
  }

 private:
  friend class NeighbourSearch;
  /// Rows [first_row, next segment's first_row) with their entries; offsets_
  /// of those rows count from `base` (the entries of the segments before).
  struct Segment {
    std::size_t first_row = 0, rows = 0;
    std::uint64_t base = 0;
    UninitBuffer<std::uint32_t> entries;
    /// Makes room for `more` entries past `used` (plus SIMD store slack),
    /// keeping the first `used`, once `rows_done` of its rows are written;
    /// never shrinks.
    std::uint32_t* reserve(std::uint64_t used, std::uint64_t more, std::size_t rows_done);
  };
  const Segment& segment_of(std::size_t r) const {
    std::size_t k = num_segments_ - 1;
    while (segments_[k].first_row > r) --k;
    return segments_[k];
  }
  BufferVector<std::uint32_t> point_;
  BufferVector<std::uint64_t> offsets_;
  std::vector<Segment> segments_;  // kept between runs with their memory
  std::size_t num_segments_ = 1;
};

/// Seconds of the last run, split as `sphnl neighbours` reports them.
struct SearchTimes {
  double build = 0;   // bounds, cells, cell keys, gridder, reordering
  double search = 0;  // distance tests and writing the lists
  // Threads' seconds inside their sweeps (split_rows): the longest, and the
  // sum. sweep_sum / (threads * sweep_max) is the sweep's balance; search
  // minus sweep_max the serial rest (key ranges, global offsets).
  double sweep_max = 0, sweep_sum = 0;
};

class NeighbourSearch {
 public:
  explicit NeighbourSearch(const SearchOptions& options = {});
  ~NeighbourSearch();

  /// Full lists of the points (x[i], y[i], z[i]) within `radius` (strictly)
  /// into `out` (its storage is reused between calls). Coordinates must be
  /// finite; radius > 0. Buffers are kept, so repeated calls do not allocate.
  /// `known`: the coordinates' extents when the caller has scanned them
  /// already (coordinate_extents; the public API checks its input so), to
  /// save the second pass over every coordinate.
  void run(std::span<const double> x, std::span<const double> y, std::span<const double> z, double radius,
           NeighbourLists& out, const CoordinateExtents* known = nullptr);

  const SearchTimes& times() const { return times_; }
  const CellGrid& grid() const { return grid_; }
  const Gridder& gridder() const { return *gridder_; }
  const CellOrder& order() const { return *order_; }
  /// With reorder on: the points of cell key k are the cell-order positions
  /// (= rows) [cell_start()[k], cell_start()[k + 1]), and
  /// coordinate_in_cell_order(d)[r] is axis d of the point in position r
  /// (input point NeighbourLists::point(r)). Empty spans with reorder off.
  std::span<const std::uint32_t> cell_start() const {
    if (!options_.reorder) return {};
    return cell_start_;
  }
  std::span<const double> coordinate_in_cell_order(int axis) const {
    const BufferVector<double>& c = axis == 0 ? xs_ : axis == 1 ? ys_ : zs_;
    if (!options_.reorder) return {};
    return {c.data(), c.size()};
  }
  /// Bytes of the search structures (gridder, ordering tables, keys,
  /// reordering buffers, gather buffers), not counting the lists.
  std::size_t bytes() const;

 private:
  /// The 27 cells of one home cell, gathered (reorder off): one per thread.
  struct Gather {
    std::vector<std::uint32_t> index;
    std::vector<double> x, y, z;
  };
  void build(std::span<const double> x, std::span<const double> y, std::span<const double> z, double radius,
             const CoordinateExtents* known);
  /// Splits the keys into one range per thread and runs
  /// sweep(thread, key_begin, key_end, segment) on each, in parallel when
  /// there are several; then makes the offsets global.
  template <class Sweep>
  void split_rows(NeighbourLists& out, Sweep&& sweep);
  void search_sorted(double radius2, NeighbourLists& out);
  void search_gathered(std::span<const double> x, std::span<const double> y, std::span<const double> z,
                       double radius2, NeighbourLists& out);

  SearchOptions options_;
  CellGrid grid_;
  std::unique_ptr<CellOrder> order_;
  std::unique_ptr<Gridder> gridder_;
  CellSort sort_;  // keys, gridder, and with reorder on the permutation into cell order
  // first point (in cell order) of every key; with reorder on, the
  // coordinates in cell order
  std::vector<std::uint32_t> cell_start_;
  BufferVector<double> xs_, ys_, zs_;
  // reorder off: per thread, the 27 cells of one home cell, gathered
  std::vector<Gather> gather_;
  std::vector<std::uint32_t> key_bounds_;  // first key of every thread's range, and num_keys
  std::vector<std::uint64_t> key_work_;    // threads > 1: running sum of n_k^2 over the keys
  SearchTimes times_;
};

}  // namespace sphnl
