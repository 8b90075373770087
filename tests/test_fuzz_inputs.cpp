// Fuzz-style robustness of the input readers: thousands of deterministic
// mutations (byte flips to structural characters, deletions, insertions,
// duplicated spans, truncation) of a valid point CSV, run config and
// experiment file. Every input is either accepted or refused with the
// reader's own exception and a message naming the input; nothing crashes
// (run under ASan/UBSan by `make test-sanitize`), and `sphnl neighbours`
// on a refused file leaves no output file behind.
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "sphnl/config.hpp"
#include "sphnl/config_file.hpp"
#include "sphnl/experiment_schema.hpp"
#include "sphnl/json_reader.hpp"
#include "neighbours_tool.hpp"

namespace fs = std::filesystem;

namespace sphnl {
namespace {

class Mutator {
 public:
  explicit Mutator(unsigned seed) : rng_(seed) {}

  std::string operator()(std::string s) {
    const int edits = 1 + static_cast<int>(rng_() % 4);
    for (int e = 0; e < edits && !s.empty(); ++e) {
      const std::size_t at = rng_() % s.size();
      switch (rng_() % 6) {
        case 0: s[at] = pick(); break;                                     // flip
        case 1: s.erase(at, 1 + rng_() % 3); break;                        // delete
        case 2: s.insert(at, 1, pick()); break;                            // insert
        case 3: s.insert(at, s.substr(at, 1 + rng_() % 24)); break;        // duplicate a span
        case 4: s.resize(at); break;                                       // truncate
        case 5: s.insert(at, big_number()); break;                         // extreme values
      }
    }
    return s;
  }

 private:
  char pick() {
    static const char kChars[] = ",;\n\r\t \"{}[]:.-+eE0123456789naNIfx\\/*#\x01\xff";
    return kChars[rng_() % (sizeof(kChars) - 1)];
  }
  std::string big_number() {
    static const char* kValues[] = {"1e308", "-1e308", "1e999", "nan", "inf", "4294967296", "-0", "1e-320",
                                    "99999999999999999999", "0x10"};
    return kValues[rng_() % 10];
  }
  std::mt19937 rng_;
};

const std::string kCsv = "x,y,z\n0,0,0\n0.05,0,0\n0.1,0.02,0.3\n1e-3,2.5,-1\n0.5,0.5,0.5\n";
const std::string kConfig = R"({
  // a run config
  "particles": 3000, "gridder": "C", "cell_order": "hilbert", "list": "vlx",
  "list_steps": 7, "threads": 2, "end_time": 0.1, "output_interval": 0.05, "kgc": true
})";

TEST(FuzzInputs, PointCsvReader) {
  Mutator mutate(1);
  int accepted = 0, refused = 0;
  for (int k = 0; k < 4000; ++k) {
    const std::string text = mutate(kCsv);
    try {
      const PointCloud pc = parse_points_csv(text, "in.csv");
      ASSERT_GT(pc.size(), 0u);
      for (std::size_t i = 0; i < pc.size(); ++i) ASSERT_TRUE(std::isfinite(pc.x[i]) && std::isfinite(pc.y[i]) && std::isfinite(pc.z[i]));
      ++accepted;
    } catch (const PointFileError& e) {
      ASSERT_EQ(std::string(e.what()).rfind("in.csv:", 0), 0u) << e.what();
      ++refused;
    }
  }
  EXPECT_GT(accepted, 100);  // the mutations are not all fatal...
  EXPECT_GT(refused, 100);   // ...nor all harmless
}

TEST(FuzzInputs, RunConfigReader) {
  Mutator mutate(2);
  int accepted = 0, refused = 0;
  for (int k = 0; k < 4000; ++k) {
    const std::string text = mutate(kConfig);
    try {
      const nlohmann::json j = parse_config_text(text, "cfg.json");
      config_from_json(j);  // accepted means a usable config
      ++accepted;
    } catch (const ConfigError& e) {
      ASSERT_EQ(std::string(e.what()).rfind("cfg.json", 0), 0u) << e.what();
      ++refused;
    }
  }
  EXPECT_GT(accepted, 50);
  EXPECT_GT(refused, 1000);
}

TEST(FuzzInputs, ExperimentReader) {
  std::ifstream in(std::string(SPHNL_SOURCE_DIR) + "/experiments/fig14.json");
  std::stringstream ss;
  ss << in.rdbuf();
  const std::string valid = ss.str();
  ASSERT_FALSE(valid.empty());
  Mutator mutate(3);
  int refused = 0;
  for (int k = 0; k < 1500; ++k) {
    try {
      const auto errors = validate_experiment(parse_json_strict(mutate(valid), "e.json"));
      for (const auto& e : errors) ASSERT_EQ(e.rfind("e.json", 0), 0u) << e;
      refused += !errors.empty();
    } catch (const JsonFileError& e) {
      ASSERT_EQ(std::string(e.what()).rfind("e.json", 0), 0u) << e.what();
      ++refused;
    }
  }
  EXPECT_GT(refused, 500);
}

TEST(FuzzInputs, NeighboursToolLeavesNoOutputOnRefusal) {
  const fs::path dir = fs::temp_directory_path() / ("sphnl_fuzz_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const std::string in = (dir / "in.csv").string(), out = (dir / "counts.csv").string();
  Mutator mutate(4);
  const int saved = ::dup(::fileno(stdout));
  for (int k = 0; k < 300; ++k) {
    std::ofstream(in, std::ios::binary) << mutate(kCsv);
    fs::remove(out);
    const char* argv[] = {"neighbours", "--input", in.c_str(), "--radius", "0.1", "--out", out.c_str()};
    std::fflush(stdout);
    ASSERT_NE(std::freopen("/dev/null", "w", stdout), nullptr);  // its report; stderr stays for failures
    const int code = neighbours_main(7, const_cast<char**>(argv));
    std::fflush(stdout);
    ASSERT_NE(::dup2(saved, ::fileno(stdout)), -1);
    if (code == 0) {
      ASSERT_TRUE(fs::exists(out));
    } else {
      ASSERT_EQ(code, 1);
      ASSERT_FALSE(fs::exists(out)) << "a refused input left " << out;
    }
    for (const auto& e : fs::directory_iterator(dir))  // never a temporary left behind
      ASSERT_TRUE(e.path().filename() == "in.csv" || e.path().filename() == "counts.csv") << e.path();
  }
  ::close(saved);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace sphnl
