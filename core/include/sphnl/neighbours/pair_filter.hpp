#pragma once
// The one distance filter of every neighbour path: from candidate points, keep
// those within a radius and write only the survivors (compaction).
//
//   filter_range   candidates contiguous in a cell-gather buffer (cell-linked
//                  list, Verlet-list build): 1e-18 < r^2 < (2h)^2 and not two
//                  boundary particles (boundary-boundary pairs are never
//                  computed, docs/PHYSICS.md).
//   filter_list    candidates given by index (the Verlet-list loop).
//   append_within  candidates contiguous with their own ids, one point
//                  excluded (NeighbourSearch's full lists).
//
// Compaction defeats auto-vectorisation, so the three are written on 8
// candidates at a time with the primitives below: with AVX-512 the test runs
// in one 8-lane register and the surviving indices are compressed in a
// register; with AVX2 + FMA in two 4-lane halves, compressed by a permutation
// from a table; elsewhere a branch-free scalar loop does the same. Every path
// computes r^2 as distance2() does. `out` needs kFilterSlack entries of room
// beyond the survivors. The kind test (fluid_i + fluid_j > 0: no two boundary
// particles) holds for every candidate of a fluid home particle, so the
// vector loops of filter_range and filter_blocks run without it for those
// (one load and one comparison fewer per 8 candidates; the same survivors).
// filter_range and filter_list take `Simd` (template): false runs the scalar
// loop alone, whatever the build has (the ablation `simd=off`, README.md).
#include <array>
#include <bit>
#include <cstdint>

#if (defined(__AVX512F__) && defined(__AVX512VL__)) || (defined(__AVX2__) && defined(__FMA__))
#include <immintrin.h>
#endif
#if defined(__AVX512F__) && defined(__AVX512VL__)
#define SPHNL_FILTER_AVX512 1
#elif defined(__AVX2__) && defined(__FMA__)
#define SPHNL_FILTER_AVX2 1
#endif
#if defined(SPHNL_FILTER_AVX512) || defined(SPHNL_FILTER_AVX2)
#define SPHNL_FILTER_SIMD 1
#endif

#include "sphnl/kernel.hpp"
#include "sphnl/neighbours/distance.hpp"
#include "sphnl/neighbours/pair_operation.hpp"
#include "sphnl/particle_view.hpp"

namespace sphnl {

/// Entries a compaction may write past the last survivor (one 8-lane store).
inline constexpr int kFilterSlack = 8;

namespace simd {

#if defined(SPHNL_FILTER_SIMD)
/// Candidate indices j0 .. j0 + 7.
inline __m256i iota8(std::uint32_t j0) {
  return _mm256_add_epi32(_mm256_set1_epi32(static_cast<int>(j0)), _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7));
}
#endif

#if defined(SPHNL_FILTER_AVX512)
using Vd = __m512d;  // the lanes one comparison covers: 8 here, 4 with AVX2
inline Vd splat(double v) { return _mm512_set1_pd(v); }
/// r^2 of 8 candidates from a broadcast point, rounded as distance2().
inline __m512d distance2(__m512d xi, __m512d yi, __m512d zi, __m512d x, __m512d y, __m512d z) {
  const __m512d dx = _mm512_sub_pd(xi, x), dy = _mm512_sub_pd(yi, y), dz = _mm512_sub_pd(zi, z);
  return _mm512_fmadd_pd(dz, dz, _mm512_fmadd_pd(dy, dy, _mm512_mul_pd(dx, dx)));
}
/// base[idx[0..8)]; the masked form with a zero source keeps GCC 12 from
/// warning about an uninitialised pass-through operand.
inline __m512d gather(__m256i idx, const double* base) {
  return _mm512_mask_i32gather_pd(_mm512_setzero_pd(), 0xFF, idx, base, 8);
}
/// Writes the lanes of `ids` selected by `m` to out[0..popcount(m)).
/// Compressed in a register and stored whole (a compress-store to memory is
/// microcoded and slow on some cores); the slack absorbs the extra lanes.
inline void store_compressed(std::uint32_t* out, __m256i ids, unsigned m) {
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(out), _mm256_maskz_compress_epi32(static_cast<__mmask8>(m), ids));
}
#elif defined(SPHNL_FILTER_AVX2)
using Vd = __m256d;
inline Vd splat(double v) { return _mm256_set1_pd(v); }
/// For an 8-bit survivor mask, the lane indices of the survivors packed to the
/// front (a vpermd control), as bytes.
constexpr std::array<std::uint64_t, 256> make_compress_table() {
  std::array<std::uint64_t, 256> t{};
  for (unsigned m = 0; m < 256; ++m) {
    std::uint64_t v = 0;
    int k = 0;
    for (unsigned lane = 0; lane < 8; ++lane)
      if (m & (1u << lane)) v |= static_cast<std::uint64_t>(lane) << (8 * k++);
    t[m] = v;
  }
  return t;
}
inline constexpr auto kCompressTable = make_compress_table();

