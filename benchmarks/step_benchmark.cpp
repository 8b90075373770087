// The `step` family: a window of dam-break steps from the developed flow, for
// one combination of particles, gridder, cell order, reordering, list, n_s
// (list_steps), KGC, threads and (optional axis) the flow time the window
// starts from. Every Table I phase, memory and list counters are reported.
#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "bench_common.hpp"
#include "bench_guard.hpp"
#include "roofline/core_peaks.hpp"
#include "sphnl/pair_kernel_flops.hpp"

namespace sphnl::bench {

using nlohmann::json;

namespace {

// Name segments in this order (docs/CONTRACTS.md §2); an axis not listed comes after them.
// The optional ablation axes (README.md, "Ablations") come last; cache_model
// only in the counters family (the caches valgrind simulates).
const std::vector<std::string> kAxes = {"particles", "gridder", "cell_order", "reorder", "list", "list_steps",
                                        "kgc", "threads", "lattice", "h_coefficient", "flow_time", "window_start",
                                        "pair_loop", "simd", "skip_boundary_pairs", "gridder_a_variant",
                                        "initial_order", "extra_loops", "thread_updates", "thread_split", "precision", "inner_order",
                                        "cache_model"};

/// This core's FMA peak (GFlop/s) in the pair kernel's precision (float for
/// precision=mixed), measured once per process before its first window
/// (docs/PERFORMANCE.md: the best of 3 trials of 20 ms).
double core_fma_peak_gflops(Precision precision) {
  static const double peak_double = measure_fma_peak_double_gflops();
  if (precision == Precision::double_precision) return peak_double;
  static const double peak_float = measure_fma_peak_float_gflops();
  return peak_float;
}

void run_point(benchmark::State& state, RunConfig cfg, double flow_time, const std::vector<double>& flow_times,
               int window, const std::string& cache_dir, bool roofline, bool primed) {
  const long sequence = next_run_sequence();
  // Before the windows: measured inside the first one, the peak would be timed with it.
  const double peak = roofline ? core_fma_peak_gflops(cfg.precision) : 0.0;
  const Simulation& start =
      developed_flow({cfg.particles, cfg.lattice, cfg.h_coefficient, flow_time}, flow_times, cache_dir);
  cfg.dx = start.case_info().dx;  // the same case, without searching dx again
  Simulation sim(cfg);
  std::size_t max_bytes = 0;  // over every step of every window (docs/CONTRACTS.md §2: nl_bytes)
  // The core's speed right before and after each window (one 5 ms trial of
  // the FMA kernel each, untimed): on a shared host the core itself can slow
  // down with no steal time and cpu_time = real_time in the guest, and this
  // is the record of it for each repetition (docs/MEASUREMENT.md).
  double probe_sum = 0;
  int probes = 0;
  MachineWitness witness;  // wall-clock core and memory speed before each window (core_peaks.hpp)
  int witnesses = 0;
  double faults = 0;  // minor page faults inside the last window
  for (auto _ : state) {
    state.PauseTiming();
    sim.restore(start.particles(), start.time(), start.steps_done(), start.lost());
    if (primed) {
      // A long run's step finds its grid, lists and scratch already allocated
      // and touched; a fresh Simulation would time their first touches (at
      // 150 000 particles, a Verlet list of ~100 MB page by page). One step
      // from the same snapshot sizes them exactly as the window's first step.
      sim.step();
      sim.restore(start.particles(), start.time(), start.steps_done(), start.lost());
    }
    if (roofline) {
      const MachineWitness w = measure_machine_witness(cfg.threads);
      witness.core_gflops += w.core_gflops;
      witness.mem_gbps += w.mem_gbps;
      ++witnesses;
      probe_sum += measure_fma_peak_double_gflops(1, 0.005), ++probes;
    }
    const double faults_before = process_faults().minor;
    state.ResumeTiming();
    timed_window(sim, window, max_bytes);
    faults = process_faults().minor - faults_before;
    if (roofline) {
      state.PauseTiming();
      probe_sum += measure_fma_peak_double_gflops(1, 0.005), ++probes;
      state.ResumeTiming();
    }
  }
  // Counters describe the last window (every window times the same steps).
  const double steps = static_cast<double>(sim.steps_done() - start.steps_done());
  const double n = static_cast<double>(sim.particles().size());
  const PhaseTimes& t = sim.phase_times();
  const NeighbourStats& s = sim.neighbour_stats();
  auto& c = state.counters;
  c["n_particles"] = n;
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
  c["kernel_lanes_per_pair"] = s.kernel_lanes_per_pair();
  // Where two threads lose (docs/PERFORMANCE.md): the main pair loop's
  // region, the threads' busy seconds in it, the serial reduction after it.
  c["s_force_region"] = s.pair_region_seconds / steps;
  c["s_force_threads_busy"] = s.pair_busy_seconds / steps;
  c["s_force_reduce"] = s.pair_reduce_seconds / steps;
  c["force_busy_fraction"] =
      s.pair_region_seconds > 0 ? s.pair_busy_seconds / (cfg.threads * s.pair_region_seconds) : 0.0;
  // The force phase on the roofline (docs/PERFORMANCE.md): pairs x flops per
  // pair as the kernels' source counts them, against threads x this core's
  // FMA peak. Not in the counters family (time means nothing under valgrind).
  const int flops_per_pair = force_phase_flops_per_pair(cfg.kgc, cfg.extra_loops);
  c["flops_per_pair"] = flops_per_pair;
  if (roofline) {
    const double gflops = static_cast<double>(s.interactions) * flops_per_pair / t.force * 1e-9;
    c["force_gflops"] = gflops;
    c["fma_peak_gflops"] = peak;
    c["force_peak_fraction"] = gflops / (peak * cfg.threads);
    c["core_gflops_around_window"] = probes ? probe_sum / probes : 0.0;
    c["witness_core_gflops"] = witnesses ? witness.core_gflops / witnesses : 0.0;
    c["witness_mem_gbps"] = witnesses ? witness.mem_gbps / witnesses : 0.0;
  }
  c["vl_misses"] = static_cast<double>(s.vl_misses);
  c["extra_loop_passes"] = static_cast<double>(s.extra_loop_passes);
  c["list_bytes"] = static_cast<double>(s.max_list_bytes);
  // What the builds stored, per particle-step: the list phase's work, so its
  // seconds (and the counters family's misses) can be taken per stored pair.
  c["list_pairs_built_per_particle_step"] = static_cast<double>(s.list_pairs_built) / steps / n;
  c["forced_rebuilds"] = static_cast<double>(s.forced_rebuilds);
  c["skin_over_h"] = s.skin / sim.physics().h();
  c["snapshot_time"] = start.time();  // at or just past the requested flow_time
  c["run_sequence"] = static_cast<double>(sequence);
  c["primed_steps"] = primed ? 1.0 : 0.0;
  c["minor_faults_per_step"] = faults / steps;
}

}  // namespace

void register_step_benchmarks(const json& sweep, int window, const Options& opt, const std::string& family) {
  std::vector<double> flow_times;  // every snapshot one development run of a case can save
  for (const Point& p : cross_product(sweep, kAxes)) flow_times.push_back(flow_time_of(p));
  std::sort(flow_times.begin(), flow_times.end());
  flow_times.erase(std::unique(flow_times.begin(), flow_times.end()), flow_times.end());
  for (const Point& p : cross_product(sweep, kAxes)) {
    const RunConfig cfg = run_config_of(p);  // validates every value before anything runs
    const std::string name = benchmark_name(family, p, kAxes);
    const double flow_time = flow_time_of(p);
    const bool roofline = family != "counters";
    const bool primed = primed_window_of(p);
    benchmark::RegisterBenchmark(name.c_str(),
                                 [cfg, flow_time, flow_times, window, cache = opt.cache_dir, name, roofline,
                                  primed](benchmark::State& st) {
                                   guarded(name, [&] {
                                     run_point(st, cfg, flow_time, flow_times, window, cache, roofline, primed);
                                   });
                                 })
        ->Unit(benchmark::kMillisecond);
  }
}

}  // namespace sphnl::bench
