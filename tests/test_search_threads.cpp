// Threads split the rows of the neighbour search, they do not change them:
// NeighbourSearch with 2 or 3 threads gives exactly the rows of one thread
// (same row order, same points, same entries in the same order) for every
// gridder, cell order and reorder choice, and the public API's rows are the
// same whatever its thread count. Huge pages change where the lists live,
// not what they hold.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <limits>
#include <stdexcept>
#include <string>
#include <random>
#include <vector>

#include "peers/clouds.hpp"
#include "sphnl/neighbours/coordinate_extent.hpp"
#include "sphnl/neighbours/neighbour_search.hpp"
#include "sphnl/neighbours/uninit_buffer.hpp"
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

// Clouds large enough that the build splits over threads too (bounding box,
// gridder B's counting sort): the rows stay those of one thread.
TEST(SearchThreads, SplitBuildGivesTheRowsOfOneThread) {
  const peers::Cloud cloud = peers::make_cloud(peers::CloudKind::random, peers::MemoryOrder::shuffled, 140000);
  for (GridderKind g : {GridderKind::B, GridderKind::D})
    for (bool reorder : {false, true}) {
      SearchOptions so{g, CellOrderKind::sort_x, reorder, 0, 1};
      ParticleSet ps;
      ps.resize(cloud.size());
      for (std::size_t i = 0; i < cloud.size(); ++i) {
        ps.x[i] = cloud.x[i];
        ps.y[i] = cloud.y[i];
        ps.z[i] = cloud.z[i];
      }
      const double radius = 2.6;  // unit density: about 74 neighbours
      const EngineRows one = engine_rows(ps, radius, so);
      for (int threads : {2, 4}) {
        so.threads = threads;
        const EngineRows many = engine_rows(ps, radius, so);
        EXPECT_EQ(many.point, one.point) << to_string(g) << " reorder " << reorder << " threads " << threads;
        EXPECT_TRUE(many.row == one.row) << to_string(g) << " reorder " << reorder << " threads " << threads;
      }
    }
}

// Minimum, maximum and finiteness against a plain loop, for every length up
// to past a few vector widths (the lanes' remainder), with a NaN or an
// infinity at every position, and extremes a multiplication by 0 keeps finite.
TEST(CoordinateExtent, MatchesAPlainLoopAndFindsEveryNonFiniteValue) {
  EXPECT_TRUE(coordinate_extent({}).finite);
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-1e3, 1e3);
  for (std::size_t n = 1; n <= 40; ++n) {
    std::vector<double> a(n);
    for (double& v : a) v = u(rng);
    a[n / 2] = n % 2 ? std::numeric_limits<double>::max() : -std::numeric_limits<double>::max();
    const CoordinateExtent e = coordinate_extent(a);
    EXPECT_TRUE(e.finite) << n;
    EXPECT_EQ(e.lo, *std::min_element(a.begin(), a.end())) << n;
    EXPECT_EQ(e.hi, *std::max_element(a.begin(), a.end())) << n;
    for (std::size_t bad = 0; bad < n; ++bad)
      for (double v : {std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity(),
                       -std::numeric_limits<double>::infinity()}) {
        std::vector<double> b = a;
        b[bad] = v;
        EXPECT_FALSE(coordinate_extent(b).finite) << n << " " << bad << " " << v;
      }
  }
}

// The three extents scanned in parts over threads are those of one scan,
// and a non-finite value in any part (the last thread's included) is seen.
TEST(CoordinateExtent, ExtentsSplitOverThreadsEqualOneScan) {
  const std::size_t n = 4 * 65536 + 11;  // four threads' worth, uneven
  std::mt19937_64 rng(8);
  std::uniform_real_distribution<double> u(-50.0, 50.0);
  std::vector<double> c[3];
  for (auto& a : c) {
    a.resize(n);
    for (double& v : a) v = u(rng);
  }
  c[1][n - 1] = 900.0;  // the largest y in the last thread's part
  c[2][3] = -900.0;     // the smallest z in the first
  for (int threads : {1, 2, 4}) {
    const CoordinateExtents e = coordinate_extents(c[0], c[1], c[2], threads);
    for (int d = 0; d < 3; ++d) {
      EXPECT_TRUE(e[d].finite) << threads << " " << d;
      EXPECT_EQ(e[d].lo, *std::min_element(c[d].begin(), c[d].end())) << threads << " " << d;
      EXPECT_EQ(e[d].hi, *std::max_element(c[d].begin(), c[d].end())) << threads << " " << d;
    }
    for (std::size_t at : {std::size_t{0}, n / 2, n - 1}) {
      std::vector<double> bad = c[0];
      bad[at] = std::numeric_limits<double>::quiet_NaN();
      const CoordinateExtents b = coordinate_extents(bad, c[1], c[2], threads);
      EXPECT_FALSE(b[0].finite) << threads << " " << at;
      EXPECT_TRUE(b[1].finite && b[2].finite) << threads << " " << at;
    }
  }
  const CoordinateExtents empty = coordinate_extents({}, {}, {}, 2);
  EXPECT_TRUE(empty[0].finite && empty[0].lo == 0 && empty[0].hi == 0);
}

