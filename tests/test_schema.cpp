// The strict JSON reader (duplicate keys, positions) and the experiment-file
// schema: every shipped experiment is valid, and each kind of mistake gives a
// message with the file, line, column, key and the allowed values.
#include <algorithm>
#include <filesystem>
#include <string>

#include <gtest/gtest.h>

#include "sphnl/config.hpp"
#include "sphnl/experiment_schema.hpp"
#include "sphnl/json_reader.hpp"

namespace sphnl {
namespace {

#define EXPECT_HAS(text, part) EXPECT_NE(std::string(text).find(part), std::string::npos) << "in: " << (text)

std::string all_errors(const std::string& text) {
  const auto errors = validate_experiment(parse_json_strict(text, "e.json"));
  std::string s;
  for (const auto& e : errors) s += e + "\n";
  return s;
}

const char* kValidStep = R"({
  "id": "x", "benchmark": "step", "uses": null, "metric": "s_per_step",
  "sweep": {
    "tiny": {"particles": [1500], "gridder": ["A"], "cell_order": ["sort_x"], "reorder": [0], "list": ["cll"], "list_steps": [1], "kgc": [0], "threads": [1]},
    "default": {"particles": [1500], "gridder": ["A"], "cell_order": ["sort_x"], "reorder": [0], "list": ["cll"], "list_steps": [1], "kgc": [0], "threads": [1]},
    "full": {"particles": [1500], "gridder": ["A"], "cell_order": ["sort_x"], "reorder": [0], "list": ["cll"], "list_steps": [1], "kgc": [0], "threads": [1], "flow_time": [0.35]}
  },
  "window_steps": {"tiny": 3, "default": 10, "full": 20},
  "protocol": {"tiny": {"min_rounds": 1, "max_rounds": 3}, "full": {"budget_s": 60, "target_halfwidth_pct": 2}},
  "claims": [{"id": "c1", "band_reason": "anything goes here", "tolerance": {"reproduced": [1, null]}}]
})";

std::string with(std::string text, const std::string& from, const std::string& to) {
  const auto at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  return text.replace(at, from.size(), to);
}

TEST(JsonReader, DuplicateKeyIsAnErrorWithBothLines) {
  try {
    parse_json_strict("{\n  \"a\": 1,\n  \"b\": {\"c\": 1},\n    \"a\": 2\n}", "f.json");
    FAIL() << "duplicate key accepted";
  } catch (const JsonFileError& e) {
    EXPECT_HAS(e.what(), "f.json:4:5: duplicate key 'a' (first at line 2)");
  }
  // the same key in two different objects is fine
  EXPECT_NO_THROW(parse_json_strict(R"({"a": {"k": 1}, "b": {"k": 2}})", "f.json"));
}

TEST(JsonReader, SyntaxErrorHasLineAndColumn) {
  try {
    parse_json_strict("{\n  \"a\": 1,\n  \"b\": ]\n}", "f.json");
    FAIL() << "malformed JSON accepted";
  } catch (const JsonFileError& e) {
    EXPECT_HAS(e.what(), "f.json:3:8: not valid JSON");
  }
}

TEST(JsonReader, BuildsTheSameValueAsNlohmann) {
  const std::string text = R"({"a": [1, 2.5, "s", null, true, {"b": [[]]}], "c": {}, "d": -3, "e": 18446744073709551615})";
  const ParsedJson p = parse_json_strict(text, "f.json");
  EXPECT_EQ(p.value, nlohmann::json::parse(text));
  EXPECT_EQ(p.where("/a/5/b"), "f.json:1:34");
  EXPECT_EQ(p.where("/nope"), "f.json");
}

TEST(JsonReader, CommentsOnlyWhenAllowed) {
  EXPECT_THROW(parse_json_strict("{\"a\": 1 // x\n}", "f.json"), JsonFileError);
  EXPECT_EQ(parse_json_strict("{\"a\": 1 // x\n}", "f.json", true).value["a"], 1);
}

