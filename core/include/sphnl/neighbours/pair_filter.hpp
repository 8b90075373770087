#pragma once
// The distance test shared by every pair source: from candidate particles,
// keep those with 1e-18 < r^2 < (2h)^2 that are not two boundary particles
// (boundary-boundary pairs are never computed, PHYSICS.md).
//
// Compaction (writing only the survivors) defeats auto-vectorisation, so with
// AVX-512 the test runs on 8 candidates at once and compresses the surviving
// indices in a register; elsewhere a branch-free scalar loop does the same.
// `out` needs room for count + kFilterSlack entries.
#include <cstdint>

#if defined(__AVX512F__) && defined(__AVX512VL__)
#include <immintrin.h>
#define SPHNL_FILTER_AVX512 1
#endif

#include "sphnl/kernel.hpp"
#include "sphnl/particle_view.hpp"

namespace sphnl {

inline constexpr int kFilterSlack = 8;

#ifdef SPHNL_FILTER_AVX512
/// base[idx[0..8)]; the masked form with a zero source keeps GCC 12 from
/// warning about an uninitialised pass-through operand.
inline __m512d gather(__m256i idx, const double* base) {
  return _mm512_mask_i32gather_pd(_mm512_setzero_pd(), 0xFF, idx, base, 8);
}
#endif

/// Candidates j0..j1-1 (contiguous) of particle i; writes the survivors to `out`.
/// `min_r2` < 0 keeps coincident pairs (a Verlet list stores them: they may
/// separate during the life of the list).
inline int filter_range(const ParticleView& v, std::uint32_t i, std::uint32_t j0, std::uint32_t j1, double support2,
                        std::uint32_t* __restrict out, double min_r2 = CubicSpline::kMinR2) {
  const double xi = v.x[i], yi = v.y[i], zi = v.z[i], fi = v.is_fluid[i];
  int n = 0;
  std::uint32_t j = j0;
#ifdef SPHNL_FILTER_AVX512
  const __m512d vx = _mm512_set1_pd(xi), vy = _mm512_set1_pd(yi), vz = _mm512_set1_pd(zi);
  const __m512d vs = _mm512_set1_pd(support2), vmin = _mm512_set1_pd(min_r2);
  const __m512d vf = _mm512_set1_pd(fi), zero = _mm512_setzero_pd();
  __m256i idx = _mm256_add_epi32(_mm256_set1_epi32(static_cast<int>(j0)), _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7));
  const __m256i eight = _mm256_set1_epi32(8);
  for (; j + 8 <= j1; j += 8) {
    const __m512d dx = _mm512_sub_pd(vx, _mm512_loadu_pd(v.x + j));
    const __m512d dy = _mm512_sub_pd(vy, _mm512_loadu_pd(v.y + j));
    const __m512d dz = _mm512_sub_pd(vz, _mm512_loadu_pd(v.z + j));
    const __m512d r2 = _mm512_fmadd_pd(dz, dz, _mm512_fmadd_pd(dy, dy, _mm512_mul_pd(dx, dx)));
    const __m512d fluid = _mm512_add_pd(vf, _mm512_loadu_pd(v.is_fluid + j));
    const __mmask8 keep = _mm512_cmp_pd_mask(r2, vs, _CMP_LT_OQ) & _mm512_cmp_pd_mask(r2, vmin, _CMP_GT_OQ) &
                          _mm512_cmp_pd_mask(fluid, zero, _CMP_GT_OQ);
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(out + n), _mm256_maskz_compress_epi32(keep, idx));
    n += __builtin_popcount(keep);
    idx = _mm256_add_epi32(idx, eight);
  }
#endif
  for (; j < j1; ++j) {
    const double dx = xi - v.x[j], dy = yi - v.y[j], dz = zi - v.z[j];
    const double r2 = dx * dx + dy * dy + dz * dz;
    const bool keep = (r2 < support2) & (r2 > min_r2) & (fi + v.is_fluid[j] > 0.0);
    out[n] = j;  // branch-free compaction
    n += keep;
  }
  return n;
}

/// Candidates given as a list (Verlet lists); writes the survivors to `out`.
/// The list holds no boundary-boundary pair, so only the distance is tested.
inline int filter_list(const ParticleView& v, std::uint32_t i, const std::uint32_t* __restrict candidates, int count,
                       double support2, std::uint32_t* __restrict out) {
  const double xi = v.x[i], yi = v.y[i], zi = v.z[i];
  int n = 0;
  int k = 0;
#ifdef SPHNL_FILTER_AVX512
  const __m512d vx = _mm512_set1_pd(xi), vy = _mm512_set1_pd(yi), vz = _mm512_set1_pd(zi);
  const __m512d vs = _mm512_set1_pd(support2), vmin = _mm512_set1_pd(CubicSpline::kMinR2);
  for (; k + 8 <= count; k += 8) {
    const __m256i idx = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(candidates + k));
    const __m512d dx = _mm512_sub_pd(vx, gather(idx, v.x));
    const __m512d dy = _mm512_sub_pd(vy, gather(idx, v.y));
    const __m512d dz = _mm512_sub_pd(vz, gather(idx, v.z));
    const __m512d r2 = _mm512_fmadd_pd(dz, dz, _mm512_fmadd_pd(dy, dy, _mm512_mul_pd(dx, dx)));
    const __mmask8 keep = _mm512_cmp_pd_mask(r2, vs, _CMP_LT_OQ) & _mm512_cmp_pd_mask(r2, vmin, _CMP_GT_OQ);
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(out + n), _mm256_maskz_compress_epi32(keep, idx));
    n += __builtin_popcount(keep);
  }
#endif
  for (; k < count; ++k) {
    const std::uint32_t j = candidates[k];
    const double dx = xi - v.x[j], dy = yi - v.y[j], dz = zi - v.z[j];
    const double r2 = dx * dx + dy * dy + dz * dz;
    out[n] = j;
    n += (r2 < support2) & (r2 > CubicSpline::kMinR2);
  }
  return n;
}

}  // namespace sphnl
