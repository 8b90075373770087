#pragma once
// The schema of experiment files (experiments/<id>.json, docs/CONTRACTS.md §1),
// checked in this one place: sphnl_bench validates every file before it
// registers a benchmark, and `sphnl_bench --validate` does only that.
//
// The tables of allowed keys and sweep axes are in experiment_schema.cpp
// (the top-level checks, axes(), kProtocol): a new key is one line there.
// Sweep axes are the run-config keys (README "Configuration"), so a point of a
// sweep is a config as it stands; the few axes that are not run settings are
// listed by benchmark_only_axes().
#include <string>
#include <vector>

#include "sphnl/json_reader.hpp"

namespace sphnl {

/// Every problem of the experiment document, one message each, as
/// "FILE:LINE:COL: key: what is wrong; allowed: ...". Empty when valid.
std::vector<std::string> validate_experiment(const ParsedJson& doc);

/// Reads `path` strictly (duplicate keys, syntax) and validates it; throws
/// JsonFileError with every problem, one per line.
nlohmann::json load_experiment(const std::string& path);

/// Sweep axes that are not run-config keys (`flow_time`: which snapshot of the
/// developed flow a window starts from). sphnl_bench takes these out of a
/// sweep point before the rest goes to config_from_json.
const std::vector<std::string>& benchmark_only_axes();

/// The seconds of idle a value of the search family's `freed_memory` axis
/// asks for: 0 for "as_found" and "just_freed", s for "idle_<s>s" (s an
/// integer from 1 to 60 without a leading zero); -1 for any other value.
int freed_memory_idle_seconds(const std::string& value);

}  // namespace sphnl