TEST(ExperimentSchema, ShippedExperimentsAreValid) {
  int seen = 0;
  for (const auto& f : std::filesystem::directory_iterator(std::string(SPHNL_SOURCE_DIR) + "/experiments")) {
    if (f.path().extension() != ".json") continue;
    ++seen;
    EXPECT_NO_THROW(load_experiment(f.path().string())) << f.path();
  }
  EXPECT_GE(seen, 10);
  EXPECT_EQ(all_errors(kValidStep), "");
}

TEST(ExperimentSchema, MisspelledSweepAxisIsNamedWithItsPlace) {
  const std::string e = all_errors(with(kValidStep, R"("tiny": {"particles": [1500], "gridder")", R"("tiny": {"particles": [1500], "gridderr")"));
  EXPECT_HAS(e, "e.json:4:35: sweep.tiny: unknown sweep axis 'gridderr' for benchmark 'step'; allowed: particles, gridder, cell_order,");
  EXPECT_HAS(e, "sweep.tiny: missing sweep axis 'gridder'");
}

TEST(ExperimentSchema, OldAxisNamesSayWhatTheyWereRenamedTo) {
  // The vocabulary before the sweep axes became the run-config keys.
  std::string old = with(kValidStep, R"("tiny": {"particles": [1500])", R"("tiny": {"n": [1500])");
  old = with(old, R"("cell_order": ["sort_x"], "reorder": [0], "list": ["cll"], "list_steps": [1], "kgc": [0], "threads": [1]},)",
             R"("order": ["sort_x"], "reorder": [0], "list": ["cll"], "ns": [1], "kgc": [0], "threads": [1]},)");
  const std::string e = all_errors(old);
  EXPECT_HAS(e, "e.json:4:14: sweep.tiny: sweep axis 'n' was renamed to 'particles'");
  EXPECT_HAS(e, "e.json:4:45: sweep.tiny: sweep axis 'order' was renamed to 'cell_order'");
  EXPECT_HAS(e, "sweep.tiny: sweep axis 'ns' was renamed to 'list_steps'");
  // said once, as a rename: neither unknown nor missing
  EXPECT_EQ(e.find("unknown sweep axis"), std::string::npos) << e;
  EXPECT_EQ(e.find("missing sweep axis"), std::string::npos) << e;
}

TEST(ExperimentSchema, BenchmarkOnlyAxesAreTheOnesThatAreNotConfigKeys) {
  // the snapshot's flow time, the search family's peers and clouds, the
  // counters kind's simulated caches: none of them is a run setting
  const std::vector<std::string> only = benchmark_only_axes();
  EXPECT_EQ(only, (std::vector<std::string>{"flow_time", "window_start", "impl", "cloud", "memory_order", "call", "pages",
                                             "freed_memory", "cache_model", "ranks"}));
  const std::vector<std::string> keys = config_keys();
  for (const auto& axis : only) EXPECT_EQ(std::count(keys.begin(), keys.end(), axis), 0) << axis;
}

TEST(ExperimentSchema, UnknownTopLevelKey) {
  EXPECT_HAS(all_errors(with(kValidStep, R"("metric")", R"("metrics")")), "e.json:2:49: top level: unknown key 'metrics'; allowed: id, figure, title,");
}

TEST(ExperimentSchema, DuplicateKeyInAnExperiment) {
  EXPECT_THROW(parse_json_strict(with(kValidStep, R"("metric": "s_per_step")", R"("metric": "a", "metric": "b")"), "e.json"),
               JsonFileError);
}

