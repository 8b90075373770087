// The public API (sphnl/search.hpp) against the brute-force oracle: full and
// half rows in input order, for_each_pair, for_each_row, the cell-order permutation, update
// after a move, queries of a second point set, float and double input, and a
// clear exception for every bad input.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <span>
#include <string>
#include <vector>

#include "sphnl/search.hpp"
#include "support/clouds.hpp"
#include "support/oracle.hpp"

using namespace sphnl;
using namespace sphnl::test;

namespace {

struct Columns {
  std::vector<double> x, y, z;
};

Columns columns_of(const ParticleSet& ps) { return {ps.x, ps.y, ps.z}; }

/// The oracle's pairs of NeighbourSearch's rule (every distinct pair closer
/// than radius, coincident points included).
PairSet truth_of(const Columns& c, double radius) {
  std::vector<std::array<double, 3>> pts;
  for (std::size_t i = 0; i < c.x.size(); ++i) pts.push_back({c.x[i], c.y[i], c.z[i]});
  OracleRules rules;
  rules.min_r2 = -1;
  return brute_force_pairs(cloud_from(pts), radius * radius, rules);
}

/// Pairs of compressed rows; checks the rows' own invariants on the way
/// (n + 1 offsets from 0, rows sorted strictly ascending, no self entry).
PairSet pairs_of(const CompressedRows& rows, std::size_t n, Rows kind) {
  EXPECT_EQ(rows.offsets.size(), n + 1);
  EXPECT_EQ(rows.offsets.front(), 0);
  EXPECT_EQ(static_cast<std::size_t>(rows.offsets.back()), rows.indices.size());
  PairSet pairs;
  for (std::size_t i = 0; i < n; ++i) {
    for (std::int64_t k = rows.offsets[i]; k < rows.offsets[i + 1]; ++k) {
      const std::uint32_t j = rows.indices[k];
      const auto ii = static_cast<std::uint32_t>(i);
      EXPECT_NE(j, ii);
      if (k > rows.offsets[i]) {
        EXPECT_LT(rows.indices[k - 1], j) << "row " << i << " not sorted";
      }
      if (kind == Rows::half) {
        EXPECT_GT(j, ii) << "half row " << i << " holds a smaller index";
      }
      if (kind == Rows::half || ii < j) pairs.emplace_back(std::min(ii, j), std::max(ii, j));
    }
  }
  std::sort(pairs.begin(), pairs.end());
  return pairs;
}

void expect_search_matches(Search& s, const Columns& c, const PairSet& truth, const std::string& what) {
  const std::size_t n = c.x.size();
  ASSERT_EQ(s.size(), n) << what;
  const CompressedRows full = s.rows(Rows::full);
  EXPECT_EQ(full.indices.size(), 2 * truth.size()) << what;
  EXPECT_EQ(pairs_of(full, n, Rows::full), truth) << what;
  const CompressedRows half = s.rows(Rows::half);
  EXPECT_EQ(s.num_entries(Rows::half), truth.size()) << what;
  EXPECT_EQ(pairs_of(half, n, Rows::half), truth) << what;
  // full rows are symmetric: j in row i iff i in row j (pairs_of only reads i < j)
  PairSet lower;
  for (std::size_t i = 0; i < n; ++i)
    for (std::int64_t k = full.offsets[i]; k < full.offsets[i + 1]; ++k)
      if (full.indices[k] < i) lower.emplace_back(full.indices[k], static_cast<std::uint32_t>(i));
  std::sort(lower.begin(), lower.end());
  EXPECT_EQ(lower, truth) << what << ": full rows not symmetric";
  PairSet visited;
  s.for_each_pair([&](std::uint32_t i, std::uint32_t j) {
    EXPECT_LT(i, j);
    visited.emplace_back(i, j);
  });
  std::sort(visited.begin(), visited.end());
  EXPECT_EQ(visited, truth) << what << ": for_each_pair";
  // for_each_row: every point once, with row i of the full rows in some order
  std::vector<int> seen(n, 0);
  s.for_each_row([&](std::uint32_t i, std::span<const std::uint32_t> row) {
    ASSERT_LT(i, n) << what;
    ++seen[i];
    std::vector<std::uint32_t> sorted(row.begin(), row.end());
    std::sort(sorted.begin(), sorted.end());
    const std::vector<std::uint32_t> want(full.indices.begin() + full.offsets[i], full.indices.begin() + full.offsets[i + 1]);
    EXPECT_EQ(sorted, want) << what << ": for_each_row, point " << i;
  });
  EXPECT_EQ(std::count(seen.begin(), seen.end(), 1), static_cast<std::ptrdiff_t>(n)) << what << ": for_each_row visits each point once";
}

std::vector<Search::Options> all_options() {
  std::vector<Search::Options> out;
  for (GridderKind g : {GridderKind::A, GridderKind::B, GridderKind::C, GridderKind::D})
    for (CellOrderKind o : {CellOrderKind::sort_x, CellOrderKind::hilbert})
      for (bool reorder : {true, false}) {
        Search::Options opt;
        opt.gridder = g;
        opt.cell_order = o;
        opt.reorder = reorder;
        out.push_back(opt);
      }
  return out;
}

std::string name_of(const Search::Options& o) {
  return std::string(to_string(o.gridder)) + "/" + to_string(o.cell_order) + (o.reorder ? "/reorder" : "/no-reorder");
}

}  // namespace

