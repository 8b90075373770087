// End-to-end checks of the `sphnl` binary: outputs of a short run (summary,
// VTU, CSV in id order, no temporary files left) and errors for bad input
// that name the key or path before any work is done.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include "sphnl_revision.hpp"

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

struct Result {
  int status = -1;
  std::string err;
};

/// A fresh scratch directory per test, removed afterwards.
class Cli : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("sphnl_test_cli_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  Result sphnl(const std::string& args) const {
    const fs::path err = dir_ / "stderr.txt";
    const std::string cmd = std::string("'") + SPHNL_BINARY + "' " + args + " > '" + (dir_ / "stdout.txt").string() +
                            "' 2> '" + err.string() + "'";
    const int raw = std::system(cmd.c_str());
    Result r;
    r.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
    std::ifstream in(err);
    std::stringstream ss;
    ss << in.rdbuf();
    r.err = ss.str();
    return r;
  }
  std::string stdout_text() const {
    std::ifstream in(dir_ / "stdout.txt");
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
  }

  fs::path dir_;
};

std::vector<std::string> split(const std::string& line, char sep) {
  std::vector<std::string> out;
  std::stringstream ss(line);
  std::string item;
  while (std::getline(ss, item, sep)) out.push_back(item);
  return out;
}

/// Reads one appended DataArray of a raw-appended VTU file (UInt64 headers).
template <class T>
std::vector<T> vtu_array(const std::string& file, const std::string& name) {
  const std::string tag = "Name=\"" + name + "\"";
  const auto at = file.find(tag);
  if (at == std::string::npos) return {};
  const auto off_at = file.find("offset=\"", at) + 8;
  const std::uint64_t offset = std::stoull(file.substr(off_at, file.find('"', off_at) - off_at));
  const auto data = file.find('_', file.find("<AppendedData")) + 1;
  std::uint64_t bytes = 0;
  std::memcpy(&bytes, file.data() + data + offset, sizeof bytes);
  std::vector<T> v(bytes / sizeof(T));
  std::memcpy(v.data(), file.data() + data + offset + sizeof bytes, bytes);
  return v;
}

}  // namespace

