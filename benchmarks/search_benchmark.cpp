// The `search` family: `sphnl neighbours` as a neighbour-search library. Full
// neighbour lists (every j != i with r < R) of a simple cubic lattice of
// `particles` points with R = 2.6 spacings, the layout the search's speed is quoted for (docs/FINDINGS.md).
#include <cmath>

#include "bench_common.hpp"
#include "bench_guard.hpp"
#include "sphnl/neighbours/neighbour_search.hpp"

namespace sphnl::bench {

using nlohmann::json;

void register_search_benchmarks(const json& sweep) {
  const std::vector<std::string> axes = {"particles", "gridder", "cell_order", "reorder", "threads"};
  for (const Point& p : cross_product(sweep, axes)) {
    SearchOptions so;
    const RunConfig cfg = run_config_of(p);
    so.gridder = cfg.gridder;
    so.order = cfg.cell_order;
    so.reorder = cfg.reorder;
    const long n = cfg.particles;  // points of the cubic lattice (rounded to a cube)
    const std::string name = benchmark_name("search", p, axes);
    benchmark::RegisterBenchmark(name.c_str(), [so, n, name](benchmark::State& st) {
     guarded(name, [&] {
      const long sequence = next_run_sequence();
      const long side = std::lround(std::cbrt(static_cast<double>(n)));
      std::vector<double> x, y, z;
      for (long k = 0; k < side; ++k)
        for (long j = 0; j < side; ++j)
          for (long i = 0; i < side; ++i) {
            x.push_back(static_cast<double>(i));
            y.push_back(static_cast<double>(j));
            z.push_back(static_cast<double>(k));
          }
      NeighbourSearch search(so);
      NeighbourLists lists;
      search.run(x, y, z, 2.6, lists);  // warm-up: first touch of the list memory
      double seconds = 0;
      for (auto _ : st) {
        search.run(x, y, z, 2.6, lists);
        seconds = search.times().build + search.times().search;
      }
      st.counters["n_particles"] = static_cast<double>(x.size());
      st.counters["entries"] = static_cast<double>(lists.num_entries());
      st.counters["entries_per_s"] = static_cast<double>(lists.num_entries()) / seconds;
      st.counters["s_build"] = search.times().build;
      st.counters["s_search"] = search.times().search;
      st.counters["bytes"] = static_cast<double>(search.bytes() + lists.bytes());
      st.counters["run_sequence"] = static_cast<double>(sequence);
     });
    })->Unit(benchmark::kMillisecond)->UseRealTime();
  }
}

}  // namespace sphnl::bench
