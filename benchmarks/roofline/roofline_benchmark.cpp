// sphnl_roofline: the limits of one core of this machine, the roofs of the
// roofline model the step family is placed against (docs/PERFORMANCE.md).
//   fma/double, fma/float   independent FMA chains at the vector width of the
//                           build's -march; counter gflops (GFlop/s, an FMA = 2)
//   triad                   a[i] = b[i] + s c[i], each array 4x the last-level
//                           cache; counter gbytes_per_s (STREAM's 24 B/element)
// One thread. Rates are per CPU second of the process (Google Benchmark's
// rate counters without UseRealTime): what the core does while it runs this
// thread; on a shared machine the wall seconds also hold the time the core
// was given to others. The step family's fraction of peak multiplies the
// per-core peak by its thread count. Run it under `flock
// /tmp/sphnl-timed.lock` and take the best repetition
// (--benchmark_repetitions=5): other work only ever slows a peak down.
#include <benchmark/benchmark.h>

#include <string>

#include "roofline/core_peaks.hpp"

namespace sb = sphnl::bench;

namespace {

template <double (*Kernel)(std::int64_t)>
void fma_peak(benchmark::State& state) {
  constexpr std::int64_t kRounds = 1'000'000;
  double flops = 0;
  for (auto _ : state) flops += Kernel(kRounds);
  state.counters["gflops"] = benchmark::Counter(flops * 1e-9, benchmark::Counter::kIsRate);
  state.counters["vector_bits"] = sb::fma_vector_bits();
  state.counters["fused"] = sb::fma_fused() ? 1 : 0;
}

void triad(benchmark::State& state) {
  sb::Triad t(sb::triad_elements());
  t.run();  // first touch outside the timing
  double bytes = 0;
  for (auto _ : state) bytes += t.run();
  state.counters["gbytes_per_s"] = benchmark::Counter(bytes * 1e-9, benchmark::Counter::kIsRate);
  state.counters["array_bytes"] = static_cast<double>(t.elements() * sizeof(double));
  state.counters["llc_bytes"] = static_cast<double>(sb::last_level_cache_bytes());
}

}  // namespace

BENCHMARK(fma_peak<sb::fma_flops_double>)->Name("fma/double")->Unit(benchmark::kMillisecond);
BENCHMARK(fma_peak<sb::fma_flops_float>)->Name("fma/float")->Unit(benchmark::kMillisecond);
BENCHMARK(triad)->Name("triad")->Unit(benchmark::kMillisecond);

int main(int argc, char** argv) {
  benchmark::AddCustomContext("sphnl_fma_vector_bits", std::to_string(sb::fma_vector_bits()));
  benchmark::AddCustomContext("sphnl_fma_fused", sb::fma_fused() ? "yes" : "no (multiply + add)");
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 2;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
