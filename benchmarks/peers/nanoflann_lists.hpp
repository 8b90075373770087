#pragma once
// The nanoflann peer of the `search` family (impl: nanoflann): full neighbour
// lists (every j != i strictly closer than R) of the same points, built the
// way a nanoflann user builds them: a k-d tree over the points, then one
// radius search per point, its hits appended to compressed rows in input
// order. Rows are split over `threads` OpenMP threads in contiguous blocks,
// each thread appending to its own vectors, which are then joined (in
// parallel, each thread copying its own block) into one array.
//
// nanoflann compares squared distances, with `<` in some versions and `<=` in
// others; the result set below applies sphnl's rule itself (r^2 < R^2, i
// excluded), so the pair set is the same whatever the installed version.
#include <omp.h>

#include <nanoflann.hpp>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <span>
#include <vector>

#include "sphnl/neighbours/pair_checksum.hpp"

namespace sphnl::peers {

/// Full neighbour lists in input order: the neighbours of point i are
/// entries[offsets[i] .. offsets[i + 1]), in nanoflann's order.
struct PeerLists {
  std::vector<std::uint64_t> offsets;
  std::vector<std::uint32_t> entries;

  PairChecksum checksum() const {
    PairChecksum c;
    for (std::size_t i = 0; i + 1 < offsets.size(); ++i)
      c.add_row(static_cast<std::uint32_t>(i), entries.data() + offsets[i], offsets[i + 1] - offsets[i]);
    return c;
  }
};

/// nanoflann's dataset interface over x, y, z columns.
struct ColumnCloud {
  std::span<const double> x, y, z;
  std::size_t kdtree_get_point_count() const { return x.size(); }
  double kdtree_get_pt(std::size_t i, std::size_t d) const { return d == 0 ? x[i] : d == 1 ? y[i] : z[i]; }
  template <class Box>
  bool kdtree_get_bbox(Box&) const {
    return false;  // nanoflann computes it
  }
};

using KdTree =
    nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<double, ColumnCloud>, ColumnCloud, 3, std::uint32_t>;

/// Hits strictly closer than R, the query point itself left out.
class StrictRadiusHits {
 public:
  using DistanceType = double;
  using IndexType = std::uint32_t;
  StrictRadiusHits(double radius2, std::uint32_t self, std::vector<std::uint32_t>& out)
      : radius2_(radius2), self_(self), out_(out) {}
  void init() {}
  void clear() {}
  std::size_t size() const { return count_; }
  bool full() const { return true; }
  bool addPoint(double dist2, std::uint32_t j) {
    if (dist2 < radius2_ && j != self_) {
      out_.push_back(j);
      ++count_;
    }
    return true;
  }
  double worstDist() const { return radius2_; }

 private:
  double radius2_;
  std::uint32_t self_;
  std::vector<std::uint32_t>& out_;
  std::size_t count_ = 0;
};

#if NANOFLANN_VERSION >= 0x150
using SearchParameters = nanoflann::SearchParameters;
#else
using SearchParameters = nanoflann::SearchParams;
#endif

/// Leaf size of the tree: nanoflann's default.
inline constexpr std::size_t kLeafSize = 10;

/// Full lists of the points within `radius` into `out` (overwritten).
inline void nanoflann_full_lists(std::span<const double> x, std::span<const double> y, std::span<const double> z,
                                 double radius, int threads, PeerLists& out) {
  const std::size_t n = x.size();
  const ColumnCloud cloud{x, y, z};
  const KdTree tree(3, cloud, nanoflann::KDTreeSingleIndexAdaptorParams(kLeafSize));
  const double radius2 = radius * radius;
  SearchParameters params;
  params.sorted = false;  // sphnl's engine does not sort its rows either
  threads = std::max(1, threads);
  out.offsets.resize(n + 1);
  out.offsets[0] = 0;
  std::vector<std::vector<std::uint32_t>> parts(static_cast<std::size_t>(threads));
  std::vector<std::uint64_t> part_begin(static_cast<std::size_t>(threads) + 1, 0);
  int team = 1;
#pragma omp parallel num_threads(threads)
  {
    const int t = omp_get_thread_num(), nt = omp_get_num_threads();
    const std::size_t b = n * static_cast<std::size_t>(t) / static_cast<std::size_t>(nt);
    const std::size_t e = n * static_cast<std::size_t>(t + 1) / static_cast<std::size_t>(nt);
    std::vector<std::uint32_t>& mine = parts[static_cast<std::size_t>(t)];
    for (std::size_t i = b; i < e; ++i) {
      const double q[3] = {x[i], y[i], z[i]};
      StrictRadiusHits hits(radius2, static_cast<std::uint32_t>(i), mine);
      tree.radiusSearchCustomCallback(q, hits, params);
      out.offsets[i + 1] = mine.size();  // within this thread's part, made global below
    }
#pragma omp barrier
#pragma omp single
    {  // its implicit barrier: every thread sees part_begin and team after it
      team = nt;
      for (std::size_t k = 0; k < static_cast<std::size_t>(nt); ++k) part_begin[k + 1] = part_begin[k] + parts[k].size();
    }
    const std::uint64_t base = part_begin[static_cast<std::size_t>(t)];
    for (std::size_t i = b; i < e; ++i) out.offsets[i + 1] += base;
    if (nt > 1) {
#pragma omp single
      out.entries.resize(part_begin[static_cast<std::size_t>(nt)]);
      if (!mine.empty()) std::memcpy(out.entries.data() + base, mine.data(), mine.size() * sizeof(std::uint32_t));
    }
  }
  if (team == 1) out.entries.swap(parts[0]);
}

}  // namespace sphnl::peers
