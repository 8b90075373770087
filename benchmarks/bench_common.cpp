#include "bench_common.hpp"

#include <omp.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <sstream>

#include "sphnl/experiment_schema.hpp"
#include "sphnl/memory_estimate.hpp"
#include "sphnl/snapshot.hpp"

namespace sphnl::bench {

using nlohmann::json;

std::vector<Point> cross_product(const json& sweep, const std::vector<std::string>& axis_order) {
  std::vector<std::string> axes;
  for (const auto& a : axis_order)
    if (sweep.contains(a)) axes.push_back(a);
  for (const auto& [k, v] : sweep.items())
    if (std::find(axes.begin(), axes.end(), k) == axes.end()) axes.push_back(k);
  std::vector<Point> points{Point{}};
  for (const auto& a : axes) {
    const json& values = sweep.at(a);
    if (!values.is_array() || values.empty())
      throw std::runtime_error("sweep axis '" + a + "' must be a non-empty array");
    std::vector<Point> next;
    for (const auto& p : points)
      for (const auto& v : values) {
        Point q = p;
        q[a] = v;
        next.push_back(std::move(q));
      }
    points.swap(next);
  }
  return points;
}

std::string benchmark_name(const std::string& family, const Point& p, const std::vector<std::string>& axis_order) {
  std::ostringstream os;
  os << family;
  auto put = [&](const std::string& k, const json& v) {
    os << '/' << k << ':' << (v.is_string() ? v.get<std::string>() : v.dump());
  };
  for (const auto& k : axis_order)
    if (p.count(k)) put(k, p.at(k));
  for (const auto& [k, v] : p)
    if (std::find(axis_order.begin(), axis_order.end(), k) == axis_order.end()) put(k, v);
  return os.str();
}

RunConfig run_config_of(const Point& p) {
  const auto& only_bench = benchmark_only_axes();
  json j = json::object();
  for (const auto& [axis, value] : p)
    if (std::find(only_bench.begin(), only_bench.end(), axis) == only_bench.end()) j[axis] = value;
  j["progress"] = false;
  return config_from_json(j);
}

bool primed_window_of(const Point& p) {
  if (!p.count("window_start")) return true;
  const json& v = p.at("window_start");
  if (v != "primed" && v != "cold")
    throw std::runtime_error("sweep axis window_start: " + v.dump() + " is not \"primed\" or \"cold\"");
  return v == "primed";
}

double flow_time_of(const Point& p) {
  if (!p.count("flow_time")) return kDefaultFlowTime;
  const json& v = p.at("flow_time");
  if (!v.is_number() || v.get<double>() <= 0)
    throw std::runtime_error("sweep axis flow_time: " + v.dump() + " is not a positive time in seconds");
  return v.get<double>();
}

int development_threads() {
  const long online = sysconf(_SC_NPROCESSORS_ONLN);
  return online > 0 ? static_cast<int>(online) : std::max(1, omp_get_num_procs());
}

namespace {
RunConfig develop_config(const FlowState& f) {
  RunConfig c;
  c.particles = f.n;
  c.lattice = f.lattice;
  c.h_coefficient = f.h_coefficient;
  // Every processor of the machine, whatever this process may run on: the
  // thread count is part of the snapshot's key, and omp_get_num_procs()
  // counts only the CPUs of the process's affinity mask, so a bench started
  // under `taskset -c 0` (the counters runner's concurrent valgrind jobs)
  // looked for another snapshot than an unpinned one and, missing it,
  // developed it under valgrind.
  c.threads = development_threads();
  c.progress = false;
  return c;
}

std::string cache_path(const FlowState& f, int threads, const std::string& dir) {
  std::ostringstream os;
  // v1: bump when the physics or the case changes, so old snapshots are stale.
  // The thread count of the development run is part of the key: it changes the
  // round-off of the reductions, hence the state reached.
  os << dir << "/dambreak_v1_n" << f.n << '_' << to_string(f.lattice) << "_h" << f.h_coefficient << "_t" << f.flow_time
     << "_thr" << threads << ".snap";
  return os.str();
}

/// The name snapshots had before the key held the thread count (t = 0.35 s
/// only); such a file is used only if its stored config, threads included,
/// is the wanted one, so that existing caches (77 min for N = 10^6) stay valid.
std::string legacy_cache_path(const FlowState& f, const std::string& dir) {
  std::ostringstream os;
  os << dir << "/dambreak_v1_n" << f.n << '_' << to_string(f.lattice) << "_h" << f.h_coefficient << "_t" << f.flow_time
     << ".snap";
  return os.str();
}

/// Whether `path` holds the state `cfg` reaches at `flow_time` (same case,
/// physics and thread count, stored time at or just past flow_time; keys
/// added to the config since it was written count at their defaults).
bool snapshot_fresh(const std::string& path, const RunConfig& cfg, double flow_time) {
  if (!std::filesystem::exists(path)) return false;
  try {
    const SnapshotInfo info = read_snapshot_info(path);
    return info.time >= flow_time && snapshot_config_matches(info.config_json, cfg);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "sphnl_bench: %s; rebuilding it\n", e.what());
    return false;
  }
}
}  // namespace