TEST(SearchApi, MatchesBruteForceOnEveryCloudAndOption) {
  for (const Cloud& cloud : test_clouds()) {
    const Columns c = columns_of(cloud.ps);
    const PairSet truth = truth_of(c, cloud.radius);
    ASSERT_GT(truth.size(), c.x.size()) << cloud.name;
    for (const Search::Options& opt : all_options()) {
      Search s(cloud.radius, opt);
      s.build(c.x, c.y, c.z);
      expect_search_matches(s, c, truth, std::string(cloud.name) + " " + name_of(opt));
    }
  }
}

TEST(SearchApi, FloatInputIsWidenedToTheSameAnswer) {
  for (const Cloud& cloud : test_clouds()) {
    std::vector<float> fx(cloud.ps.x.begin(), cloud.ps.x.end()), fy(cloud.ps.y.begin(), cloud.ps.y.end()),
        fz(cloud.ps.z.begin(), cloud.ps.z.end());
    // the oracle sees exactly the doubles the floats widen to
    const Columns widened{{fx.begin(), fx.end()}, {fy.begin(), fy.end()}, {fz.begin(), fz.end()}};
    const PairSet truth = truth_of(widened, cloud.radius);
    Search s(cloud.radius);
    s.build(std::span<const float>(fx), std::span<const float>(fy), std::span<const float>(fz));
    expect_search_matches(s, widened, truth, std::string(cloud.name) + " float");
    std::vector<float> xyz;
    for (std::size_t i = 0; i < fx.size(); ++i) xyz.insert(xyz.end(), {fx[i], fy[i], fz[i]});
    Search si(cloud.radius);
    si.build_interleaved(std::span<const float>(xyz));
    expect_search_matches(si, widened, truth, std::string(cloud.name) + " float interleaved");
  }
}

TEST(SearchApi, InterleavedDoubleEqualsColumns) {
  const Cloud cloud = test_clouds()[0];
  const Columns c = columns_of(cloud.ps);
  std::vector<double> xyz;
  for (std::size_t i = 0; i < c.x.size(); ++i) xyz.insert(xyz.end(), {c.x[i], c.y[i], c.z[i]});
  Search s(cloud.radius);
  s.build_interleaved(xyz);
  expect_search_matches(s, c, truth_of(c, cloud.radius), "interleaved");
}