/// r^2 of 4 candidates from a broadcast point, rounded as distance2().
inline __m256d distance2(__m256d xi, __m256d yi, __m256d zi, __m256d x, __m256d y, __m256d z) {
  const __m256d dx = _mm256_sub_pd(xi, x), dy = _mm256_sub_pd(yi, y), dz = _mm256_sub_pd(zi, z);
  return _mm256_fmadd_pd(dz, dz, _mm256_fmadd_pd(dy, dy, _mm256_mul_pd(dx, dx)));
}
/// base[idx[0..4)]; the masked form with a zero source keeps GCC 12 from
/// warning about an uninitialised pass-through operand.
inline __m256d gather(__m128i idx, const double* base) {
  return _mm256_mask_i32gather_pd(_mm256_setzero_pd(), base, idx, _mm256_castsi256_pd(_mm256_set1_epi64x(-1)), 8);
}
/// 4 bits, lane k set when its comparison holds.
inline unsigned bits(__m256d cmp) { return static_cast<unsigned>(_mm256_movemask_pd(cmp)); }
/// Writes the lanes of `ids` selected by `m` to out[0..popcount(m)); stores 8 lanes.
inline void store_compressed(std::uint32_t* out, __m256i ids, unsigned m) {
  const __m256i perm = _mm256_cvtepu8_epi32(_mm_cvtsi64_si128(static_cast<long long>(kCompressTable[m])));
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(out), _mm256_permutevar8x32_epi32(ids, perm));
}
#endif

}  // namespace simd

