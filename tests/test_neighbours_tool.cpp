// `sphnl neighbours` (neighbours_main): CSV input is validated line by line,
// counts and pairs match brute force for any coordinates (negative, far from
// the origin, all on one plane) and any gridder / cell order / reorder, and
// outputs appear only complete.
#include <gtest/gtest.h>

#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "sphnl/neighbours/neighbour_search.hpp"
#include "neighbours_tool.hpp"

using namespace sphnl;
namespace fs = std::filesystem;

namespace {

class ToolTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("sphnl_neighbours_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::string write(const std::string& name, const std::string& text) {
    const std::string p = (dir_ / name).string();
    std::ofstream(p, std::ios::binary) << text;
    return p;
  }
  static std::string read(const std::string& path) {
    std::ifstream in(path);
    std::ostringstream s;
    s << in.rdbuf();
    return s.str();
  }
  /// Runs the tool; returns the exit code, stderr in `err`.
  int run(std::vector<std::string> args, std::string* err = nullptr) {
    args.insert(args.begin(), "neighbours");
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    ::testing::internal::CaptureStderr();
    ::testing::internal::CaptureStdout();
    const int rc = neighbours_main(static_cast<int>(argv.size()), argv.data());
    stdout_ = ::testing::internal::GetCapturedStdout();
    const std::string e = ::testing::internal::GetCapturedStderr();
    if (err) *err = e;
    return rc;
  }
  std::string rejected(const std::string& csv) {
    const std::string in = write("bad.csv", csv);
    std::string err;
    EXPECT_EQ(run({"--input", in, "--radius", "1", "--out", (dir_ / "c.csv").string()}, &err), 1) << csv;
    EXPECT_FALSE(fs::exists(dir_ / "c.csv")) << "no output for rejected input";
    return err;
  }

  fs::path dir_;
  std::string stdout_;
};

std::string to_csv(const PointCloud& pc, bool header) {
  std::ostringstream s;
  s.precision(17);
  if (header) s << "x,y,z\n";
  for (std::size_t i = 0; i < pc.size(); ++i) s << pc.x[i] << "," << pc.y[i] << "," << pc.z[i] << "\n";
  return s.str();
}

struct Expected {
  std::string counts, pairs;
};

/// The files the tool must write, computed by brute force.
Expected brute_force_files(const PointCloud& pc, double radius) {
  std::vector<std::uint32_t> count(pc.size(), 0);
  std::ostringstream pairs;
  pairs << "i,j\n";
  for (std::size_t i = 0; i < pc.size(); ++i)
    for (std::size_t j = i + 1; j < pc.size(); ++j)
      if (distance2(pc.x[i] - pc.x[j], pc.y[i] - pc.y[j], pc.z[i] - pc.z[j]) < radius * radius) {
        ++count[i];
        ++count[j];
        pairs << i << "," << j << "\n";
      }
  std::ostringstream counts;
  counts << "index,count\n";
  for (std::size_t i = 0; i < pc.size(); ++i) counts << i << "," << count[i] << "\n";
  return {counts.str(), pairs.str()};
}

PointCloud random_cloud(std::size_t n, double lo, double hi, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(lo, hi);
  PointCloud pc;
  for (std::size_t i = 0; i < n; ++i) {
    pc.x.push_back(u(rng));
    pc.y.push_back(u(rng));
    pc.z.push_back(u(rng));
  }
  return pc;
}

}  // namespace

