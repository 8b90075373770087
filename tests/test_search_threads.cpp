// Threads split the rows of the neighbour search, they do not change them:
// NeighbourSearch with 2 or 3 threads gives exactly the rows of one thread
// (same row order, same points, same entries in the same order) for every
// gridder, cell order and reorder choice, and the public API's rows are the
// same whatever its thread count.
#include <gtest/gtest.h>

#include <random>
#include <vector>

#include "peers/clouds.hpp"
#include "sphnl/neighbours/neighbour_search.hpp"
#include "sphnl/search.hpp"
#include "support/clouds.hpp"

namespace sphnl {
namespace {

struct EngineRows {
  std::vector<std::uint32_t> point;
  std::vector<std::vector<std::uint32_t>> row;
};

EngineRows engine_rows(const ParticleSet& ps, double radius, SearchOptions so, NeighbourSearch* reuse = nullptr) {
  NeighbourSearch fresh(so);
  NeighbourSearch& search = reuse ? *reuse : fresh;
  NeighbourLists lists;
  search.run(ps.x, ps.y, ps.z, radius, lists);
  EngineRows out;
  for (std::size_t r = 0; r < lists.num_rows(); ++r) {
    out.point.push_back(lists.point(r));
    const auto row = lists.row(r);
    out.row.emplace_back(row.begin(), row.end());
  }
  std::uint64_t total = 0;
  for (const auto& r : out.row) total += r.size();
  EXPECT_EQ(total, lists.num_entries());
  return out;
}

std::vector<test::Cloud> clouds() {
  std::vector<test::Cloud> c = test::test_clouds();
  const peers::Cloud lattice = peers::make_cloud(peers::CloudKind::lattice, peers::MemoryOrder::shuffled, 4096);
  std::vector<std::array<double, 3>> pts;
  for (std::size_t i = 0; i < lattice.size(); ++i) pts.push_back({lattice.x[i], lattice.y[i], lattice.z[i]});
  c.push_back({"lattice_shuffled", test::cloud_from(pts), 2.6});
  pts.assign(5, {1.0, 2.0, 3.0});  // fewer points than threads' share: empty ranges
  c.push_back({"five_coincident", test::cloud_from(pts), 0.5});
  return c;
}

TEST(SearchThreads, EngineRowsAreThoseOfOneThread) {
  for (const auto& cloud : clouds())
    for (GridderKind g : {GridderKind::B, GridderKind::C, GridderKind::D})
      for (CellOrderKind o : {CellOrderKind::sort_x, CellOrderKind::hilbert})
        for (bool reorder : {false, true}) {
          SearchOptions so{g, o, reorder, 0, 1};
          const EngineRows one = engine_rows(cloud.ps, cloud.radius, so);
          for (int threads : {2, 3}) {
            so.threads = threads;
            const EngineRows many = engine_rows(cloud.ps, cloud.radius, so);
            EXPECT_EQ(many.point, one.point) << cloud.name << " " << to_string(g) << " " << to_string(o) << " reorder "
                                             << reorder << " threads " << threads;
            EXPECT_EQ(many.row, one.row) << cloud.name << " " << to_string(g) << " " << to_string(o) << " reorder "
                                         << reorder << " threads " << threads;
          }
        }
}

// The sweep times are parts of the search time: the longest sweep lies
// within it, and the summed sweeps within threads times the longest.
TEST(SearchThreads, SweepTimesLieWithinTheSearch) {
  const peers::Cloud lattice = peers::make_cloud(peers::CloudKind::lattice, peers::MemoryOrder::generated, 27000);
  for (int threads : {1, 2, 3}) {
    SearchOptions so;
    so.threads = threads;
    NeighbourSearch search(so);
    NeighbourLists lists;
    search.run(lattice.x, lattice.y, lattice.z, 2.6, lists);
    const SearchTimes& t = search.times();
    EXPECT_GT(t.sweep_max, 0.0) << threads;
    EXPECT_LE(t.sweep_max, t.search) << threads;
    EXPECT_LE(t.sweep_sum, threads * t.sweep_max * (1 + 1e-12)) << threads;
    EXPECT_GE(t.sweep_sum, t.sweep_max) << threads;
  }
}

TEST(SearchThreads, ReusedSearchAndListsStayExact) {
  // The second run reuses the segments of the first (another cloud, another
  // split of the rows): still the one-thread rows.
  const auto all = clouds();
  SearchOptions so;
  so.threads = 2;
  NeighbourSearch reused(so);
  for (const auto& cloud : all) {
    const EngineRows one = engine_rows(cloud.ps, cloud.radius, SearchOptions{});
    const EngineRows two = engine_rows(cloud.ps, cloud.radius, so, &reused);
    EXPECT_EQ(two.point, one.point) << cloud.name;
    EXPECT_EQ(two.row, one.row) << cloud.name;
  }
}

TEST(SearchThreads, PublicApiRowsDoNotDependOnThreads) {
  for (const auto& cloud : clouds()) {
    Search::Options options;
    Search one(cloud.radius, options);
    one.build(cloud.ps.x, cloud.ps.y, cloud.ps.z);
    // rows() splits the transpose's sources over the threads: every count
    // of threads gives the one-thread rows, also more threads than points.
    for (int threads : {2, 3, 7}) {
      options.threads = threads;
      Search two(cloud.radius, options);
      two.build(cloud.ps.x, cloud.ps.y, cloud.ps.z);
      for (sphnl::Rows kind : {sphnl::Rows::full, sphnl::Rows::half}) {
        const CompressedRows a = one.rows(kind), b = two.rows(kind);
        EXPECT_EQ(a.offsets, b.offsets) << cloud.name << " threads " << threads;
        EXPECT_EQ(a.indices, b.indices) << cloud.name << " threads " << threads;
      }
    }
  }
}

}  // namespace
}  // namespace sphnl