TEST(SearchApi, DegenerateClouds) {
  // all points identical: every pair is a neighbour (distance 0 < R)
  Columns same{std::vector<double>(40, 1.5), std::vector<double>(40, -2.0), std::vector<double>(40, 0.25)};
  Search s(0.1);
  s.build(same.x, same.y, same.z);
  EXPECT_EQ(s.num_entries(Rows::full), 40u * 39u);
  expect_search_matches(s, same, truth_of(same, 0.1), "identical");
  // one point: one empty row
  Columns one{{3.0}, {4.0}, {5.0}};
  s.build(one.x, one.y, one.z);
  const CompressedRows r1 = s.rows(Rows::full);
  EXPECT_EQ(r1.offsets, (std::vector<std::int64_t>{0, 0}));
  EXPECT_TRUE(r1.indices.empty());
  EXPECT_EQ(s.cell_order().size(), 1u);
  // empty set: offsets {0}, no pairs, queries find nothing
  const std::vector<double> none;
  s.build(none, none, none);
  EXPECT_EQ(s.size(), 0u);
  EXPECT_EQ(s.rows(Rows::full).offsets, (std::vector<std::int64_t>{0}));
  EXPECT_EQ(s.rows(Rows::half).offsets, (std::vector<std::int64_t>{0}));
  int calls = 0;
  s.for_each_pair([&](std::uint32_t, std::uint32_t) { ++calls; });
  EXPECT_EQ(calls, 0);
  const std::vector<double> q{0.0};
  EXPECT_EQ(s.query(q, q, q).offsets, (std::vector<std::int64_t>{0, 0}));
}

TEST(SearchApi, UpdateAfterAMoveMatchesAFreshSearch) {
  Cloud cloud = test_clouds()[1];  // clustered
  Columns c = columns_of(cloud.ps);
  Search s(cloud.radius);
  s.build(c.x, c.y, c.z);
  std::mt19937_64 rng(7);
  std::normal_distribution<double> step(0.0, 0.05);
  for (int round = 0; round < 3; ++round) {
    for (std::size_t i = 0; i < c.x.size(); ++i) {
      c.x[i] += step(rng);
      c.y[i] += step(rng);
      c.z[i] += step(rng);
    }
    s.update(c.x, c.y, c.z);
    expect_search_matches(s, c, truth_of(c, cloud.radius), "after move " + std::to_string(round));
  }
  const std::vector<double> shorter(c.x.begin(), c.x.end() - 1);
  EXPECT_THROW(s.update(shorter, shorter, shorter), std::invalid_argument);
}

TEST(SearchApi, CellOrderPermutationSortsUserFields) {
  const Cloud cloud = test_clouds()[0];
  Columns c = columns_of(cloud.ps);
  Search s(cloud.radius);
  s.build(c.x, c.y, c.z);
  const std::span<const std::uint32_t> order = s.cell_order();
  ASSERT_EQ(order.size(), c.x.size());
  std::vector<std::uint32_t> seen(order.begin(), order.end());
  std::sort(seen.begin(), seen.end());
  for (std::size_t k = 0; k < seen.size(); ++k) ASSERT_EQ(seen[k], k) << "not a permutation";
  std::vector<double> id(c.x.size());
  for (std::size_t i = 0; i < id.size(); ++i) id[i] = static_cast<double>(i);
  s.apply_cell_order(id);
  for (std::size_t k = 0; k < id.size(); ++k) ASSERT_EQ(id[k], order[k]);
  // sorted arrays give the same pairs, renumbered; and they are in cell order:
  // neighbours sit close in memory (the point of z_sort + sort_field)
  Columns sorted = c;
  s.apply_cell_order(sorted.x);
  s.apply_cell_order(sorted.y);
  s.apply_cell_order(sorted.z);
  PairSet renamed;
  for (const auto& [i, j] : truth_of(sorted, cloud.radius)) {
    const std::uint32_t a = order[i], b = order[j];
    renamed.emplace_back(std::min(a, b), std::max(a, b));
  }
  std::sort(renamed.begin(), renamed.end());
  EXPECT_EQ(renamed, truth_of(c, cloud.radius));
  auto mean_gap = [&](const Columns& cols) {
    Search t(cloud.radius);
    t.build(cols.x, cols.y, cols.z);
    double sum = 0, count = 0;
    t.for_each_pair([&](std::uint32_t i, std::uint32_t j) { sum += j - i, count += 1; });
    return sum / count;
  };
  EXPECT_LT(mean_gap(sorted), 0.25 * mean_gap(c));
  std::vector<double> wrong(3);
  EXPECT_THROW(s.apply_cell_order(wrong), std::invalid_argument);
}

