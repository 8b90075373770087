// The `cellindex` family: the cost of computing the cell index of every
// particle of the developed flow with one ordering (paper §3.2: "the
// calculation of the index of the cell ... is much faster (~100 times) for
// SortX than using the Z-Order solution").
#include <algorithm>
#include <memory>

#include "bench_common.hpp"
#include "bench_guard.hpp"
#include "sphnl/orderings/cell_order.hpp"
#include "sphnl/timer.hpp"

namespace sphnl::bench {

using nlohmann::json;

void register_cellindex_benchmarks(const json& sweep, const Options& opt) {
  const std::vector<std::string> axes = {"cell_order", "particles"};
  for (const Point& p : cross_product(sweep, axes)) {
    const RunConfig cfg = run_config_of(p);
    const std::string name = benchmark_name("cellindex", p, axes);
    benchmark::RegisterBenchmark(name.c_str(), [cfg, cache = opt.cache_dir, name](benchmark::State& st) {
     guarded(name, [&] {
      const long sequence = next_run_sequence();
      const Simulation& flow =
          developed_flow({cfg.particles, cfg.lattice, cfg.h_coefficient, kDefaultFlowTime}, {}, cache);
      const ParticleSet& ps = flow.particles();
      const CellGrid grid(flow.case_info().domain, 2.0 * flow.physics().h());
      auto order = make_cell_order(cfg.cell_order);
      order->setup(grid);
      std::vector<std::uint32_t> keys(ps.size());
      // One iteration = enough passes over all particles (>= 2e6 keys) to be
      // timed reliably even with --benchmark_min_time=0.
      const std::size_t passes = std::max<std::size_t>(1, 2'000'000 / ps.size());
      double seconds = 0;
      for (auto _ : st) {
        Stopwatch sw;
        for (std::size_t k = 0; k < passes; ++k) {
          order->compute_keys(grid, ps, keys);
          benchmark::DoNotOptimize(keys.data());
          benchmark::ClobberMemory();
        }
        seconds = sw.lap();
      }
      st.counters["n_particles"] = static_cast<double>(ps.size());
      st.counters["s_per_particle"] = seconds / static_cast<double>(passes * ps.size());
      st.counters["cell_keys"] = static_cast<double>(order->num_keys());
      st.counters["cells"] = static_cast<double>(grid.num_cells());
      st.counters["run_sequence"] = static_cast<double>(sequence);
     });
    });
  }
}

}  // namespace sphnl::bench
