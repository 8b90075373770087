// The `step` family: a window of dam-break steps from the developed flow, for
// one combination of N, gridder, cell order, reordering, list, n_s, KGC and
// threads. Every Table I phase, memory and list counters are reported.
#include <cmath>

#include "bench_common.hpp"
#include "bench_guard.hpp"

namespace sphnl::bench {

using nlohmann::json;

namespace {

const std::vector<std::string> kAxes = {"n", "gridder", "order", "reorder", "list", "ns", "kgc", "threads", "lattice",
                                        "h_coefficient"};

RunConfig config_for(const Point& p) {
  json j = json::object();
  auto take = [&](const char* axis, const char* key) {
    if (p.count(axis)) j[key] = p.at(axis);
  };
  take("n", "particles");
  take("gridder", "gridder");
  take("order", "cell_order");
  take("reorder", "reorder");
  take("list", "list");
  take("ns", "list_steps");
  take("kgc", "kgc");
  take("threads", "threads");
  take("lattice", "lattice");
  take("h_coefficient", "h_coefficient");
  j["progress"] = false;
  return config_from_json(j);
}

void run_point(benchmark::State& state, RunConfig cfg, int window, const std::string& cache_dir) {
  const Simulation& start = developed_flow(cfg.particles, cfg.lattice, cfg.h_coefficient, cache_dir);
  cfg.dx = start.case_info().dx;  // the same case, without searching dx again
  Simulation sim(cfg);
  std::size_t max_bytes = 0;
  for (auto _ : state) {
    state.PauseTiming();
    sim.restore(start.particles(), start.time(), start.steps_done(), start.lost());
    state.ResumeTiming();
    timed_window(sim, window);
    max_bytes = std::max(max_bytes, sim.neighbour_bytes());
  }
  // Counters describe the last window (every window times the same steps).
  const double steps = static_cast<double>(sim.steps_done() - start.steps_done());
  const double n = static_cast<double>(sim.particles().size());
  const PhaseTimes& t = sim.phase_times();
  const NeighbourStats& s = sim.neighbour_stats();
  auto& c = state.counters;
  c["n"] = n;
  c["n_fluid"] = static_cast<double>(sim.case_info().n_fluid);
  c["window_steps"] = steps;
  c["s_per_step"] = t.total() / steps;
  c["s_neighbour_list"] = t.neighbour_list / steps;
  c["s_force"] = t.force / steps;
  c["s_update"] = t.update / steps;
  c["s_per_particle_step"] = t.total() / steps / n;
  c["nl_bytes"] = static_cast<double>(max_bytes);
  c["peak_rss_bytes"] = peak_rss_bytes();
  c["rebuilds"] = static_cast<double>(s.builds);
  c["mean_steps_per_list"] = s.mean_steps_per_list();
  c["max_steps_per_list"] = static_cast<double>(s.max_steps_per_list);
  c["candidates_per_particle"] = 2.0 * static_cast<double>(s.candidates) / steps / n;
  c["interactions_per_particle"] = 2.0 * static_cast<double>(s.interactions) / steps / n;
  c["pairs_per_s"] = static_cast<double>(s.interactions) / t.force;
  c["vl_misses"] = static_cast<double>(s.vl_misses);
  c["list_bytes"] = static_cast<double>(s.max_list_bytes);
  c["forced_rebuilds"] = static_cast<double>(s.forced_rebuilds);
  c["skin_over_h"] = s.skin / sim.physics().h();
}

}  // namespace

void register_step_benchmarks(const json& sweep, int window, const Options& opt) {
  for (const Point& p : cross_product(sweep, kAxes)) {
    const RunConfig cfg = config_for(p);  // validates every value before anything runs
    const std::string name = benchmark_name("step", p, kAxes);
    benchmark::RegisterBenchmark(name.c_str(),
                                 [cfg, window, cache = opt.cache_dir, name](benchmark::State& st) {
                                   guarded(name, [&] { run_point(st, cfg, window, cache); });
                                 })
        ->Unit(benchmark::kMillisecond);
  }
}

}  // namespace sphnl::bench