TEST_F(ToolTest, RejectsMalformedInputNamingTheLine) {
  std::string err = rejected("x,y,z\n1,2,3\n4,abc,6\n");
  EXPECT_NE(err.find("bad.csv:3:"), std::string::npos) << err;
  EXPECT_NE(err.find("'abc' is not a number"), std::string::npos) << err;
  err = rejected("1,2,3\n4,5\n");
  EXPECT_NE(err.find(":2: expected 3 columns (x,y,z), found 2"), std::string::npos) << err;
  err = rejected("1,2,3\n4,5,6,7\n");
  EXPECT_NE(err.find(":2: expected 3 columns"), std::string::npos) << err;
  err = rejected("1,2,3\n\n1,nan,3\n");
  EXPECT_NE(err.find(":3:"), std::string::npos) << err;
  EXPECT_NE(err.find("not finite"), std::string::npos) << err;
  err = rejected("1,2,inf\n");
  EXPECT_NE(err.find(":1:"), std::string::npos) << err;
  err = rejected("");
  EXPECT_NE(err.find("no points"), std::string::npos) << err;
  err = rejected("x,y,z\n");
  EXPECT_NE(err.find("no points"), std::string::npos) << err;
  err = rejected("1,2,3\nx,y,z\n");  // a header only on the first line
  EXPECT_NE(err.find(":2:"), std::string::npos) << err;
  err = rejected("1,2,3\n1,,3\n");
  EXPECT_NE(err.find(":2: field 2"), std::string::npos) << err;
}

TEST_F(ToolTest, ParsesHeaderlessCrlfAndSpacedInput) {
  const PointCloud pc = parse_points_csv("1, 2 ,3\r\n\r\n-4.5e-1,+5,6\n", "t");
  ASSERT_EQ(pc.size(), 2u);
  EXPECT_EQ(pc.x[1], -0.45);
  EXPECT_EQ(pc.y[1], 5.0);
  EXPECT_EQ(pc.z[0], 3.0);
}

TEST_F(ToolTest, RejectsBadOptions) {
  const std::string in = write("p.csv", "0,0,0\n1,0,0\n");
  const std::string out = (dir_ / "c.csv").string();
  std::string err;
  EXPECT_EQ(run({"--input", in, "--radius", "-1", "--out", out}, &err), 2);
  EXPECT_NE(err.find("--radius"), std::string::npos) << err;
  EXPECT_EQ(run({"--input", in, "--radius", "1", "--out", out, "--gridder", "E"}, &err), 2);
  EXPECT_NE(err.find("A, B, C, D"), std::string::npos) << err;
  EXPECT_EQ(run({"--input", in, "--radius", "1", "--out", out, "--cell-order", "morton"}, &err), 2);
  EXPECT_NE(err.find("sort_xyz"), std::string::npos) << err;
  EXPECT_EQ(run({"--input", in, "--radius", "1", "--out", out, "--reorder", "2"}, &err), 2);
  EXPECT_EQ(run({"--input", in, "--radius", "1"}, &err), 2);
  EXPECT_NE(err.find("missing --out"), std::string::npos) << err;
  EXPECT_EQ(run({"--input", in, "--radius", "1", "--out", out, "--bogus", "1"}, &err), 2);
  EXPECT_NE(err.find("unknown option --bogus"), std::string::npos) << err;
  EXPECT_EQ(run({"--input", (dir_ / "missing.csv").string(), "--radius", "1", "--out", out}, &err), 1);
  EXPECT_NE(err.find("cannot open"), std::string::npos) << err;
}

TEST_F(ToolTest, CountsAndPairsMatchBruteForceForEveryCombination) {
  const PointCloud pc = random_cloud(700, -2.0, 3.0, 99);
  const double radius = 0.7;
  const Expected want = brute_force_files(pc, radius);
  const std::string in = write("p.csv", to_csv(pc, true));
  const std::string counts = (dir_ / "counts.csv").string(), pairs = (dir_ / "pairs.csv").string();
  for (const char* g : {"A", "B", "C", "D"})
    for (const char* o : {"sort_x", "sort_xy", "sort_xyz", "hilbert"})
      for (const char* r : {"0", "1"}) {
        const std::string what = std::string(g) + "/" + o + "/" + r;
        ASSERT_EQ(run({"--input", in, "--radius", "0.7", "--gridder", g, "--cell-order", o, "--reorder", r, "--out",
                       counts, "--pairs", pairs}),
                  0)
            << what;
        EXPECT_EQ(read(counts), want.counts) << what;
        EXPECT_EQ(read(pairs), want.pairs) << what;
      }
  // The summary names what was run and what it found.
  EXPECT_NE(stdout_.find("points              700"), std::string::npos) << stdout_;
  EXPECT_NE(stdout_.find("entries per second"), std::string::npos) << stdout_;
  EXPECT_NE(stdout_.find("bytes used"), std::string::npos) << stdout_;
  // No temporary files are left behind.
  for (const auto& e : fs::directory_iterator(dir_))
    EXPECT_EQ(e.path().string().find(".tmp."), std::string::npos) << e.path();
}

