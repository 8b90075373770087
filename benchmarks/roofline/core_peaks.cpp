#include "roofline/core_peaks.hpp"

#include <omp.h>
#include <time.h>

#include <algorithm>
#include <chrono>
#include <fstream>
#include <string>
#include <vector>

namespace sphnl::bench {

namespace {

// One vector type per precision at the widest width the build's -march
// allows (GCC vector extensions). `acc * m + c` is one fused instruction where
// the ISA has FMA: CMakeLists.txt compiles this file with -ffp-contract=fast,
// so that does not depend on the compiler's default.
#if defined(__AVX512F__)
constexpr int kBytes = 64;
#elif defined(__AVX__)
constexpr int kBytes = 32;
#else
constexpr int kBytes = 16;
#endif
#if defined(__FMA__) || defined(__AVX512F__)
constexpr bool kFused = true;
#else
constexpr bool kFused = false;
#endif
using VecD = double __attribute__((vector_size(kBytes)));
using VecF = float __attribute__((vector_size(kBytes)));

// Independent chains: a chain link waits for the previous one (FMA latency
// 4-5 cycles), so covering 2 FMA pipes needs at least 8-10 chains in flight.
// 12 fit in the 16 vector registers of AVX2 beside the two constants.
constexpr int kChains = 12;

/// acc <- acc * m + c on every chain; acc tends to its fixed point 1 (no
/// overflow, no subnormals), and the result is kept alive through an asm.
/// The starting values and constants pass through an empty asm, so the
/// compiler knows nothing of them: chains that start equal it merged into one
/// (after inlining into sphnl_bench: one chain counted as twelve), and a chain
/// that starts at the fixed point it folded away.
template <class Vec, class T>
double chains(std::int64_t rounds) {
  Vec acc[kChains];
  for (int k = 0; k < kChains; ++k) {
    acc[k] = Vec{} + (T(1) + T(k) * T(0.001));
    asm volatile("" : "+x"(acc[k]));
  }
  Vec m = Vec{} + T(0.999999), c = Vec{} + T(0.000001);
  asm volatile("" : "+x"(m), "+x"(c));
  for (std::int64_t r = 0; r < rounds; ++r) {
#pragma GCC unroll 12
    for (int k = 0; k < kChains; ++k) acc[k] = acc[k] * m + c;
  }
  for (auto& a : acc) asm volatile("" : : "x"(a));
  constexpr int lanes = static_cast<int>(sizeof(Vec) / sizeof(T));
  return 2.0 * lanes * kChains * static_cast<double>(rounds);
}

}  // namespace

int fma_vector_bits() { return 8 * kBytes; }
bool fma_fused() { return kFused; }

double fma_flops_double(std::int64_t rounds) { return chains<VecD, double>(rounds); }
double fma_flops_float(std::int64_t rounds) { return chains<VecF, float>(rounds); }

Triad::Triad(std::size_t elements) : a_(elements, 0.0), b_(elements, 1.0), c_(elements, 2.0) {}

double Triad::run(std::size_t begin, std::size_t end) {
  double* __restrict a = a_.data();
  const double* __restrict b = b_.data();
  const double* __restrict c = c_.data();
  const double s = s_;
  for (std::size_t i = begin; i < end; ++i) a[i] = b[i] + s * c[i];
  asm volatile("" : : "r"(a) : "memory");
  return 24.0 * static_cast<double>(end - begin);
}

std::size_t last_level_cache_bytes() {
  std::size_t best = 0;
  for (int index = 0; index < 8; ++index) {
    std::ifstream in("/sys/devices/system/cpu/cpu0/cache/index" + std::to_string(index) + "/size");
    std::string size;
    if (!(in >> size) || size.empty()) continue;
    std::size_t value = std::stoul(size);
    const char unit = size.back();
    if (unit == 'K') value <<= 10;
    else if (unit == 'M') value <<= 20;
    best = std::max(best, value);
  }
  return best > 0 ? best : std::size_t{32} << 20;
}

std::size_t triad_elements() { return 4 * last_level_cache_bytes() / sizeof(double); }

double thread_cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

namespace {
/// The best of `trials` runs of about `seconds` of thread CPU time of `kernel`.
double best_gflops(double (*kernel)(std::int64_t), int trials, double seconds) {
  auto time = [kernel](std::int64_t rounds, double& flops) {
    const double t0 = thread_cpu_seconds();
    flops = kernel(rounds);
    return thread_cpu_seconds() - t0;
  };
  // Size the trials: rounds that take about `seconds` at the speed of a first short run.
  double flops = 0;
  std::int64_t rounds = 100'000;
  const double t = time(rounds, flops);
  rounds = std::max<std::int64_t>(rounds, static_cast<std::int64_t>(static_cast<double>(rounds) * seconds / std::max(t, 1e-6)));
  double best = 0;
  for (int k = 0; k < trials; ++k) {
    const double s = time(rounds, flops);
    best = std::max(best, flops / s * 1e-9);
  }
  return best;
}
}  // namespace

double measure_fma_peak_double_gflops(int trials, double seconds) {
  return best_gflops(fma_flops_double, trials, seconds);
}

double measure_fma_peak_float_gflops(int trials, double seconds) {
  return best_gflops(fma_flops_float, trials, seconds);
}

MachineWitness measure_machine_witness(int threads) {
  using clock = std::chrono::steady_clock;
  auto seconds_since = [](clock::time_point t0) { return std::chrono::duration<double>(clock::now() - t0).count(); };
  // 32 MiB per array: larger than a core's L2, and too large for a tenant's
  // fair share of a shared last-level cache to hold all three.
  static Triad triad(std::size_t{32} << 17);  // allocated and touched on first use
  // ~2 ms of FMA chains at this core's peak; fixed, so every witness does
  // the same work.
  constexpr std::int64_t kFmaRounds = 2'000'000;
  threads = std::max(1, threads);
  std::vector<MachineWitness> per(static_cast<std::size_t>(threads));
#pragma omp parallel num_threads(threads)
  {
    const int t = omp_get_thread_num(), team = omp_get_num_threads();
    MachineWitness& w = per[static_cast<std::size_t>(t)];
#pragma omp barrier
    auto t0 = clock::now();
    const double flops = fma_flops_double(kFmaRounds);
    w.core_gflops = flops / seconds_since(t0) * 1e-9;
    const std::size_t n = triad.elements();
    const std::size_t begin = n * static_cast<std::size_t>(t) / static_cast<std::size_t>(team);
    const std::size_t end = n * static_cast<std::size_t>(t + 1) / static_cast<std::size_t>(team);
#pragma omp barrier
    t0 = clock::now();
    const double bytes = triad.run(begin, end);
    w.mem_gbps = bytes / seconds_since(t0) * 1e-9;
  }
  MachineWitness slowest = per[0];
  for (const MachineWitness& w : per) {
    slowest.core_gflops = std::min(slowest.core_gflops, w.core_gflops);
    slowest.mem_gbps = std::min(slowest.mem_gbps, w.mem_gbps);
  }
  return slowest;
}

}  // namespace sphnl::bench