TEST_F(Cli, ShortRunWritesSummaryVtuAndCsvInIdOrder) {
  const fs::path out = dir_ / "out";
  const Result r = sphnl("run --set particles=3000 --set steps=20 --set output_interval=0.01 --quiet --out '" +
                         out.string() + "'");
  ASSERT_EQ(r.status, 0) << r.err;

  std::ifstream sin(out / "summary.json");
  const json s = json::parse(sin);
  EXPECT_EQ(s["steps"], 20);
  EXPECT_EQ(s["config"]["particles"], 3000);
  EXPECT_EQ(s["status"], "completed");
  const std::size_t n_fluid = s["n_fluid"], n_boundary = s["n_boundary"], n = s["n_total"];
  EXPECT_EQ(n_fluid + n_boundary, n);
  for (const char* phase : {"neighbour_list", "force", "update", "total"})
    EXPECT_GT(s["wall_time_s"][phase].get<double>(), 0) << phase;
  EXPECT_EQ(s["total_mass"]["initial"], s["total_mass"]["final"]);
  EXPECT_EQ(s["particles_lost"], 0);
  EXPECT_EQ(s["momentum"].size(), 3u);
  for (const char* key : {"dx", "h", "c0", "simulated_time", "seconds_per_step", "max_speed", "neighbour_bytes",
                          "peak_rss_bytes", "git_revision", "build_type"})
    EXPECT_TRUE(s.contains(key)) << key;
  EXPECT_EQ(s["neighbour_stats"]["builds"], 20);
  EXPECT_GT(s["neighbour_stats"]["interactions_per_particle"].get<double>(), 1);

  // Snapshots: t = 0 and the final step always; CSV columns fixed, rows in id order.
  for (const char* stem : {"step_000000", "step_000020"}) {
    const fs::path csv = out / "snapshots" / (std::string(stem) + ".csv");
    const fs::path vtu = out / "snapshots" / (std::string(stem) + ".vtu");
    ASSERT_TRUE(fs::exists(csv)) << csv;
    ASSERT_TRUE(fs::exists(vtu)) << vtu;
    std::ifstream in(csv);
    std::string line;
    std::getline(in, line);
    EXPECT_EQ(line, "id,type,x,y,z,vx,vy,vz,rho,p");
    std::size_t rows = 0, fluid = 0, boundary = 0;
    std::vector<double> xs;
    while (std::getline(in, line)) {
      const auto f = split(line, ',');
      ASSERT_EQ(f.size(), 10u) << line;
      EXPECT_EQ(std::stoul(f[0]), rows) << "rows must be in id order";
      fluid += f[1] == "fluid";
      boundary += f[1] == "boundary";
      xs.push_back(std::stod(f[2]));
      ++rows;
    }
    EXPECT_EQ(rows, n);
    EXPECT_EQ(fluid, n_fluid);
    EXPECT_EQ(boundary, n_boundary);

    std::ifstream vin(vtu, std::ios::binary);
    const std::string file((std::istreambuf_iterator<char>(vin)), std::istreambuf_iterator<char>());
    EXPECT_NE(file.find("<VTKFile type=\"UnstructuredGrid\""), std::string::npos);
    EXPECT_NE(file.find("NumberOfPoints=\"" + std::to_string(n) + "\""), std::string::npos);
    EXPECT_NE(file.rfind("</VTKFile>"), std::string::npos);
    const auto ids = vtu_array<std::int32_t>(file, "id");
    const auto types = vtu_array<std::int32_t>(file, "type");
    const auto points = vtu_array<double>(file, "Points");
    const auto velocity = vtu_array<double>(file, "velocity");
    const auto cell_types = vtu_array<std::uint8_t>(file, "types");
    ASSERT_EQ(ids.size(), n);
    ASSERT_EQ(types.size(), n);
    ASSERT_EQ(points.size(), 3 * n);
    ASSERT_EQ(velocity.size(), 3 * n);
    ASSERT_EQ(cell_types.size(), n);
    for (std::size_t k = 0; k < n; ++k) {
      EXPECT_EQ(ids[k], static_cast<std::int32_t>(k));
      EXPECT_NEAR(points[3 * k], xs[k], 1e-9);
      EXPECT_EQ(cell_types[k], 1);  // VTK_VERTEX
      EXPECT_EQ(types[k], k < n_fluid ? 0 : 1);
    }
  }
  EXPECT_TRUE(fs::exists(out / "snapshots.pvd"));
  // The snapshot interval (0.01 s, dt ~ 1.5 ms) gives intermediate snapshots.
  EXPECT_GE(s["snapshots"].size(), 3u);
  for (const auto& e : fs::recursive_directory_iterator(out))
    EXPECT_EQ(e.path().filename().string().find(".tmp."), std::string::npos) << e.path();
}

TEST_F(Cli, UnknownKeyFailsBeforeAnyWorkNamingTheKey) {
  const fs::path out = dir_ / "out";
  const Result r = sphnl("run --set gridr=B --out '" + out.string() + "'");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("'gridr'"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("gridder"), std::string::npos) << r.err;  // the known keys
  EXPECT_FALSE(fs::exists(out));
}

TEST_F(Cli, BadValueNamesKeyAndAllowedValues) {
  const Result r = sphnl("run --set gridder=E --out '" + (dir_ / "out").string() + "'");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("'gridder'"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("A, B, C, D"), std::string::npos) << r.err;
}

TEST_F(Cli, ConfigFileKeysAreChecked) {
  const fs::path cfg = dir_ / "cfg.json";
  std::ofstream(cfg) << R"({"particles": 3000, "threads": "two"})";
  const Result r = sphnl("run --config '" + cfg.string() + "' --out '" + (dir_ / "out").string() + "'");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("'threads'"), std::string::npos) << r.err;
}

TEST_F(Cli, UnwritableOutputDirectoryIsNamed) {
  // A directory below a regular file can never be created (also as root).
  const fs::path blocker = dir_ / "a_file";
  std::ofstream(blocker) << "x";
  const fs::path out = blocker / "out";
  const Result r = sphnl("run --set particles=3000 --set steps=2 --out '" + out.string() + "'");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find(out.string()), std::string::npos) << r.err;
}

TEST_F(Cli, UnknownCommandOrOptionPrintsUsage) {
  Result r = sphnl("frobnicate");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("usage: sphnl"), std::string::npos) << r.err;
  r = sphnl("run --bogus");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("--bogus"), std::string::npos) << r.err;
  r = sphnl("--version");
  EXPECT_EQ(r.status, 0);
  EXPECT_NE(stdout_text().find(SPHNL_GIT_REVISION), std::string::npos) << stdout_text();
}