TEST(SearchApi, QueryOfASecondPointSet) {
  for (const Cloud& cloud : test_clouds()) {
    const Columns c = columns_of(cloud.ps);
    // queries inside, on top of built points, and far outside the cloud
    std::mt19937_64 rng(99);
    std::uniform_real_distribution<double> u(-4.0, 6.0);
    Columns q;
    for (int k = 0; k < 300; ++k) {
      q.x.push_back(u(rng));
      q.y.push_back(u(rng));
      q.z.push_back(k % 3 == 0 ? 0.125 : u(rng));
    }
    for (std::size_t i = 0; i < c.x.size(); i += 97) {
      q.x.push_back(c.x[i]);
      q.y.push_back(c.y[i]);
      q.z.push_back(c.z[i]);
    }
    q.x.push_back(1e6), q.y.push_back(0), q.z.push_back(0);
    const double r2 = cloud.radius * cloud.radius;
    for (const Search::Options& opt : all_options()) {
      Search s(cloud.radius, opt);
      s.build(c.x, c.y, c.z);
      const CompressedRows rows = s.query(q.x, q.y, q.z);
      ASSERT_EQ(rows.offsets.size(), q.x.size() + 1);
      std::size_t total = 0;
      for (std::size_t k = 0; k < q.x.size(); ++k) {
        std::vector<std::uint32_t> expect;
        for (std::size_t j = 0; j < c.x.size(); ++j)
          if (distance2(c.x[j] - q.x[k], c.y[j] - q.y[k], c.z[j] - q.z[k]) < r2) expect.push_back(static_cast<std::uint32_t>(j));
        const std::vector<std::uint32_t> got(rows.indices.begin() + rows.offsets[k], rows.indices.begin() + rows.offsets[k + 1]);
        ASSERT_EQ(got, expect) << cloud.name << " " << name_of(opt) << " query " << k;
        total += expect.size();
      }
      EXPECT_GT(total, q.x.size()) << cloud.name;
    }
  }
  Search fresh(1.0);
  const std::vector<double> p{0.0};
  EXPECT_THROW(fresh.query(p, p, p), std::logic_error);
}

// Double input with reorder on is not copied (the engine keeps the points in
// cell order); every option must still answer queries about the cloud as it
// was built, after the caller has overwritten or freed its arrays.
TEST(SearchApi, QueryAnswersForTheBuiltCloudAfterTheCallersArraysChange) {
  const Cloud cloud = test_clouds().front();
  const Columns c = columns_of(cloud.ps);
  const double r2 = cloud.radius * cloud.radius;
  for (const Search::Options& opt : all_options()) {
    Search s(cloud.radius, opt);
    {
      Columns scratch = c;
      s.build(scratch.x, scratch.y, scratch.z);
      std::fill(scratch.x.begin(), scratch.x.end(), std::numeric_limits<double>::quiet_NaN());
      std::fill(scratch.y.begin(), scratch.y.end(), 1e9);
    }  // and freed
    ASSERT_EQ(s.size(), c.x.size());
    for (std::size_t k = 0; k < c.x.size(); k += 53) {
      const std::vector<double> qx{c.x[k]}, qy{c.y[k]}, qz{c.z[k]};
      const CompressedRows rows = s.query(qx, qy, qz);
      std::vector<std::uint32_t> expect;
      for (std::size_t j = 0; j < c.x.size(); ++j)
        if (distance2(c.x[j] - qx[0], c.y[j] - qy[0], c.z[j] - qz[0]) < r2) expect.push_back(static_cast<std::uint32_t>(j));
      ASSERT_EQ(rows.indices, expect) << cloud.name << " " << name_of(opt) << " point " << k;
    }
  }
}