// A non-finite coordinate anywhere in a cloud split over threads is found,
// and the message names the first such point.
TEST(SearchThreads, SplitBoundingBoxNamesTheFirstNonFinitePoint) {
  const std::size_t n = 300000;
  std::vector<double> x(n), y(n), z(n);
  for (std::size_t i = 0; i < n; ++i) {
    x[i] = static_cast<double>(i % 67);
    y[i] = static_cast<double>((i / 67) % 67);
    z[i] = static_cast<double>(i / (67 * 67));
  }
  const auto message = [&](int threads) {
    SearchOptions so{GridderKind::B, CellOrderKind::sort_x, true, 0, threads};
    NeighbourSearch search(so);
    NeighbourLists lists;
    try {
      search.run(x, y, z, 1.5, lists);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no exception");
  };
  for (int threads : {1, 2, 3}) {
    y[250001] = std::numeric_limits<double>::quiet_NaN();
    EXPECT_NE(message(threads).find("point 250001 has a non-finite"), std::string::npos) << threads;
    x[160000] = -std::numeric_limits<double>::infinity();
    EXPECT_NE(message(threads).find("point 160000 has a non-finite"), std::string::npos) << threads;
    z[n - 1] = std::numeric_limits<double>::infinity();
    x[160000] = 1;
    y[250001] = 1;
    EXPECT_NE(message(threads).find("point " + std::to_string(n - 1) + " has"), std::string::npos) << threads;
    z[n - 1] = 1;
    EXPECT_EQ(message(threads), "no exception") << threads;
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

TEST(HugePages, LargeBuffersStartAtStaggeredOffsetsInHugePages) {
  // Held at once, as a search holds its coordinate arrays: each starts on a
  // cache line, at one of the staggered offsets into a huge page, and no two
  // of kHugePageColours consecutive ones at the same offset.
  std::vector<void*> held;
  std::vector<std::uintptr_t> offsets;
  for (std::size_t k = 0; k < kHugePageColours; ++k) {
    const std::size_t bytes = k % 2 ? kHugePageMinBytes : 3 * kHugePageBytes + 1;
    void* p = allocate_buffer(bytes, true);
    const std::uintptr_t at = reinterpret_cast<std::uintptr_t>(p);
    EXPECT_EQ(at % kBufferAlignment, 0u) << k;
    const std::uintptr_t offset = at % kHugePageBytes;
    EXPECT_EQ(offset % kHugePageColourStep, 0u) << k;
    EXPECT_GE(offset, kHugePageColourStep) << k;
    EXPECT_LE(offset, kHugePageColours * kHugePageColourStep) << k;
    EXPECT_EQ(std::count(offsets.begin(), offsets.end(), offset), 0) << k;
    offsets.push_back(offset);
    static_cast<unsigned char*>(p)[0] = 1;
    static_cast<unsigned char*>(p)[bytes - 1] = 1;  // the whole size is writable
    held.push_back(p);
  }
  for (void* p : held) free_buffer(p);
  free_buffer(nullptr);  // nothing to free
  // Small buffers and huge_pages off: cache-line aligned, usable memory.
  for (bool huge : {false, true})
    for (std::size_t bytes : {std::size_t{0}, std::size_t{1000}, kHugePageMinBytes}) {
      if (huge && bytes == kHugePageMinBytes) continue;
      void* p = allocate_buffer(bytes, huge);
      ASSERT_NE(p, nullptr);
      EXPECT_EQ(reinterpret_cast<std::uintptr_t>(p) % kBufferAlignment, 0u) << bytes;
      if (bytes) static_cast<unsigned char*>(p)[bytes - 1] = 1;
      free_buffer(p);
    }
  // Sizes no object can have are refused before an allocator sees them (so
  // also under AddressSanitizer, which aborts on them).
  EXPECT_THROW(allocate_buffer(~std::size_t{0} / 2, true), std::bad_alloc);
  EXPECT_THROW(allocate_buffer(~std::size_t{0} - 1, false), std::bad_alloc);
}

namespace {
/// A fake sysfs tree: virtio devices given as (device id, feature bits).
std::string fake_sysfs(const std::string& name, const std::vector<std::pair<std::string, std::string>>& devices) {
  const std::filesystem::path root = std::filesystem::temp_directory_path() / ("sphnl_sysfs_" + name);
  std::filesystem::remove_all(root);
  for (std::size_t k = 0; k < devices.size(); ++k) {
    const std::filesystem::path d = root / "bus" / "virtio" / "devices" / ("virtio" + std::to_string(k));
    std::filesystem::create_directories(d);
    std::ofstream(d / "device") << devices[k].first << '\n';
    std::ofstream(d / "features") << devices[k].second << '\n';
  }
  return root.string();
}
}  // namespace

TEST(HugePages, FreePageReportingIsReadFromTheBalloonsFeatureBits) {
  // A balloon (0x0005) with bit 5 (VIRTIO_BALLOON_F_REPORTING) set, as on the
  // machine of docs/FINDINGS.md, "Huge pages on idle memory".
  const std::string reporting = "0110010100000000000000000000000010000000";
  EXPECT_TRUE(free_memory_reported_to_host(
      fake_sysfs("reporting", {{"0x0002", "0010001001"}, {"0x0005", reporting}}).c_str()));
  std::string without = reporting;
  without[5] = '0';
  EXPECT_FALSE(free_memory_reported_to_host(fake_sysfs("balloon_only", {{"0x0005", without}}).c_str()));
  EXPECT_FALSE(free_memory_reported_to_host(fake_sysfs("block_device", {{"0x0002", reporting}}).c_str()));
  EXPECT_FALSE(free_memory_reported_to_host(fake_sysfs("short", {{"0x0005", "01100"}}).c_str()));
  EXPECT_FALSE(free_memory_reported_to_host(fake_sysfs("none", {}).c_str()));
  EXPECT_FALSE(free_memory_reported_to_host("/nonexistent/sysfs"));
  for (const char* name : {"reporting", "balloon_only", "block_device", "short", "none"})
    std::filesystem::remove_all(std::filesystem::temp_directory_path() / (std::string("sphnl_sysfs_") + name));
  // The API's default follows the machine it runs on.
  EXPECT_EQ(huge_pages_by_default(), !free_memory_reported_to_host());
  EXPECT_EQ(Search::Options{}.huge_pages, huge_pages_by_default());
}

TEST(HugePages, BufferVectorSwitchesItsPagesAndKeepsItsValues) {
  BufferVector<std::uint64_t> v;
  EXPECT_FALSE(v.get_allocator().huge_pages);
  v.assign(10, 7);
  use_huge_pages(v, false);  // already base pages: kept as it is
  EXPECT_EQ(v.size(), 10u);
  use_huge_pages(v, true);  // switched: empty, the next allocation huge
  EXPECT_TRUE(v.empty());
  EXPECT_TRUE(v.get_allocator().huge_pages);
  v.resize(kHugePageMinBytes / sizeof(std::uint64_t));
  EXPECT_EQ(reinterpret_cast<std::uintptr_t>(v.data()) % kHugePageBytes % kHugePageColourStep, 0u);
  for (std::size_t k = 0; k < v.size(); ++k) v[k] = k;
  v.push_back(1);  // growth copies the values into the new buffer
  for (std::size_t k = 0; k + 1 < v.size(); ++k) ASSERT_EQ(v[k], k);
  BufferVector<std::uint64_t> w;
  w.swap(v);  // the flag travels with the memory
  EXPECT_TRUE(w.get_allocator().huge_pages);
  EXPECT_FALSE(v.get_allocator().huge_pages);
}

// 27 000 lattice points hold 2 million entries (8 MB): the lists, offsets and
// coordinates are above kHugePageMinBytes, so huge_pages on takes the huge
// path for them; the rows are those of base pages, on 1 and 2 threads, and
// a search and lists reused across the two choices stay exact.
TEST(HugePages, RowsDoNotDependOnThePages) {
  const peers::Cloud lattice = peers::make_cloud(peers::CloudKind::lattice, peers::MemoryOrder::shuffled, 27000);
  ParticleSet ps;
  ps.x = lattice.x;
  ps.y = lattice.y;
  ps.z = lattice.z;
  SearchOptions base;
  base.huge_pages = false;
  const EngineRows reference = engine_rows(ps, 2.6, base);
  EXPECT_GT(reference.row.size() * 70, kHugePageMinBytes / sizeof(std::uint32_t));
  for (int threads : {1, 2}) {
    SearchOptions huge;
    huge.threads = threads;
    huge.huge_pages = true;
    const EngineRows rows = engine_rows(ps, 2.6, huge);
    EXPECT_EQ(rows.point, reference.point) << threads;
    EXPECT_EQ(rows.row, reference.row) << threads;
  }
  NeighbourSearch first(base), second(SearchOptions{});
  NeighbourLists lists;
  for (NeighbourSearch* search : {&first, &second, &first}) {
    search->run(ps.x, ps.y, ps.z, 2.6, lists);
    ASSERT_EQ(lists.num_rows(), reference.row.size());
    for (std::size_t r = 0; r < lists.num_rows(); ++r) {
      const auto row = lists.row(r);
      ASSERT_EQ(std::vector<std::uint32_t>(row.begin(), row.end()), reference.row[r]) << r;
    }
  }
  // The public API's option reaches the engine: same rows either way.
  Search::Options options;
  options.huge_pages = false;
  Search a(2.6, options);
  options.huge_pages = true;
  Search b(2.6, options);
  a.build(ps.x, ps.y, ps.z);
  b.build(ps.x, ps.y, ps.z);
  const CompressedRows ra = a.rows(Rows::full), rb = b.rows(Rows::full);
  EXPECT_EQ(ra.offsets, rb.offsets);
  EXPECT_EQ(ra.indices, rb.indices);
}

}  // namespace
}  // namespace sphnl