TEST(ExperimentSchema, WrongTypesAndValues) {
  EXPECT_HAS(all_errors(with(kValidStep, R"("gridder": ["A"], "cell_order")", R"("gridder": ["E"], "cell_order")")), "sweep.tiny.gridder: config key 'gridder': invalid value \"E\"; allowed: A, B, C, D");
  EXPECT_HAS(all_errors(with(kValidStep, R"("threads": [1]},)", R"("threads": 1},)")), "sweep.tiny.threads: is 1; expected a non-empty array of values");
  EXPECT_HAS(all_errors(with(kValidStep, R"("flow_time": [0.35])", R"("flow_time": [0])")), "sweep.full.flow_time: value 0 is not allowed; expected a number > 0");
  EXPECT_EQ(all_errors(with(kValidStep, R"("flow_time": [0.35])", R"("flow_time": [0.35], "window_start": ["primed", "cold"])")), "");
  EXPECT_HAS(all_errors(with(kValidStep, R"("flow_time": [0.35])", R"("flow_time": [0.35], "window_start": ["warm"])")),
             "sweep.full.window_start: value \"warm\" is not allowed; expected one of primed, cold");
  EXPECT_HAS(all_errors(with(kValidStep, R"("window_steps": {"tiny": 3)", R"("window_steps": {"tiny": 0)")), "window_steps.tiny: is 0; expected an integer >= 1");
  EXPECT_HAS(all_errors(with(kValidStep, R"("benchmark": "step")", R"("benchmark": "steps")")), "benchmark: is \"steps\"; expected one of step, counters, cellindex, search");
  EXPECT_HAS(all_errors(with(kValidStep, R"("tiny": {"particles")", R"("small": {"particles")")), "sweep: unknown size 'small'; allowed: tiny, default, full");
}

TEST(ExperimentSchema, FreedMemoryTakesNamedStatesAndIdleSeconds) {
  // the search family's freed_memory: as_found, just_freed, idle_<s>s with s from 1 to 60
  const std::string search = with(with(with(kValidStep, R"("benchmark": "step")", R"("benchmark": "search")"),
                                        R"("list": ["cll"], "list_steps": [1], "kgc": [0], "threads": [1], "flow_time": [0.35]})",
                                        R"("threads": [1], "call": ["first"], "freed_memory": ["as_found", "just_freed", "idle_1s", "idle_60s"]})"),
                                   R"("metric": "s_per_step")", R"("metric": "s_call")");
  const std::string tiny_and_default_cleaned = [&] {
    std::string t = search;
    for (int k = 0; k < 2; ++k)
      t = with(t, R"("list": ["cll"], "list_steps": [1], "kgc": [0], "threads": [1]})", R"("threads": [1]})");
    return t;
  }();
  EXPECT_EQ(all_errors(tiny_and_default_cleaned), "");
  for (const char* bad : {"idle_0s", "idle_61s", "idle_05s", "idle_s", "idle_3", "idle_3.5s", "fresh"}) {
    const std::string text = with(tiny_and_default_cleaned, "\"idle_60s\"", std::string("\"") + bad + "\"");
    EXPECT_HAS(all_errors(text), std::string("sweep.full.freed_memory: value \"") + bad + "\" is not allowed; expected \"as_found\"");
  }
}

TEST(ExperimentSchema, FreedMemoryIdleSecondsIsTheOneParserOfTheAxis) {
  // what the bench waits, from the value the schema accepted
  EXPECT_EQ(freed_memory_idle_seconds("as_found"), 0);
  EXPECT_EQ(freed_memory_idle_seconds("just_freed"), 0);
  EXPECT_EQ(freed_memory_idle_seconds("idle_1s"), 1);
  EXPECT_EQ(freed_memory_idle_seconds("idle_12s"), 12);
  EXPECT_EQ(freed_memory_idle_seconds("idle_60s"), 60);
  for (const char* bad : {"idle_0s", "idle_61s", "idle_05s", "idle_s", "idle_3", "idle_3.5s", "idle_123s", "fresh", ""})
    EXPECT_EQ(freed_memory_idle_seconds(bad), -1) << bad;
}