namespace {
template <class Fn>
std::string message_of(Fn fn) {
  try {
    fn();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "(no exception)";
}
}  // namespace

TEST(SearchApi, BadInputsThrowClearErrors) {
  const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
  EXPECT_THROW(Search{0.0}, std::invalid_argument);
  EXPECT_THROW(Search{-1.0}, std::invalid_argument);
  EXPECT_THROW(Search{nan}, std::invalid_argument);
  EXPECT_THROW(Search{inf}, std::invalid_argument);
  EXPECT_NE(message_of([&] { Search s(-1.0); }).find("radius"), std::string::npos);
  Search::Options threaded;
  threaded.threads = 0;  // at least one thread
  EXPECT_NE(message_of([&] { Search s(1.0, threaded); }).find("threads"), std::string::npos);

  Search s(1.0);
  std::vector<double> x{0, 1, 2}, y{0, 1, 2}, z{0, 1};
  EXPECT_THROW(s.build(x, y, z), std::invalid_argument);
  EXPECT_NE(message_of([&] { s.build(x, y, z); }).find("same length"), std::string::npos);
  z.push_back(nan);
  EXPECT_NE(message_of([&] { s.build(x, y, z); }).find("z[2] is NaN"), std::string::npos);
  z[2] = -inf;
  EXPECT_NE(message_of([&] { s.build(x, y, z); }).find("z[2] is infinite"), std::string::npos);
  z[2] = 1.7e308;
  x[0] = -1.7e308;
  z[0] = -1.7e308;
  EXPECT_NE(message_of([&] { s.build(x, y, z); }).find("span more than the largest double"), std::string::npos);
  const std::vector<float> f4(4, 0.f);
  EXPECT_NE(message_of([&] { s.build_interleaved(std::span<const float>(f4)); }).find("multiple of 3"), std::string::npos);
  const std::vector<float> fnan{0.f, std::numeric_limits<float>::quiet_NaN(), 0.f};
  EXPECT_NE(message_of([&] { s.build(std::span<const float>(fnan), std::span<const float>(fnan), std::span<const float>(fnan)); })
                .find("x[1] is NaN"),
            std::string::npos);

  // a failed build leaves no stale results behind
  EXPECT_EQ(s.size(), 0u);
  const std::vector<double> ok{0.0, 0.5};
  s.build(ok, ok, ok);
  const std::vector<double> qbad{nan};
  EXPECT_THROW(s.query(qbad, qbad, qbad), std::invalid_argument);
  EXPECT_THROW(s.query(ok, ok, qbad), std::invalid_argument);
  std::vector<std::int64_t> offsets(2);
  std::vector<std::uint32_t> indices(2);
  EXPECT_THROW(s.rows_into(Rows::full, offsets, indices), std::invalid_argument);  // needs 3 offsets
  offsets.resize(3);
  indices.resize(1);
  EXPECT_THROW(s.rows_into(Rows::full, offsets, indices), std::invalid_argument);  // needs 2 entries
  indices.resize(2);
  s.rows_into(Rows::full, offsets, indices);
  EXPECT_EQ(offsets, (std::vector<std::int64_t>{0, 1, 2}));
  EXPECT_EQ(indices, (std::vector<std::uint32_t>{1, 0}));
}

TEST(SearchApi, MoreCellsAlongAnAxisThanCoordinatesHoldIsRefused) {
  // A line of 2 200 000 points 1 apart with radius 1.01: 2.18 million cells
  // along x, past the 2^21 = 2 097 152 cell coordinates per axis. Lists would silently lose pairs;
  // the API refuses them with std::length_error instead.
  const std::size_t n = 2200000;
  std::vector<double> x(n), zero(n, 0.0);
  for (std::size_t i = 0; i < n; ++i) x[i] = static_cast<double>(i);
  Search s(1.01);
  EXPECT_NE(message_of([&] { s.build(x, zero, zero); }).find("cells of side"), std::string::npos);
  EXPECT_THROW(s.build(x, zero, zero), std::length_error);
  EXPECT_EQ(s.size(), 0u);
  // a million fewer points fit: every inner point has its two neighbours
  x.resize(n - 1000000);
  zero.resize(x.size());
  s.build(x, zero, zero);
  EXPECT_EQ(s.num_entries(Rows::full), 2 * (x.size() - 1));
}
