#pragma once
// The pairs each path of the library finds, as sets comparable with the
// oracle: the simulation's path (ParticleGrid + CellSweep + distance filter)
// and NeighbourSearch's full lists; and every gridder / cell order choice.
#include <algorithm>
#include <cmath>
#include <string>

#include <gtest/gtest.h>

#include "sphnl/kinds.hpp"
#include "sphnl/neighbours/cell_sweep.hpp"
#include "sphnl/neighbours/neighbour_search.hpp"
#include "sphnl/neighbours/pair_filter.hpp"
#include "sphnl/neighbours/particle_grid.hpp"
#include "support/oracle.hpp"

namespace sphnl::test {

inline constexpr GridderKind kGridders[] = {GridderKind::A, GridderKind::B, GridderKind::C, GridderKind::D};
inline constexpr CellOrderKind kOrders[] = {CellOrderKind::sort_x, CellOrderKind::sort_xy, CellOrderKind::sort_xyz,
                                            CellOrderKind::hilbert};

inline std::string combo(GridderKind g, CellOrderKind o, bool reorder) {
  return std::string("gridder ") + to_string(g) + ", order " + to_string(o) + ", reorder " + (reorder ? "1" : "0");
}


/// Pairs the simulation's path finds: ParticleGrid (cells of side sqrt(support2),
/// optional reordering) swept by CellSweep with the shared distance filter.
inline PairSet swept_pairs(ParticleSet& ps, const Box& domain, double support2, GridderKind g, CellOrderKind o, bool reorder,
                    const GridderOptions& options = {}, double period_y = 0,
                    InnerOrder inner = InnerOrder::index) {
  ParticleGrid pg(domain, o, g, options, period_y);
  pg.set_inner_order(inner);
  pg.build(ps, std::sqrt(support2), reorder);
  if (reorder) {  // reordered: keys are non-decreasing, out particles last
    const auto& keys = pg.cell_keys();
    for (std::size_t k = 1; k < keys.size(); ++k)
      if (keys[k] < keys[k - 1]) ADD_FAILURE() << combo(g, o, reorder) << ": keys not in cell order at " << k;
  }
  CellSweep sweep;
  PairSet pairs;
  sweep.run(pg.grid(), pg.order(), pg.gridder(), ps, fields::position, 1,
            [&](int, CellSweep::Scratch& s, std::uint32_t n_home) {
              const ParticleView v = s.buffer.view();
              const std::uint32_t* index = s.buffer.index();
              for (std::uint32_t i = 0; i < n_home; ++i) {
                const int m = filter_range(v, i, i + 1, s.buffer.size(), support2, s.survivors.data());
                for (int k = 0; k < m; ++k) {
                  const std::uint32_t a = ps.id[index[i]], b = ps.id[index[s.survivors[k]]];
                  pairs.emplace_back(std::min(a, b), std::max(a, b));
                }
              }
            });
  std::sort(pairs.begin(), pairs.end());
  return pairs;
}

/// Pairs (i < j, input indices) of NeighbourSearch's full lists; also checks
/// that the lists are symmetric (j in row i iff i in row j).
inline PairSet searched_pairs(const ParticleSet& ps, double radius, GridderKind g, CellOrderKind o, bool reorder) {
  NeighbourSearch search(SearchOptions{g, o, reorder, 0});
  NeighbourLists lists;
  search.run(ps.x, ps.y, ps.z, radius, lists);
  PairSet pairs, lower;
  EXPECT_EQ(lists.num_rows(), ps.size());
  for (std::size_t r = 0; r < lists.num_rows(); ++r) {
    const std::uint32_t i = lists.point(r);
    for (std::uint32_t j : lists.row(r)) (i < j ? pairs : lower).emplace_back(std::min(i, j), std::max(i, j));
  }
  std::sort(pairs.begin(), pairs.end());
  std::sort(lower.begin(), lower.end());
  EXPECT_EQ(pairs, lower) << combo(g, o, reorder) << ": lists are not symmetric";
  return pairs;
}


}  // namespace sphnl::test
