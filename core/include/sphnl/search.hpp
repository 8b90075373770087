#pragma once
// sphnl's public neighbour-search API: every point j within a radius of every
// point i (strictly, |x_j - x_i| < radius) of a 3-D point cloud, found with the
// cell grid of the paper (cells of side >= radius, 27-cell stencil, §2.5 (a)),
// any gridder (§2.3), cell order (§2.4) and reordering choice.
//
//   #include <sphnl/search.hpp>
//   sphnl::Search s(0.1);                 // radius, default options
//   s.build(x, y, z);                     // spans of float or double
//   sphnl::CompressedRows rows = s.rows(sphnl::Rows::full);
//   for (std::uint64_t k = rows.offsets[i]; k < rows.offsets[i + 1]; ++k) use(rows.indices[k]);
//
// A thin layer over NeighbourSearch (the engine of `sphnl neighbours` and of
// the `search` benchmarks); this header includes none of the engine's headers.
// Not thread-safe: one Search per calling thread (Options::threads is how
// one search uses several). A moved-from Search may only be
// assigned to or destroyed.
#include <cstdint>
#include <memory>
#include <span>
#include <type_traits>
#include <vector>

#include "sphnl/kinds.hpp"

namespace sphnl {

/// Which pairs a row holds.
enum class Rows : std::uint8_t {
  full,  ///< row i holds every neighbour j of i (each pair appears in two rows)
  half,  ///< row i holds the neighbours j > i only (each pair appears once)
};

/// Neighbour lists in compressed-row form, in input order: the neighbours of
/// point i are indices[offsets[i]] .. indices[offsets[i + 1] - 1], sorted
/// ascending. offsets has n + 1 entries (offsets[0] = 0); for a query,
/// row q belongs to query point q and holds indices of the built points.
struct CompressedRows {
  std::vector<std::int64_t> offsets;
  std::vector<std::uint32_t> indices;
};

/// The default of Search::Options::huge_pages on this machine: on, except in a
/// virtual machine whose kernel reports free memory to its host (virtio
/// balloon free page reporting), where a first build in a fresh process ran
/// 1.4-1.6x faster on base pages (its memory has been handed to the host, and
/// huge pages of it cost twice as much to fault in); read once per process.
bool huge_pages_by_default();

class Search {
 public:
  struct Options {
    GridderKind gridder = GridderKind::B;            ///< particles in cells, paper §2.3
    CellOrderKind cell_order = CellOrderKind::sort_x;  ///< numbering of the cells, §2.4
    bool reorder = true;  ///< search on coordinates copied into cell order (§2.4); results do not change
    /// OpenMP threads the search and rows() split the rows over (>= 1); the
    /// lists do not depend on it.
    int threads = 1;
    /// Lists in memory advised as transparent huge pages (Linux): a first
    /// build faults once per 2 MiB of lists instead of once per 4 KiB, which
    /// on a virtual machine is most of a first call's time. Off: base pages.
    /// Default: huge_pages_by_default() (off where the kernel hands free
    /// memory back to its host).
    bool huge_pages = huge_pages_by_default();
  };

  /// A search for neighbours closer than `radius`. Throws std::invalid_argument
  /// when radius is not a positive finite number or options.threads < 1.
  Search(double radius, const Options& options);
  /// Search(radius, Options{}): gridder B, sort_x, reordering, one thread.
  explicit Search(double radius);
  ~Search();
  Search(Search&&) noexcept;
  Search& operator=(Search&&) noexcept;
  Search(const Search&) = delete;
  Search& operator=(const Search&) = delete;

  /// Finds the neighbours of the points (x[i], y[i], z[i]). May be called again
  /// with another cloud; buffers are reused. The spans are read during the
  /// call only. Float input is widened into internal double buffers (the
  /// engine computes in double). Throws std::invalid_argument for spans of
  /// different lengths or a non-finite coordinate (naming the point), and
  /// std::length_error for 2^32 - 1 points or more, for a grid of more than
  /// 2^21 cells along one axis (the cell coordinates' range), or when memory
  /// runs out. After a failed build, size() is 0 and no old results remain.
  void build(std::span<const double> x, std::span<const double> y, std::span<const double> z);
  /// build() for float coordinates (widened to double internally).
  void build(std::span<const float> x, std::span<const float> y, std::span<const float> z);
  /// build() from interleaved coordinates x0 y0 z0 x1 y1 z1 ... (3 n values,
  /// e.g. a C-contiguous (n, 3) array), split into internal x/y/z buffers.
  /// Throws std::invalid_argument when the length is not a multiple of 3.
  void build_interleaved(std::span<const double> xyz);
  /// build_interleaved() for float coordinates.
  void build_interleaved(std::span<const float> xyz);

