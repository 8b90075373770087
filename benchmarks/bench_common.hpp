#pragma once
// Shared pieces of sphnl_bench: the experiment sweep, the snapshot cache of the
// developed flow, and the counters every step benchmark reports.
#include <cstddef>
#include <map>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>
#include <nlohmann/json.hpp>

#include "sphnl/config.hpp"
#include "sphnl/simulation.hpp"

namespace sphnl::bench {

struct Options {
  std::string experiment_path;
  std::string size = "default";
  std::string cache_dir = "results/cache";
};

/// One point of a sweep: axis name -> value (as JSON scalars). Axis names are
/// the run-config keys (README "Configuration"), plus the benchmark-only axes
/// of sphnl::benchmark_only_axes().
using Point = std::map<std::string, nlohmann::json>;
/// Cross product of the axes of `sweep` (an object of arrays), in axis order.
std::vector<Point> cross_product(const nlohmann::json& sweep, const std::vector<std::string>& axis_order);
/// `family/key:value/...` with the axes in `axis_order`, then any others; the
/// keys are the axis names as they stand (docs/CONTRACTS.md §2).
std::string benchmark_name(const std::string& family, const Point& p, const std::vector<std::string>& axis_order);

/// The flow state a benchmark starts from: the dam-break case (N, lattice,
/// h coefficient) developed to `flow_time` seconds.
struct FlowState {
  long n = 0;
  Lattice lattice = Lattice::bcc;
  double h_coefficient = 0;
  double flow_time = 0;
};
inline constexpr double kDefaultFlowTime = 0.35;  // s: the dam has collapsed, the front reaches the obstacle

/// The one place a sweep point becomes a run: every axis that is a run-config
/// key goes to config_from_json as it stands (so its values are checked there,
/// and a new config key is a new axis without code here); the benchmark-only
/// axes (sphnl::benchmark_only_axes()) are left out and read by their own
/// accessor (flow_time_of). Progress output is off.
RunConfig run_config_of(const Point& p);
/// Whether a step window runs primed (the point's `window_start`, default
/// "primed"): one untimed step of its Simulation from the same snapshot first.
bool primed_window_of(const Point& p);
/// The flow time a step window starts from: the point's `flow_time` (s), else kDefaultFlowTime.
double flow_time_of(const Point& p);

/// Threads of a development run: the machine's online processors, not the
/// CPUs this process is allowed (taskset), so a pinned bench finds the same
/// snapshots as an unpinned one.
int development_threads();

/// The developed flow `state`, from the cache directory, made when missing or
/// stale with a CLL run on every core (the cache key holds everything that
/// changes the snapshot: case, flow time and that thread count). When it must
/// be made, the run from t = 0 also saves every missing one of `also_times`
/// (the sweep's other flow times of the same case) that it passes, since a run
/// to 0.5 s goes through 0.2 s. Kept in memory after the first call.
const Simulation& developed_flow(const FlowState& state, const std::vector<double>& also_times,
                                 const std::string& cache_dir);

/// Runs `steps` steps: the region callgrind counts in `make compare`
/// (--toggle-collect='sphnl::bench::timed_window*'). `max_nl_bytes` becomes the
/// largest neighbour-structure size seen after any step of the window (lists
/// and grids grow and shrink as the flow moves; one sample at the end would
/// miss the peak).
void timed_window(Simulation& sim, int steps, std::size_t& max_nl_bytes);

/// 0, 1, 2, ... for the successive benchmark-function calls of this process
/// (Google Benchmark's discarded warm-up included): reported as the counter
/// `run_sequence`, it records the order in which the repetitions actually ran
/// under --benchmark_enable_random_interleaving.
long next_run_sequence();

/// The `step` family; with family "counters", the same windows named
/// `counters/...` (cache_model segment included) for experiments/counters.py,
/// which runs each under callgrind.
void register_step_benchmarks(const nlohmann::json& sweep, int window, const Options& opt,
                              const std::string& family = "step");
void register_cellindex_benchmarks(const nlohmann::json& sweep, const Options& opt);
void register_search_benchmarks(const nlohmann::json& sweep);

double peak_rss_bytes();

/// This process's page faults so far (getrusage; zeros where it fails):
/// minor, the first touches of fresh memory, and major, reads from disk.
struct ProcessFaults {
  double minor = 0, major = 0;
};
ProcessFaults process_faults();

}  // namespace sphnl::bench
