// KeyPartition and Decomposition (parallel/decomposition.hpp): the serial
// part of the domain decomposition, without any communicator.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <numeric>
#include <set>
#include <stdexcept>
#include <vector>

#include "sphnl/parallel/decomposition.hpp"

namespace sphnl {
namespace {

TEST(KeyPartition, EqualWeightsGiveEqualRanges) {
  const std::vector<double> w(12, 1.0);
  const KeyPartition p = KeyPartition::balanced(w, 4);
  ASSERT_EQ(p.ranks(), 4);
  for (int r = 0; r < 4; ++r) {
    EXPECT_EQ(p.begin(r), static_cast<std::uint32_t>(3 * r));
    EXPECT_EQ(p.end(r), static_cast<std::uint32_t>(3 * r + 3));
  }
  EXPECT_DOUBLE_EQ(imbalance(p.rank_weights(w)), 0.0);
}

TEST(KeyPartition, RangesAreContiguousAndCoverEveryKey) {
  std::vector<double> w(100);
  for (std::size_t k = 0; k < w.size(); ++k) w[k] = (k % 7 == 0) ? 10.0 : (k % 3 == 0 ? 0.0 : 1.0);
  for (int ranks : {1, 2, 3, 5, 8}) {
    const KeyPartition p = KeyPartition::balanced(w, ranks);
    EXPECT_EQ(p.begin(0), 0u);
    EXPECT_EQ(p.end(ranks - 1), 100u);
    for (int r = 0; r < ranks; ++r) {
      EXPECT_LT(p.begin(r), p.end(r)) << "rank " << r << " owns no key";
      if (r > 0) {
        EXPECT_EQ(p.begin(r), p.end(r - 1));
      }
      for (std::uint32_t k = p.begin(r); k < p.end(r); ++k) EXPECT_EQ(p.owner(k), r);
    }
    // A cut lands on a key boundary: no rank is over the mean by more than the heaviest key.
    const auto rw = p.rank_weights(w);
    const double mean = std::accumulate(rw.begin(), rw.end(), 0.0) / ranks;
    for (double x : rw) EXPECT_LE(x, mean + 10.0);
  }
}

TEST(KeyPartition, WeightInOneKeyStillGivesEveryRankAKey) {
  std::vector<double> w(6, 0.0);
  w[2] = 5.0;
  const KeyPartition p = KeyPartition::balanced(w, 4);
  for (int r = 0; r < 4; ++r) EXPECT_LT(p.begin(r), p.end(r));
  EXPECT_EQ(p.end(3), 6u);
  const std::vector<double> none(5, 0.0);
  const KeyPartition q = KeyPartition::balanced(none, 5);
  for (int r = 0; r < 5; ++r) EXPECT_EQ(q.end(r) - q.begin(r), 1u);
}

TEST(KeyPartition, MoreRanksThanKeysIsRefused) {
  const std::vector<double> w(3, 1.0);
  EXPECT_THROW(KeyPartition::balanced(w, 4), std::invalid_argument);
  EXPECT_THROW(KeyPartition::balanced(w, 0), std::invalid_argument);
}

TEST(KeyPartition, ImbalanceIsTheHeaviestRankOverTheMean) {
  EXPECT_DOUBLE_EQ(imbalance(std::vector<double>{1, 1, 1, 1}), 0.0);
  EXPECT_DOUBLE_EQ(imbalance(std::vector<double>{3, 1}), 0.5);
  EXPECT_DOUBLE_EQ(imbalance(std::vector<double>{0, 0}), 0.0);
}

struct GridFixture {
  explicit GridFixture(CellOrderKind kind, int nx, int ny, int nz, double period_y = 0) : order(make_cell_order(kind)) {
    Box b;
    b.hi[0] = nx;
    b.hi[1] = ny;
    b.hi[2] = nz;
    grid = CellGrid(b, 1.0, period_y);
    order->setup(grid);
  }
  CellGrid grid;
  std::unique_ptr<CellOrder> order;
};

TEST(Decomposition, SlabsAlongSortXHaveOneLayerOfHalo) {
  // sort_x keys run x fastest, then y, then z: two ranks of equal weight get
  // the lower and the upper two z-layers of a 4x3x4 grid.
  GridFixture f(CellOrderKind::sort_x, 4, 3, 4);
  const std::vector<double> w(f.order->num_keys(), 1.0);
  const KeyPartition p = KeyPartition::balanced(w, 2);
  const Decomposition d(f.grid, *f.order, p);
  const auto halo0 = d.halo_cells(0), halo1 = d.halo_cells(1);
  ASSERT_EQ(halo0.size(), 12u);  // the z = 2 layer
  ASSERT_EQ(halo1.size(), 12u);  // the z = 1 layer
  for (const auto k : halo0) EXPECT_EQ(f.order->key_coords()[k] >> 42, 2u);
  for (const auto k : halo1) EXPECT_EQ(f.order->key_coords()[k] >> 42, 1u);
}

TEST(Decomposition, GhostDestinationsAreTheHalosSeenFromTheSender) {
  for (const CellOrderKind kind : {CellOrderKind::sort_x, CellOrderKind::sort_xyz, CellOrderKind::hilbert})
    for (const double period : {0.0, 5.0}) {
      GridFixture f(kind, 6, 5, 4, period);
      std::vector<double> w(f.order->num_keys(), 0.0);
      for (std::uint32_t k = 0; k < w.size(); ++k)
        if (f.order->key_coords()[k] != CellOrder::kNoCellCoords) w[k] = 1.0 + k % 3;
      const KeyPartition p = KeyPartition::balanced(w, 5);
      const Decomposition d(f.grid, *f.order, p);
      std::vector<std::set<std::uint32_t>> from_senders(5);
      std::vector<int> dest;
      for (std::uint32_t k = 0; k < f.order->num_keys(); ++k) {
        d.ghost_destinations(k, dest);
        for (const int r : dest) {
          EXPECT_NE(r, p.owner(k));
          from_senders[r].insert(k);
        }
      }
      for (int r = 0; r < 5; ++r) {
        const auto halo = d.halo_cells(r);
        EXPECT_EQ(std::vector<std::uint32_t>(from_senders[r].begin(), from_senders[r].end()), halo)
            << "rank " << r << " order " << to_string(kind) << " period " << period;
        EXPECT_FALSE(halo.empty());
        // Neighbour-exchange partners: symmetric, and every rank that sends r a ghost is one.
        const std::vector<int> mine = d.partners(r);
        EXPECT_TRUE(std::is_sorted(mine.begin(), mine.end()));
        EXPECT_EQ(std::count(mine.begin(), mine.end(), r), 0);
        for (const int q : mine) {
          const std::vector<int> theirs = d.partners(q);
          EXPECT_EQ(std::count(theirs.begin(), theirs.end(), r), 1) << r << " lists " << q << " but not back";
        }
        for (const std::uint32_t k : halo)
          EXPECT_EQ(std::count(mine.begin(), mine.end(), p.owner(k)), 1) << "sender of cell " << k;
      }
    }
}

TEST(InteractionWeights, CountEachCellsCandidatePairsWithoutBoundaryPairs) {
  // Particles placed cell by cell; the estimate of a cell must be the ordered
  // pairs (p in the cell, q in a cell next to it or in it) that are not both
  // boundary, counted here particle by particle, with the y seam wrapped.
  for (const CellOrderKind kind : {CellOrderKind::sort_x, CellOrderKind::hilbert})
    for (const double period : {0.0, 3.0}) {
      GridFixture f(kind, 4, 3, 2, period);
      const std::size_t keys = f.order->num_keys();
      std::vector<double> fluid(keys, 0.0), boundary(keys, 0.0);
      struct P { int x, y, z; bool fluid; };
      std::vector<P> particles;
      for (int z = 0; z < 2; ++z)
        for (int y = 0; y < 3; ++y)
          for (int x = 0; x < 4; ++x) {
            const std::uint32_t k = f.order->key(x, y, z);
            fluid[k] = (x * 7 + y * 3 + z) % 4;
            boundary[k] = (x + 2 * y + 5 * z) % 3;
            for (int i = 0; i < fluid[k]; ++i) particles.push_back({x, y, z, true});
            for (int i = 0; i < boundary[k]; ++i) particles.push_back({x, y, z, false});
          }
      std::vector<double> w(keys, -1.0);
      interaction_weights(f.grid, *f.order, fluid, boundary, 0, static_cast<std::uint32_t>(keys), w);
      std::vector<double> brute(keys, 0.0);
      for (const P& p : particles)
        for (const P& q : particles) {
          int dy = std::abs(p.y - q.y);
          if (period > 0) dy = std::min(dy, 3 - dy);
          if (std::abs(p.x - q.x) > 1 || dy > 1 || std::abs(p.z - q.z) > 1 || (!p.fluid && !q.fluid)) continue;
          brute[f.order->key(p.x, p.y, p.z)] += 1;
        }
      for (std::size_t k = 0; k < keys; ++k)
        if (f.order->key_coords()[k] != CellOrder::kNoCellCoords) {
          EXPECT_EQ(w[k], brute[k]) << "key " << k << " order " << to_string(kind) << " period " << period;
        }
      // A sub-range writes only its own keys.
      std::vector<double> part(keys, -1.0);
      interaction_weights(f.grid, *f.order, fluid, boundary, 2, 5, part);
      for (std::size_t k = 0; k < keys; ++k) EXPECT_EQ(part[k], k >= 2 && k < 5 ? w[k] : -1.0) << "key " << k;
    }
}

TEST(Decomposition, PeriodicYWrapsTheHalo) {
  // Three ranks in y-slabs of a periodic 1x6x1 grid: rank 0 (y = 0, 1) and
  // rank 2 (y = 4, 5) touch across the seam.
  GridFixture f(CellOrderKind::sort_x, 1, 6, 1, 6.0);
  const KeyPartition p(std::vector<std::uint32_t>{0, 2, 4, 6});
  const Decomposition d(f.grid, *f.order, p);
  EXPECT_EQ(d.halo_cells(0), (std::vector<std::uint32_t>{2, 5}));
  EXPECT_EQ(d.halo_cells(2), (std::vector<std::uint32_t>{0, 3}));
  GridFixture open(CellOrderKind::sort_x, 1, 6, 1);
  const Decomposition d2(open.grid, *open.order, p);
  EXPECT_EQ(d2.halo_cells(0), (std::vector<std::uint32_t>{2}));
}

}  // namespace
}  // namespace sphnl