/// Candidates j0..j1-1 (contiguous) of particle i; writes the survivors to `out`.
/// `min_r2` < 0 keeps coincident pairs (a Verlet list stores them: they may
/// separate during the life of the list).
template <bool Simd = true>
inline int filter_range(const ParticleView& v, std::uint32_t i, std::uint32_t j0, std::uint32_t j1, double support2,
                        std::uint32_t* __restrict out, double min_r2 = CubicSpline::kMinR2) {
  const double xi = v.x[i], yi = v.y[i], zi = v.z[i], fi = v.is_fluid[i];
  int n = 0;
  std::uint32_t j = j0;
#if defined(SPHNL_FILTER_SIMD)
  [[maybe_unused]] const simd::Vd vx = simd::splat(xi), vy = simd::splat(yi), vz = simd::splat(zi);
  [[maybe_unused]] const simd::Vd vs = simd::splat(support2), vmin = simd::splat(min_r2), zero = simd::splat(0.0);
  [[maybe_unused]] __m256i idx = simd::iota8(j0);
  [[maybe_unused]] const __m256i eight = _mm256_set1_epi32(8);
#endif
#if defined(SPHNL_FILTER_AVX512)
  [[maybe_unused]] const auto blocks = [&]<bool HomeFluid>() {
    for (; j + 8 <= j1; j += 8) {
      const __m512d r2 = simd::distance2(vx, vy, vz, _mm512_loadu_pd(v.x + j), _mm512_loadu_pd(v.y + j),
                                         _mm512_loadu_pd(v.z + j));
      __mmask8 keep = _mm512_cmp_pd_mask(r2, vs, _CMP_LT_OQ) & _mm512_cmp_pd_mask(r2, vmin, _CMP_GT_OQ);
      if constexpr (!HomeFluid) keep &= _mm512_cmp_pd_mask(_mm512_loadu_pd(v.is_fluid + j), zero, _CMP_GT_OQ);
      simd::store_compressed(out + n, idx, keep);
      n += std::popcount(static_cast<unsigned>(keep));
      idx = _mm256_add_epi32(idx, eight);
    }
  };
  if constexpr (Simd) fi > 0.0 ? blocks.template operator()<true>() : blocks.template operator()<false>();
#elif defined(SPHNL_FILTER_AVX2)
  [[maybe_unused]] const auto blocks = [&]<bool HomeFluid>() {
    for (; j + 8 <= j1; j += 8) {
      unsigned keep = 0;
      for (unsigned half = 0; half < 2; ++half) {
        const std::uint32_t k = j + 4 * half;
        const __m256d r2 = simd::distance2(vx, vy, vz, _mm256_loadu_pd(v.x + k), _mm256_loadu_pd(v.y + k),
                                           _mm256_loadu_pd(v.z + k));
        __m256d ok = _mm256_and_pd(_mm256_cmp_pd(r2, vs, _CMP_LT_OQ), _mm256_cmp_pd(r2, vmin, _CMP_GT_OQ));
        if constexpr (!HomeFluid) ok = _mm256_and_pd(ok, _mm256_cmp_pd(_mm256_loadu_pd(v.is_fluid + k), zero, _CMP_GT_OQ));
        keep |= simd::bits(ok) << (4 * half);
      }
      simd::store_compressed(out + n, idx, keep);
      n += std::popcount(keep);
      idx = _mm256_add_epi32(idx, eight);
    }
  };
  if constexpr (Simd) fi > 0.0 ? blocks.template operator()<true>() : blocks.template operator()<false>();
#endif
  for (; j < j1; ++j) {
    const double r2 = distance2(xi - v.x[j], yi - v.y[j], zi - v.z[j]);
    const bool keep = (r2 < support2) & (r2 > min_r2) & (fi + v.is_fluid[j] > 0.0);
    out[n] = j;  // branch-free compaction
    n += keep;
  }
  return n;
}

/// Candidates j0..j1-1 (contiguous) of particle i, tested as filter_range does
/// (the same pairs survive), in blocks of kPairBlock from j0: writes the
/// first index and the lane mask (bit k: j + k survives) of every block with a
/// survivor, and returns how many blocks it wrote. The last block may reach
/// past j1; its lanes there are clear (the buffer has kFilterSlack entries
/// of room, so a kernel may read them).
template <bool Simd = true>
inline int filter_blocks(const ParticleView& v, std::uint32_t i, std::uint32_t j0, std::uint32_t j1, double support2,
                         std::uint32_t* __restrict block_first, std::uint8_t* __restrict block_lanes,
                         double min_r2 = CubicSpline::kMinR2) {
  const double xi = v.x[i], yi = v.y[i], zi = v.z[i], fi = v.is_fluid[i];
  int n = 0;
  std::uint32_t j = j0;
#if defined(SPHNL_FILTER_AVX512)
  if constexpr (Simd) {
    const __m512d vx = simd::splat(xi), vy = simd::splat(yi), vz = simd::splat(zi);
    const __m512d vs = simd::splat(support2), vmin = simd::splat(min_r2), zero = simd::splat(0.0);
    const auto blocks = [&]<bool HomeFluid>() {  // as in filter_range
      for (; j < j1; j += 8) {  // masked loads cover the tail
        const std::uint32_t left = j1 - j;
        const __mmask8 lanes = left >= 8 ? static_cast<__mmask8>(0xFF) : static_cast<__mmask8>((1u << left) - 1u);
        const __m512d r2 = simd::distance2(vx, vy, vz, _mm512_maskz_loadu_pd(lanes, v.x + j),
                                           _mm512_maskz_loadu_pd(lanes, v.y + j), _mm512_maskz_loadu_pd(lanes, v.z + j));
        __mmask8 keep = _mm512_mask_cmp_pd_mask(lanes, r2, vs, _CMP_LT_OQ) & _mm512_cmp_pd_mask(r2, vmin, _CMP_GT_OQ);
        if constexpr (!HomeFluid)
          keep &= _mm512_cmp_pd_mask(_mm512_maskz_loadu_pd(lanes, v.is_fluid + j), zero, _CMP_GT_OQ);
        block_first[n] = j;
        block_lanes[n] = static_cast<std::uint8_t>(keep);
        n += keep != 0;
      }
    };
    fi > 0.0 ? blocks.template operator()<true>() : blocks.template operator()<false>();
    return n;
  }
#endif
  for (; j < j1; j += kPairBlock) {
    unsigned keep = 0;
    const std::uint32_t end = j1 - j < static_cast<std::uint32_t>(kPairBlock) ? j1 : j + kPairBlock;
    for (std::uint32_t k = j; k < end; ++k) {
      const double r2 = distance2(xi - v.x[k], yi - v.y[k], zi - v.z[k]);
      keep |= static_cast<unsigned>((r2 < support2) & (r2 > min_r2) & (fi + v.is_fluid[k] > 0.0)) << (k - j);
    }
    block_first[n] = j;
    block_lanes[n] = static_cast<std::uint8_t>(keep);
    n += keep != 0;
  }
  return n;
}

