#include "roofline/core_peaks.hpp"

#include <immintrin.h>
#include <time.h>

#include <algorithm>
#include <fstream>
#include <string>

namespace sphnl::bench {

namespace {

// One vector type per precision at the widest width the build's -march allows,
// with its multiply-add. Intrinsics rather than `a * b + c`, so that whether a
// chain link is one fused instruction does not depend on -ffp-contract.
#if defined(__AVX512F__)
constexpr int kBits = 512;
using VecD = __m512d;
using VecF = __m512;
inline VecD splat(double x) { return _mm512_set1_pd(x); }
inline VecF splat(float x) { return _mm512_set1_ps(x); }
inline VecD madd(VecD a, VecD b, VecD c) { return _mm512_fmadd_pd(a, b, c); }
inline VecF madd(VecF a, VecF b, VecF c) { return _mm512_fmadd_ps(a, b, c); }
constexpr bool kFused = true;
#elif defined(__AVX__)
constexpr int kBits = 256;
using VecD = __m256d;
using VecF = __m256;
inline VecD splat(double x) { return _mm256_set1_pd(x); }
inline VecF splat(float x) { return _mm256_set1_ps(x); }
#if defined(__FMA__)
inline VecD madd(VecD a, VecD b, VecD c) { return _mm256_fmadd_pd(a, b, c); }
inline VecF madd(VecF a, VecF b, VecF c) { return _mm256_fmadd_ps(a, b, c); }
constexpr bool kFused = true;
#else
inline VecD madd(VecD a, VecD b, VecD c) { return _mm256_add_pd(_mm256_mul_pd(a, b), c); }
inline VecF madd(VecF a, VecF b, VecF c) { return _mm256_add_ps(_mm256_mul_ps(a, b), c); }
constexpr bool kFused = false;
#endif
#else
constexpr int kBits = 128;
using VecD = __m128d;
using VecF = __m128;
inline VecD splat(double x) { return _mm_set1_pd(x); }
inline VecF splat(float x) { return _mm_set1_ps(x); }
#if defined(__FMA__)
inline VecD madd(VecD a, VecD b, VecD c) { return _mm_fmadd_pd(a, b, c); }
inline VecF madd(VecF a, VecF b, VecF c) { return _mm_fmadd_ps(a, b, c); }
constexpr bool kFused = true;
#else
inline VecD madd(VecD a, VecD b, VecD c) { return _mm_add_pd(_mm_mul_pd(a, b), c); }
inline VecF madd(VecF a, VecF b, VecF c) { return _mm_add_ps(_mm_mul_ps(a, b), c); }
constexpr bool kFused = false;
#endif
#endif

// Independent chains: a chain link waits for the previous one (FMA latency
// 4-5 cycles), so covering 2 FMA pipes needs at least 8-10 chains in flight.
// 12 fit in the 16 vector registers of AVX2 beside the two constants.
constexpr int kChains = 12;

/// acc <- acc * m + c on every chain; acc tends to its fixed point 1 (no
/// overflow, no subnormals), and the result is kept alive through an asm.
/// Every chain starts from its own value: chains that start equal compute the
/// same thing, and the compiler merges them into one (it did, after inlining
/// into sphnl_bench: one chain counted as twelve).
template <class Vec, class T>
double chains(std::int64_t rounds) {
  Vec acc[kChains];
  for (int k = 0; k < kChains; ++k) acc[k] = splat(T(1) + T(k) * T(0.001));
  const Vec m = splat(T(0.999999)), c = splat(T(0.000001));
  for (std::int64_t r = 0; r < rounds; ++r) {
#pragma GCC unroll 12
    for (int k = 0; k < kChains; ++k) acc[k] = madd(acc[k], m, c);
  }
  for (auto& a : acc) asm volatile("" : : "x"(a));
  constexpr int lanes = static_cast<int>(sizeof(Vec) / sizeof(T));
  return 2.0 * lanes * kChains * static_cast<double>(rounds);
}

}  // namespace

int fma_vector_bits() { return kBits; }
bool fma_fused() { return kFused; }

double fma_flops_double(std::int64_t rounds) { return chains<VecD, double>(rounds); }
double fma_flops_float(std::int64_t rounds) { return chains<VecF, float>(rounds); }

Triad::Triad(std::size_t elements) : a_(elements, 0.0), b_(elements, 1.0), c_(elements, 2.0) {}

double Triad::run() {
  double* __restrict a = a_.data();
  const double* __restrict b = b_.data();
  const double* __restrict c = c_.data();
  const double s = s_;
  const std::size_t n = a_.size();
  for (std::size_t i = 0; i < n; ++i) a[i] = b[i] + s * c[i];
  asm volatile("" : : "r"(a) : "memory");
  return 24.0 * static_cast<double>(n);
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

double measure_fma_peak_double_gflops(int trials, double seconds) {
  auto time = [](std::int64_t rounds, double& flops) {
    const double t0 = thread_cpu_seconds();
    flops = fma_flops_double(rounds);
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

}  // namespace sphnl::bench
