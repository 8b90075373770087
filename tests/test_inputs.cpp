// The user's input files and options: a run config with a duplicate key,
// malformed JSON or a bad value is refused with FILE:LINE:COL, and an option
// never takes the next option as its value.
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "sphnl/config.hpp"
#include "sphnl/config_file.hpp"
#include "run.hpp"

namespace fs = std::filesystem;

#define EXPECT_HAS(text, part) EXPECT_NE(std::string(text).find(part), std::string::npos) << "in: " << (text)

namespace sphnl {
namespace {

std::string config_error(const std::string& text) {
  try {
    parse_config_text(text, "cfg.json");
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

TEST(ConfigFile, DuplicateKeyIsAnError) {
  EXPECT_HAS(config_error("{\n  \"gridder\": \"A\",\n  \"gridder\": \"D\"\n}"),
             "cfg.json:3:3: duplicate key 'gridder' (first at line 2)");
}

TEST(ConfigFile, MalformedJsonHasLineAndColumn) {
  const std::string e = config_error("{\n  \"particles\": 3000,\n  \"gridder\": B\n}");
  EXPECT_HAS(e, "cfg.json:3:14: not valid JSON");
  EXPECT_HAS(e, "expected an object such as");
}

TEST(ConfigFile, BadValueNamesItsLineKeyAndAllowedValues) {
  const std::string e = config_error("{\n  // comments are allowed in configs\n  \"particles\": 3000,\n  \"gridder\": \"E\"\n}");
  EXPECT_HAS(e, "cfg.json:4:3: config key 'gridder': invalid value \"E\"; allowed: A, B, C, D");
  EXPECT_HAS(config_error(R"({"particles": 3000, "gridr": "B"})"), "cfg.json:1:21: unknown config key 'gridr'");
  EXPECT_HAS(config_error(R"([1, 2])"), "must hold a JSON object");
  EXPECT_HAS(config_error(R"({"particles": 3000, "dx": 0.01})"), "'particles' and 'dx' both set");
  EXPECT_EQ(parse_config_text(R"({"particles": 3000, "gridder": "D"})", "cfg.json")["gridder"], "D");
}

TEST(ConfigFile, RunReadsConfigsThroughTheStrictReader) {
  const fs::path f = fs::temp_directory_path() / ("sphnl_inputs_" + std::to_string(::getpid()) + ".json");
  std::ofstream(f) << R"({"threads": 1, "threads": 2})";
  RunOptions o;
  o.config_file = f.string();
  try {
    load_run_config(o);
    ADD_FAILURE() << "duplicate key accepted";
  } catch (const ConfigError& e) {
    EXPECT_HAS(e.what(), f.string() + ":1:16: duplicate key 'threads'");
  }
  fs::remove(f);
}

TEST(RunOptions, AnOptionIsNeverTakenAsAValue) {
  const char* a[] = {"run", "--config", "--out", "x"};
  try {
    parse_run_options(4, const_cast<char**>(a));
    ADD_FAILURE() << "--out was taken as the config file name";
  } catch (const ConfigError& e) {
    EXPECT_HAS(e.what(), "option --config needs a value");
  }
}

}  // namespace
}  // namespace sphnl
