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
//   fma/double/threads:T, triad/threads:T   the same kernels on T threads at
//                           once (OpenMP, each its own chains or arrays), per
//                           wall second (timed here, not by the library),
//                           beside one thread's rate alone measured the same
//                           way (gflops_one_thread, gbytes_per_s_one_thread):
//                           whether the machine's cores (a VM's virtual CPUs)
//                           give T times one core when all of them are busy.
#include <benchmark/benchmark.h>
#include <omp.h>

#include <algorithm>
#include <memory>
#include <string>
#include <vector>

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

/// Rate of one thread alone, per wall second, measured once per process
/// (the reference the T-thread rates are read against).
double one_thread_rate(bool fma) {
  static const double rate[2] = {
      [] {
        sb::Triad t(sb::triad_elements());
        t.run();
        double bytes = 0;
        const double t0 = omp_get_wtime();
        for (int k = 0; k < 5; ++k) bytes += t.run();
        return bytes / (omp_get_wtime() - t0);
      }(),
      [] {
        double best = 0;
        for (int k = 0; k < 3; ++k) {
          const double t0 = omp_get_wtime();
          const double flops = sb::fma_flops_double(1'000'000);
          best = std::max(best, flops / (omp_get_wtime() - t0));
        }
        return best;
      }()};
  return rate[fma ? 1 : 0];
}

/// The double FMA kernel on `threads` threads at once.
void fma_peak_threads(benchmark::State& state) {
  const int threads = static_cast<int>(state.range(0));
  constexpr std::int64_t kRounds = 1'000'000;
  double flops = 0, seconds = 0;
  for (auto _ : state) {
    double f = 0;
    const double t0 = omp_get_wtime();
#pragma omp parallel num_threads(threads) reduction(+ : f)
    f += sb::fma_flops_double(kRounds);
    seconds += omp_get_wtime() - t0;
    flops += f;
  }
  state.counters["gflops"] = seconds > 0 ? flops * 1e-9 / seconds : 0;
  state.counters["gflops_one_thread"] = one_thread_rate(true) * 1e-9;
  state.counters["threads"] = threads;
}

/// The triad on `threads` threads at once, each over its own arrays (touched
/// first by the thread that runs them).
void triad_threads(benchmark::State& state) {
  const int threads = static_cast<int>(state.range(0));
  std::vector<std::unique_ptr<sb::Triad>> arrays(static_cast<std::size_t>(threads));
#pragma omp parallel num_threads(threads)
  {
    auto t = std::make_unique<sb::Triad>(sb::triad_elements());
    t->run();
    arrays[static_cast<std::size_t>(omp_get_thread_num())] = std::move(t);
  }
  double bytes = 0, seconds = 0;
  for (auto _ : state) {
    double b = 0;
    const double t0 = omp_get_wtime();
#pragma omp parallel num_threads(threads) reduction(+ : b)
    b += arrays[static_cast<std::size_t>(omp_get_thread_num())]->run();
    seconds += omp_get_wtime() - t0;
    bytes += b;
  }
  state.counters["gbytes_per_s"] = seconds > 0 ? bytes * 1e-9 / seconds : 0;
  state.counters["gbytes_per_s_one_thread"] = one_thread_rate(false) * 1e-9;
  state.counters["threads"] = threads;
}

}  // namespace

BENCHMARK(fma_peak<sb::fma_flops_double>)->Name("fma/double")->Unit(benchmark::kMillisecond);
BENCHMARK(fma_peak<sb::fma_flops_float>)->Name("fma/float")->Unit(benchmark::kMillisecond);
BENCHMARK(triad)->Name("triad")->Unit(benchmark::kMillisecond);
BENCHMARK(fma_peak_threads)->Name("fma/double/threads")->Arg(1)->Arg(2)->UseRealTime()->Unit(benchmark::kMillisecond);
BENCHMARK(triad_threads)->Name("triad/threads")->Arg(1)->Arg(2)->UseRealTime()->Unit(benchmark::kMillisecond);

int main(int argc, char** argv) {
  benchmark::AddCustomContext("sphnl_fma_vector_bits", std::to_string(sb::fma_vector_bits()));
  benchmark::AddCustomContext("sphnl_fma_fused", sb::fma_fused() ? "yes" : "no (multiply + add)");
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 2;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