const Simulation& developed_flow(const FlowState& state, const std::vector<double>& also_times,
                                 const std::string& cache_dir) {
  static std::map<std::string, std::unique_ptr<Simulation>> cache;
  const RunConfig cfg = develop_config(state);
  std::string path = cache_path(state, cfg.threads, cache_dir);
  auto& slot = cache[path];
  if (slot) return *slot;
  bool fresh = snapshot_fresh(path, cfg, state.flow_time);
  if (!fresh && state.flow_time == kDefaultFlowTime) {
    const std::string legacy = legacy_cache_path(state, cache_dir);
    if ((fresh = snapshot_fresh(legacy, cfg, state.flow_time))) path = legacy;
  }
  if (!fresh) {
    // Develop from t = 0 once, saving every missing snapshot of this case on the way.
    std::vector<std::pair<double, std::string>> due;
    for (double t : also_times) {
      FlowState other = state;
      other.flow_time = t;
      const std::string p = cache_path(other, cfg.threads, cache_dir);
      if (t != state.flow_time && !snapshot_fresh(p, cfg, t)) due.emplace_back(t, p);
    }
    due.emplace_back(state.flow_time, path);
    std::sort(due.begin(), due.end());
    Simulation sim(cfg);
    std::fprintf(stderr, "sphnl_bench: developing the dam-break flow for N=%zu to t=%.2f s on %d threads (once; cached in %s)\n",
                 sim.particles().size(), due.back().first, cfg.threads, cache_dir.c_str());
    std::filesystem::create_directories(cache_dir);
    for (const auto& [t, p] : due) {
      while (sim.time() < t) sim.step();
      save_snapshot(p, sim);
    }
    std::fprintf(stderr, "sphnl_bench: developed in %ld steps, %.1f s wall\n", sim.steps_done(), sim.phase_times().total());
  }
  RunConfig same_case = cfg;
  same_case.dx = read_snapshot_info(path).dx;  // skips the search for dx; the case is checked above
  slot = std::make_unique<Simulation>(same_case);
  load_snapshot(path, *slot);
  return *slot;
}

__attribute__((noinline)) void timed_window(Simulation& sim, int steps, std::size_t& max_nl_bytes) {
  for (int s = 0; s < steps; ++s) {
    sim.step();
    max_nl_bytes = std::max(max_nl_bytes, sim.neighbour_bytes());  // a few capacity reads
  }
}

long next_run_sequence() {
  static long next = 0;  // benchmarks run one at a time (no ->Threads())
  return next++;
}

double peak_rss_bytes() { return peak_resident_bytes(); }  // not ru_maxrss: see memory_estimate.hpp

ProcessFaults process_faults() {
  ProcessFaults f;
  rusage u{};
  if (getrusage(RUSAGE_SELF, &u) == 0) f = {static_cast<double>(u.ru_minflt), static_cast<double>(u.ru_majflt)};
  return f;
}

}  // namespace sphnl::bench