/// Candidates given as a list (Verlet lists, `pair_loop=direct`); writes the
/// survivors to `out`. A Verlet list holds no boundary-boundary pair, so by
/// default only the distance is tested; `DropBoundaryPairs` also drops them,
/// as filter_range does (candidates read in place through a gridder).
/// `min_r2` as in filter_range.
template <bool Simd = true, bool DropBoundaryPairs = false>
inline int filter_list(const ParticleView& v, std::uint32_t i, const std::uint32_t* __restrict candidates, int count,
                       double support2, std::uint32_t* __restrict out, double min_r2 = CubicSpline::kMinR2) {
  const double xi = v.x[i], yi = v.y[i], zi = v.z[i];
  [[maybe_unused]] const double fi = v.is_fluid[i];
  int n = 0;
  int k = 0;
#if defined(SPHNL_FILTER_SIMD)
  [[maybe_unused]] const simd::Vd vx = simd::splat(xi), vy = simd::splat(yi), vz = simd::splat(zi);
  [[maybe_unused]] const simd::Vd vs = simd::splat(support2), vmin = simd::splat(min_r2);
  [[maybe_unused]] const simd::Vd vf = simd::splat(fi), zero = simd::splat(0.0);
#endif
#if defined(SPHNL_FILTER_AVX512)
  if constexpr (Simd) for (; k + 8 <= count; k += 8) {
    const __m256i idx = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(candidates + k));
    const __m512d r2 = simd::distance2(vx, vy, vz, simd::gather(idx, v.x), simd::gather(idx, v.y), simd::gather(idx, v.z));
    __mmask8 keep = _mm512_cmp_pd_mask(r2, vs, _CMP_LT_OQ) & _mm512_cmp_pd_mask(r2, vmin, _CMP_GT_OQ);
    if constexpr (DropBoundaryPairs)
      keep &= _mm512_cmp_pd_mask(_mm512_add_pd(vf, simd::gather(idx, v.is_fluid)), zero, _CMP_GT_OQ);
    simd::store_compressed(out + n, idx, keep);
    n += std::popcount(static_cast<unsigned>(keep));
  }
