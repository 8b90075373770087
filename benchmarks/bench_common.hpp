#pragma once
// Shared pieces of sphnl_bench: the experiment sweep, the snapshot cache of the
// developed flow, and the counters every step benchmark reports.
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

/// One point of a sweep: axis name -> value (as JSON scalars).
using Point = std::map<std::string, nlohmann::json>;
/// Cross product of the axes of `sweep` (an object of arrays), in axis order.
std::vector<Point> cross_product(const nlohmann::json& sweep, const std::vector<std::string>& axis_order);
/// `family/key:value/...` with the axes in `axis_order`, then any others.
std::string benchmark_name(const std::string& family, const Point& p, const std::vector<std::string>& axis_order);

/// The state of the developed dam-break flow for this N (t = kDevelopTime),
/// from the cache directory, made (with a CLL run on every core) when missing
/// or stale. Kept in memory after the first call.
const Simulation& developed_flow(long n, Lattice lattice, double h_coefficient, const std::string& cache_dir);
inline constexpr double kDevelopTime = 0.35;  // s: the dam has collapsed, the front reaches the obstacle

/// Runs `steps` steps: the region callgrind counts in `make compare`
/// (--toggle-collect='sphnl::bench::timed_window*').
void timed_window(Simulation& sim, int steps);

void register_step_benchmarks(const nlohmann::json& sweep, int window, const Options& opt);
void register_cellindex_benchmarks(const nlohmann::json& sweep, const Options& opt);
void register_search_benchmarks(const nlohmann::json& sweep);

double peak_rss_bytes();

}  // namespace sphnl::bench