TEST_F(ToolTest, AnyCoordinates) {
  struct Case {
    const char* name;
    PointCloud pc;
    double radius;
  };
  std::vector<Case> cases;
  cases.push_back({"negative", random_cloud(600, -50.0, -45.0, 1), 0.8});
  PointCloud far = random_cloud(600, 0.0, 1.0, 2);
  for (std::size_t i = 0; i < far.size(); ++i) {
    far.x[i] += 1e6;
    far.y[i] -= 3e5;
    far.z[i] += 7.5e4;
  }
  cases.push_back({"far from the origin", far, 0.15});
  PointCloud plane = random_cloud(600, -1.0, 1.0, 3);
  for (double& z : plane.z) z = -2.5;
  cases.push_back({"all on one plane", plane, 0.12});
  PointCloud line = random_cloud(300, 0.0, 10.0, 4);
  for (std::size_t i = 0; i < line.size(); ++i) line.y[i] = line.z[i] = 1.0;
  cases.push_back({"all on one line", line, 0.1});
  PointCloud dup;  // coincident points are neighbours (r = 0 < R), a point is not its own
  for (int i = 0; i < 5; ++i) {
    dup.x.push_back(1.0);
    dup.y.push_back(2.0);
    dup.z.push_back(3.0);
  }
  dup.x.push_back(100.0), dup.y.push_back(2.0), dup.z.push_back(3.0);  // a sparse outlier
  cases.push_back({"coincident and sparse", dup, 1e-3});
  for (const Case& c : cases) {
    const Expected want = brute_force_files(c.pc, c.radius);
    const std::string in = write("p.csv", to_csv(c.pc, false));
    const std::string counts = (dir_ / "counts.csv").string(), pairs = (dir_ / "pairs.csv").string();
    std::ostringstream r;
    r.precision(17);
    r << c.radius;
    for (const char* o : {"sort_x", "sort_xyz", "hilbert"})
      for (const char* g : {"B", "D"}) {
        ASSERT_EQ(run({"--input", in, "--radius", r.str(), "--gridder", g, "--cell-order", o, "--out", counts, "--pairs",
                       pairs}),
                  0)
            << c.name;
        EXPECT_EQ(read(counts), want.counts) << c.name << " " << g << " " << o;
        EXPECT_EQ(read(pairs), want.pairs) << c.name << " " << g << " " << o;
      }
  }
}

TEST(NeighbourSearch, ReusesItsBuffersAndCountsEveryEntry) {
  // A cubic lattice with R = 1.5 spacing: interior points have 18 neighbours
  // (6 faces, 12 edges at sqrt 2), corners 6.
  std::vector<double> x, y, z;
  for (int k = 0; k < 6; ++k)
    for (int j = 0; j < 6; ++j)
      for (int i = 0; i < 6; ++i) x.push_back(i), y.push_back(j), z.push_back(k);
  NeighbourSearch search;
  NeighbourLists lists;
  search.run(x, y, z, 1.5, lists);
  std::vector<std::uint32_t> counts;
  lists.counts(counts);
  EXPECT_EQ(counts[0], 6u);                    // corner (0,0,0)
  EXPECT_EQ(counts[1 + 6 + 36], 18u);          // interior (1,1,1)
  const std::uint64_t entries = lists.num_entries();
  const std::size_t bytes = lists.bytes() + search.bytes();
  search.run(x, y, z, 1.5, lists);
  EXPECT_EQ(lists.num_entries(), entries);
  EXPECT_EQ(lists.bytes() + search.bytes(), bytes) << "a second run on the same cloud allocates nothing new";
  EXPECT_THROW(search.run(x, y, z, 0.0, lists), std::invalid_argument);
}