#elif defined(SPHNL_FILTER_AVX2)
  if constexpr (Simd) for (; k + 8 <= count; k += 8) {
    const __m256i idx = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(candidates + k));
    unsigned keep = 0;
    for (unsigned half = 0; half < 2; ++half) {
      const __m128i q = half ? _mm256_extracti128_si256(idx, 1) : _mm256_castsi256_si128(idx);
      const __m256d r2 = simd::distance2(vx, vy, vz, simd::gather(q, v.x), simd::gather(q, v.y), simd::gather(q, v.z));
      __m256d ok = _mm256_and_pd(_mm256_cmp_pd(r2, vs, _CMP_LT_OQ), _mm256_cmp_pd(r2, vmin, _CMP_GT_OQ));
      if constexpr (DropBoundaryPairs)
        ok = _mm256_and_pd(ok, _mm256_cmp_pd(_mm256_add_pd(vf, simd::gather(q, v.is_fluid)), zero, _CMP_GT_OQ));
      keep |= simd::bits(ok) << (4 * half);
    }
    simd::store_compressed(out + n, idx, keep);
    n += std::popcount(keep);
  }
#endif
  for (; k < count; ++k) {
    const std::uint32_t j = candidates[k];
    const double r2 = distance2(xi - v.x[j], yi - v.y[j], zi - v.z[j]);
    out[n] = j;
    if constexpr (DropBoundaryPairs)
      n += (r2 < support2) & (r2 > min_r2) & (fi + v.is_fluid[j] > 0.0);
    else
      n += (r2 < support2) & (r2 > min_r2);
  }
  return n;
}

/// Tests candidates 0..count-1 (coordinates x, y, z; ids id) against the point
/// (xi, yi, zi) and appends the id of every one with r^2 < r2max, except
/// candidate `self` (the point itself; >= count when absent), to `out`.
/// Returns the new end.
inline std::uint32_t* append_within(double xi, double yi, double zi, const double* __restrict x,
                                    const double* __restrict y, const double* __restrict z,
                                    const std::uint32_t* __restrict id, std::uint32_t count, std::uint32_t self,
                                    double r2max, std::uint32_t* __restrict out) {
  std::uint32_t j = 0;
#if defined(SPHNL_FILTER_SIMD)
  const simd::Vd vx = simd::splat(xi), vy = simd::splat(yi), vz = simd::splat(zi), vr = simd::splat(r2max);
#endif
#if defined(SPHNL_FILTER_AVX512)
  // Masked loads cover the tail too: no scalar loop.
  for (; j < count; j += 8) {
    const std::uint32_t left = count - j;
    const __mmask8 lanes = left >= 8 ? static_cast<__mmask8>(0xFF) : static_cast<__mmask8>((1u << left) - 1u);
    const __m512d d2 = simd::distance2(vx, vy, vz, _mm512_maskz_loadu_pd(lanes, x + j), _mm512_maskz_loadu_pd(lanes, y + j),
                                       _mm512_maskz_loadu_pd(lanes, z + j));
    unsigned m = _mm512_mask_cmp_pd_mask(lanes, d2, vr, _CMP_LT_OQ);
    if (self - j < 8u) m &= ~(1u << (self - j));
    simd::store_compressed(out, _mm256_maskz_loadu_epi32(lanes, id + j), m);
    out += std::popcount(m);
  }
#elif defined(SPHNL_FILTER_AVX2)
  for (; j + 8 <= count; j += 8) {
    unsigned m = 0;
    for (unsigned half = 0; half < 2; ++half) {
      const std::uint32_t k = j + 4 * half;
      const __m256d d2 = simd::distance2(vx, vy, vz, _mm256_loadu_pd(x + k), _mm256_loadu_pd(y + k), _mm256_loadu_pd(z + k));
      m |= simd::bits(_mm256_cmp_pd(d2, vr, _CMP_LT_OQ)) << (4 * half);
    }
    if (self - j < 8u) m &= ~(1u << (self - j));
    simd::store_compressed(out, _mm256_loadu_si256(reinterpret_cast<const __m256i*>(id + j)), m);
    out += std::popcount(m);
  }
#endif
  for (; j < count; ++j) {
    const double d2 = distance2(xi - x[j], yi - y[j], zi - z[j]);
    *out = id[j];  // branch-free compaction
    out += (d2 < r2max) & (j != self);
  }
  return out;
}

}  // namespace sphnl