  /// After the points moved: the same number of points (else
  /// std::invalid_argument), searched again in the buffers of the last build
  /// (no allocation unless the lists grow). The cells are rebuilt on every
  /// call: the engine has no incremental re-sort yet.
  void update(std::span<const double> x, std::span<const double> y, std::span<const double> z);
  /// update() for float coordinates.
  void update(std::span<const float> x, std::span<const float> y, std::span<const float> z);

  /// Number of points of the last build (0 before the first).
  std::size_t size() const;
  double radius() const;
  const Options& options() const;

  /// Number of entries rows(kind) holds: 2 x pairs for full, pairs for half.
  std::uint64_t num_entries(Rows kind) const;
  /// The lists of the last build, in input order, each row sorted ascending.
  CompressedRows rows(Rows kind) const;
  /// rows() into caller-owned storage: offsets.size() must be size() + 1 and
  /// indices.size() must be num_entries(kind) (else std::invalid_argument),
  /// so a caller allocates its outputs exactly once.
  void rows_into(Rows kind, std::span<std::int64_t> offsets, std::span<std::uint32_t> indices) const;

  /// Calls f(i, j) once for every pair of neighbours, with i < j (input
  /// indices), in cell order (cache-friendly). The user stores no list; the
  /// pairs come from the search's own lists of the last build.
  template <class F>
  void for_each_pair(F&& f) const {
    visit_pairs([](void* ctx, std::uint32_t i, std::uint32_t j) { (*static_cast<std::remove_reference_t<F>*>(ctx))(i, j); },
                const_cast<void*>(static_cast<const void*>(&f)));
  }

  /// Calls f(i, neighbours) once for every point i of the last build, with
  /// neighbours a std::span<const std::uint32_t> of the input indices of all
  /// its neighbours (as row i of rows(Rows::full), but in no particular
  /// order), points in cell order. The spans are the search's own lists,
  /// read in place (valid until the next build): no copy, no sort, so this
  /// costs what the search costs, while rows() moves every entry once more
  /// to put the rows in input order, sorted.
  template <class F>
  void for_each_row(F&& f) const {
    visit_rows(
        [](void* ctx, std::uint32_t i, const std::uint32_t* row, std::size_t count) {
          (*static_cast<std::remove_reference_t<F>*>(ctx))(i, std::span<const std::uint32_t>(row, count));
        },
        const_cast<void*>(static_cast<const void*>(&f)));
  }

  /// The cell-order permutation of the last build (as CompactNSearch's
  /// z_sort): the k-th point in cell order is input point cell_order()[k].
  /// Putting your arrays in this order (apply_cell_order) and building again
  /// makes neighbours close in memory.
  std::span<const std::uint32_t> cell_order() const;
  /// dst[k] = src[cell_order()[k]] (as CompactNSearch's sort_field); both of
  /// size() elements (else std::invalid_argument), and not overlapping.
  template <class T>
  void apply_cell_order(std::span<const T> src, std::span<T> dst) const {
    const std::span<const std::uint32_t> order = cell_order();
    check_field_size(src.size(), dst.size());
    for (std::size_t k = 0; k < order.size(); ++k) dst[k] = src[order[k]];
  }
  /// apply_cell_order() in place on a vector of size() elements.
  template <class T>
  void apply_cell_order(std::vector<T>& field) const {
    std::vector<T> sorted(field.size());
    apply_cell_order(std::span<const T>(field), std::span<T>(sorted));
    field.swap(sorted);
  }

  /// Neighbours among the built points of each query point (qx[q], qy[q],
  /// qz[q]): row q holds every built point closer than radius() to it,
  /// sorted ascending; a query point equal to a built point lists it (no
  /// self-exclusion across sets). Query points may lie anywhere. Each query
  /// looks up the 27 cells around it through the gridder: correct for any
  /// gridder, but not the engine's fast path (no batching, no reordering).
  /// Throws as build() does for bad spans or coordinates, std::logic_error
  /// before the first build.
  CompressedRows query(std::span<const double> qx, std::span<const double> qy, std::span<const double> qz) const;
  /// query() for float coordinates (widened to double).
  CompressedRows query(std::span<const float> qx, std::span<const float> qy, std::span<const float> qz) const;

 private:
  using PairVisitor = void (*)(void*, std::uint32_t, std::uint32_t);
  void visit_pairs(PairVisitor visit, void* ctx) const;
  using RowVisitor = void (*)(void*, std::uint32_t, const std::uint32_t*, std::size_t);
  void visit_rows(RowVisitor visit, void* ctx) const;
  void check_field_size(std::size_t src, std::size_t dst) const;
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace sphnl
