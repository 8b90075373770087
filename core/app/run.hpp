#pragma once
// `sphnl run`: runs the dam break of paper §2.2 from a RunConfig (JSON file plus
// `--set key=value` overrides), shows progress, and writes DIR/summary.json and
// snapshots (DIR/snapshots/step_NNNNNN.vtu and .csv, DIR/snapshots.pvd).
#include <string>

#include <nlohmann/json_fwd.hpp>

#include "sphnl/simulation.hpp"

namespace sphnl {

/// Options of `sphnl run` after parsing the command line.
struct RunOptions {
  std::string config_file;            // empty: the RunConfig defaults (config.hpp)
  std::vector<std::string> overrides; // `key=value`, applied in order after the file
  std::string out_dir = "sphnl-out";
  bool quiet = false;                 // no progress line
  bool overwrite = false;             // replace the run already in out_dir
  bool force_memory = false;          // run even when the memory estimate exceeds MemAvailable
};

/// Parses the arguments after `run`. Throws ConfigError naming the bad option.
RunOptions parse_run_options(int argc, char** argv);
/// Reads the config file (if any) and applies the overrides; throws ConfigError
/// naming the key or the file.
RunConfig load_run_config(const RunOptions& options);
/// Usage text of `sphnl run`.
std::string run_usage();

/// The summary of a run (the content of summary.json) as it stands now.
/// `initial_mass` is the total mass at t = 0 summed in id order.
nlohmann::json run_summary(const Simulation& sim, double initial_mass, double wall_total_s);

/// Entry point of `sphnl run` (argv[0] is "run"). Returns the process exit
/// status: 0 done, 1 the simulation failed, 2 bad input, 130 interrupted.
int run_main(int argc, char** argv);

}  // namespace sphnl