TEST(ExperimentSchema, ProtocolAndClaims) {
  EXPECT_HAS(all_errors(with(kValidStep, R"("min_rounds": 1)", R"("min_round": 1)")), "protocol.tiny: unknown key 'min_round'; allowed: min_rounds, max_rounds, reps_per_round");
  EXPECT_HAS(all_errors(with(kValidStep, R"("budget_s": 60)", R"("budget_s": -1)")), "protocol.full.budget_s: is -1; expected a number > 0");
  // one protocol for every size is allowed too
  EXPECT_EQ(all_errors(with(kValidStep, R"({"tiny": {"min_rounds": 1, "max_rounds": 3}, "full": {"budget_s": 60, "target_halfwidth_pct": 2}})",
                            R"({"reps_per_round": 2})")),
            "");
  EXPECT_HAS(all_errors(with(kValidStep, R"({"id": "c1", )", R"({)")), "claims[0]: needs an 'id'");
}

TEST(ExperimentSchema, CountersKindNeedsACacheModel) {
  // The step axes plus cache_model (harness/valgrind.py); no protocol needed.
  std::string c = with(kValidStep, R"("benchmark": "step")", R"("benchmark": "counters")");
  EXPECT_HAS(all_errors(c), "missing sweep axis 'cache_model' (required for benchmark 'counters')");
  for (const char* size : {R"("threads": [1]},
    "default")", R"("threads": [1]},
    "full")", R"("flow_time": [0.35])"})
    c = with(c, size, std::string(size).replace(std::string(size).find(']') + 1, 0, R"(, "cache_model": ["nehalem_2010"])"));
  EXPECT_EQ(all_errors(c), "");
  EXPECT_HAS(all_errors(with(c, R"(["nehalem_2010"])", R"(["epyc"])")),
             "cache_model: value \"epyc\" is not allowed; expected \"this_machine\" or \"nehalem_2010\"");
  EXPECT_HAS(all_errors(with(kValidStep, R"("flow_time": [0.35])", R"("flow_time": [0.35], "cache_model": ["this_machine"])")),
             "unknown sweep axis 'cache_model' for benchmark 'step'");
  EXPECT_EQ(all_errors(with(c, R"("claims": [)", R"("explanations": [{"id": "h"}], "claims": [)")), "");
  EXPECT_HAS(all_errors(with(c, R"("claims": [)", R"("explanations": [{"hypothesis": "h"}], "claims": [)")),
             "explanations[0]: needs an 'id'");
}

TEST(ExperimentSchema, MpiKindHasRanksAndMaxCores) {
  // `sphnl run` under mpirun (experiments/mpi_runs.py): config keys plus the launcher's ranks.
  const std::string sweep = R"({"particles": [3000], "list": ["cll"], "list_steps": [7], "ranks": [1, 2], "threads": [1]})";
  const std::string m = std::string(R"({"id": "e", "benchmark": "mpi", "max_cores": 2, "sweep": {"tiny": )") + sweep +
                        R"(, "default": )" + sweep + R"(, "full": )" + sweep +
                        R"(}, "window_steps": {"tiny": 21, "default": 21, "full": 21}, "claims": []})";
  EXPECT_EQ(all_errors(m), "");
  EXPECT_HAS(all_errors(with(m, R"("ranks": [1, 2])", R"("ranks": [0, 2])")),
             "sweep.tiny.ranks: value 0 is not allowed; expected an integer >= 1");
  EXPECT_HAS(all_errors(with(m, R"(, "ranks": [1, 2])", "")), "missing sweep axis 'ranks' (required for benchmark 'mpi')");
  EXPECT_HAS(all_errors(with(m, R"("max_cores": 2)", R"("max_cores": 0)")), "max_cores: is 0; expected an integer >= 1");
  EXPECT_HAS(all_errors(with(m, R"("list": ["cll"])", R"("gridder": ["B"])")), "unknown sweep axis 'gridder' for benchmark 'mpi'");
}

}  // namespace
}  // namespace sphnl
