// The `search` benchmark's peer and its safeguard: the pair-set checksum
// refuses a deliberately wrong pair set, the benchmark clouds are what they
// claim, and the nanoflann row finds exactly the brute-force pairs (strictly
// closer than R, also where many pairs lie at exactly r = R).
#include <gtest/gtest.h>

#include <algorithm>
#include <stdexcept>
#include <string>

#include "peers/clouds.hpp"
#include "sphnl/neighbours/neighbour_search.hpp"
#include "sphnl/neighbours/pair_checksum.hpp"
#include "support/clouds.hpp"
#include "support/oracle.hpp"
#ifdef SPHNL_HAVE_NANOFLANN
#include "peers/nanoflann_lists.hpp"
#endif

namespace sphnl {
namespace {

using test::PairSet;

ParticleSet as_particles(const peers::Cloud& c) {
  std::vector<std::array<double, 3>> pts;
  for (std::size_t i = 0; i < c.size(); ++i) pts.push_back({c.x[i], c.y[i], c.z[i]});
  return test::cloud_from(pts);
}

PairChecksum checksum_of_pairs(const PairSet& pairs) {
  PairChecksum c;
  for (const auto& [i, j] : pairs) {  // full lists: both rows
    c.add(i, j);
    c.add(j, i);
  }
  return c;
}

TEST(PairChecksum, OrderOfRowsAndEntriesDoesNotMatter) {
  PairChecksum a, b;
  a.add(0, 1);
  a.add(1, 0);
  a.add(2, 7);
  b.add(2, 7);
  b.add(1, 0);
  b.add(0, 1);
  EXPECT_EQ(a, b);
  PairChecksum swapped;  // (i, j) and (j, i) are different entries
  swapped.add(1, 0);
  swapped.add(0, 1);
  swapped.add(7, 2);
  EXPECT_NE(a, swapped);
}

TEST(PairChecksum, ADeliberatelyWrongPairSetIsRefusedNamingBothImplementations) {
  const PairSet right = {{0, 1}, {0, 2}, {3, 4}};
  PairSet missing = right, moved = right;
  missing.pop_back();
  moved.back() = {3, 5};
  const PairChecksum reference = checksum_of_pairs(right);
  EXPECT_NO_THROW(require_same_pairs("peer", checksum_of_pairs(right), "sphnl", reference));
  for (const PairSet& wrong : {missing, moved}) {
    try {
      require_same_pairs("nanoflann", checksum_of_pairs(wrong), "sphnl", reference);
      ADD_FAILURE() << "a wrong pair set was accepted";
    } catch (const std::runtime_error& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("nanoflann"), std::string::npos) << what;
      EXPECT_NE(what.find("sphnl"), std::string::npos) << what;
      EXPECT_NE(what.find("differs"), std::string::npos) << what;
    }
  }
}

TEST(BenchClouds, LatticeRandomAndShuffledHaveTheSamePointsAndDensity) {
  const peers::Cloud lattice = peers::make_cloud(peers::CloudKind::lattice, peers::MemoryOrder::generated, 1000);
  ASSERT_EQ(lattice.size(), 1000u);  // 10^3
  EXPECT_EQ(lattice.x[1], 1.0);
  EXPECT_EQ(lattice.y[10], 1.0);
  EXPECT_EQ(lattice.z[100], 1.0);
  const peers::Cloud random = peers::make_cloud(peers::CloudKind::random, peers::MemoryOrder::generated, 1000);
  ASSERT_EQ(random.size(), 1000u);
  for (std::size_t i = 0; i < random.size(); ++i)
    for (double v : {random.x[i], random.y[i], random.z[i]}) {
      ASSERT_GE(v, 0.0);
      ASSERT_LT(v, 10.0);
    }
  for (const peers::Cloud* c : {&lattice, &random}) {
    const peers::CloudKind kind = c == &lattice ? peers::CloudKind::lattice : peers::CloudKind::random;
    const peers::Cloud shuffled = peers::make_cloud(kind, peers::MemoryOrder::shuffled, 1000);
    auto sorted_points = [](const peers::Cloud& p) {
      std::vector<std::array<double, 3>> v;
      for (std::size_t i = 0; i < p.size(); ++i) v.push_back({p.x[i], p.y[i], p.z[i]});
      std::sort(v.begin(), v.end());
      return v;
    };
    EXPECT_NE(shuffled.x, c->x);  // another memory order ...
    EXPECT_EQ(sorted_points(shuffled), sorted_points(*c));  // ... of the same points
  }
}

#ifdef SPHNL_HAVE_NANOFLANN
PairSet pairs_of(const peers::PeerLists& lists) {
  PairSet pairs, lower;
  for (std::size_t i = 0; i + 1 < lists.offsets.size(); ++i)
    for (std::uint64_t k = lists.offsets[i]; k < lists.offsets[i + 1]; ++k) {
      const std::uint32_t j = lists.entries[k], a = static_cast<std::uint32_t>(i);
      (a < j ? pairs : lower).emplace_back(std::min(a, j), std::max(a, j));
    }
  std::sort(pairs.begin(), pairs.end());
  std::sort(lower.begin(), lower.end());
  EXPECT_EQ(pairs, lower) << "nanoflann's lists are not symmetric";
  return pairs;
}

TEST(NanoflannPeer, FindsExactlyTheBruteForcePairs) {
  std::vector<std::pair<std::string, ParticleSet>> clouds;
  std::vector<double> radii;
  for (auto kind : {peers::CloudKind::lattice, peers::CloudKind::random})
    for (auto order : {peers::MemoryOrder::generated, peers::MemoryOrder::shuffled}) {
      clouds.emplace_back(std::string(kind == peers::CloudKind::lattice ? "lattice" : "random") +
                              (order == peers::MemoryOrder::shuffled ? "/shuffled" : ""),
                          as_particles(peers::make_cloud(kind, order, 1728)));
      radii.push_back(2.6);
    }
  for (auto& c : test::test_clouds()) {  // cell_boundaries: many pairs at exactly r = R
    clouds.emplace_back(c.name, c.ps);
    radii.push_back(c.radius);
  }
  for (std::size_t k = 0; k < clouds.size(); ++k) {
    const ParticleSet& ps = clouds[k].second;
    const PairSet expected = test::brute_force_pairs(ps, radii[k] * radii[k], test::OracleRules{-1.0, 0});
    ASSERT_FALSE(expected.empty()) << clouds[k].first;
    for (int threads : {1, 2, 3}) {
      peers::PeerLists lists;
      peers::nanoflann_full_lists(ps.x, ps.y, ps.z, radii[k], threads, lists);
      EXPECT_EQ(pairs_of(lists), expected) << clouds[k].first << ", " << threads << " threads";
      // and the benchmark's check agrees with sphnl's engine on it
      NeighbourSearch engine;
      NeighbourLists mine;
      engine.run(ps.x, ps.y, ps.z, radii[k], mine);
      PairChecksum sphnl;
      for (std::size_t r = 0; r < mine.num_rows(); ++r) {
        const auto row = mine.row(r);
        sphnl.add_row(mine.point(r), row.data(), row.size());
      }
      EXPECT_NO_THROW(require_same_pairs("nanoflann", lists.checksum(), "sphnl", sphnl)) << clouds[k].first;
    }
  }
}
#else
TEST(NanoflannPeer, FindsExactlyTheBruteForcePairs) {
  GTEST_SKIP() << "nanoflann not found at configure time (apt-get install libnanoflann-dev)";
}
#endif

}  // namespace
}  // namespace sphnl
