#pragma once
// Kernel gradient correction (KGC, Bonet & Lok 1999; docs/PHYSICS.md): the second
// loop over the pairs of a step that paper §3.4 / Fig. 17 measures. A pre-pass
// accumulates M_a = sum_b V_b (r_b - r_a) (x) grad_a W_ab over the same pairs as
// the main loop; L_a = M_a^-1 then corrects grad_a W_ab in ForceOp<true>.
#include <cmath>
#include <cstddef>
#include <cstdint>

#include "sphnl/neighbours/pair_filter.hpp"
#include "sphnl/neighbours/pair_operation.hpp"
#include "sphnl/particle_view.hpp"
#include "sphnl/particles.hpp"
#include "sphnl/physics.hpp"

namespace sphnl {

/// Pair operation of the KGC pre-pass. With grad_a W_ab = F r_ab (r_ab = r_a - r_b)
/// both contributions are symmetric: M_a += -V_b F r_ab (x) r_ab and
/// M_b += -V_a F r_ab (x) r_ab (grad_b W_ba = -F r_ab, r_a - r_b = r_ab).
/// `Simd` = false: the loop over the neighbours stays scalar (`simd=off`).
template <bool Simd = true>
struct KgcMatrixPass {
  static constexpr unsigned kFields = fields::position | fields::mass_rho | fields::kgc_m_out;
  const PhysicsParams* phys = nullptr;

  void interact(const ParticleView& v, std::uint32_t i, const std::uint32_t* __restrict js, int n) {
    const CubicSpline k = phys->kernel;  // a local copy: the stores below cannot alias it
    const Home a(v, i);
    double mxx = 0, mxy = 0, mxz = 0, myy = 0, myz = 0, mzz = 0;
#pragma omp simd reduction(+ : mxx, mxy, mxz, myy, myz, mzz) if(simd : Simd)
    for (int p = 0; p < n; ++p) {
      const Terms t = pair(k, a, v, gather_index(js[p]), true);
      mxx += t.m[0]; mxy += t.m[1]; mxz += t.m[2]; myy += t.m[3]; myz += t.m[4]; mzz += t.m[5];
    }
    const double sums[6] = {mxx, mxy, mxz, myy, myz, mzz};
    for (int c = 0; c < 6; ++c) v.m_kgc[c][i] += sums[c];
  }

  /// `pair_loop=masked` on a Verlet list: as ForceOp::interact_candidates.
  int interact_candidates(const ParticleView& v, std::uint32_t i, const std::uint32_t* __restrict js, int n,
                          double support2) {
    const CubicSpline k = phys->kernel;
    const Home a(v, i);
    double mxx = 0, mxy = 0, mxz = 0, myy = 0, myz = 0, mzz = 0, pairs = 0;
#pragma omp simd reduction(+ : mxx, mxy, mxz, myy, myz, mzz, pairs) if(simd : Simd)
    for (int p = 0; p < n; ++p) {
      const std::int32_t j = gather_index(js[p]);
      const double r2 = distance2(a.x - v.x[j], a.y - v.y[j], a.z - v.z[j]);
      const bool live = (r2 < support2) & (r2 > CubicSpline::kMinR2);  // filter_list's test
      const Terms t = pair(k, a, v, j, live);
      mxx += t.m[0]; mxy += t.m[1]; mxz += t.m[2]; myy += t.m[3]; myz += t.m[4]; mzz += t.m[5];
      pairs += live ? 1.0 : 0.0;
    }
    const double sums[6] = {mxx, mxy, mxz, myy, myz, mzz};
    for (int c = 0; c < 6; ++c) v.m_kgc[c][i] += sums[c];
    return static_cast<int>(pairs);
  }

  /// `pair_loop=masked`: as ForceOp::interact_blocks.
  void interact_blocks(const ParticleView& v, std::uint32_t i, const std::uint32_t* __restrict first,
                       const std::uint8_t* __restrict lanes, int blocks) {
    const CubicSpline k = phys->kernel;
    const Home a(v, i);
    double acc[6][kPairBlock] = {};
    using Lane = BlockLane<double>;
    for_each_block_lane<Simd, double>(first, lanes, blocks, [&](Lane p, std::size_t j, bool live) SPHNL_INLINE_LANE {
      const Terms t = pair(k, a, v, j, live);
      for (int c = 0; c < 6; ++c) acc[c][p] += t.m[c];
    });
    for (int c = 0; c < 6; ++c) {
      double sum = 0;
      for (int p = 0; p < kPairBlock; ++p) sum += acc[c][p];
      v.m_kgc[c][i] += sum;
    }
  }

 private:
  struct Home {
    double x, y, z, volume;
    Home(const ParticleView& v, std::uint32_t i) : x(v.x[i]), y(v.y[i]), z(v.z[i]), volume(v.mass[i] / v.rho[i]) {}
  };
  struct Terms {
    double m[6];  // particle i's terms of M_a: xx, xy, xz, yy, yz, zz
  };

  /// The one pair of the pre-pass, applied to j in place and returned for i;
  /// `live` false gives exact zeros (a lane of a block that is not a pair).
  template <class Index>
  [[gnu::always_inline]] static inline Terms pair(const CubicSpline& k, const Home& a, const ParticleView& v,
                                                  Index j, bool live) {
    const double dx = a.x - v.x[j], dy = a.y - v.y[j], dz = a.z - v.z[j];
    const double r = std::sqrt(live ? dx * dx + dy * dy + dz * dz : 1.0);
    const double f = live ? k.dwdr_of_q(r * k.inv_h) / r : 0.0;  // F = (dW/dr)/r
    const double vb = live ? v.mass[j] / v.rho[j] : 0.0;  // a slot past the buffer's end may hold rho = 0
    const double sa = -vb * f, sb = -a.volume * f;  // coefficients of r_ab (x) r_ab
    const double xx = dx * dx, xy = dx * dy, xz = dx * dz, yy = dy * dy, yz = dy * dz, zz = dz * dz;
    v.m_kgc[0][j] += sb * xx; v.m_kgc[1][j] += sb * xy; v.m_kgc[2][j] += sb * xz;
    v.m_kgc[3][j] += sb * yy; v.m_kgc[4][j] += sb * yz; v.m_kgc[5][j] += sb * zz;
    return Terms{{sa * xx, sa * xy, sa * xz, sa * yy, sa * yz, sa * zz}};
  }
};

using KgcMatrixOp = KgcMatrixPass<true>;
static_assert(PairOperation<KgcMatrixOp> && PairOperation<KgcMatrixPass<false>>);

/// Sum over the particles of the trace of M_a: the observable result of the
/// extra pair passes of `extra_loops` (a checksum; M_a is not applied).
/// Only particles [0, count): a distributed run's own (its ghosts' M_a are
/// partial sums, and each is some other rank's own particle).
double kgc_trace_sum(const ParticleSet& ps, std::size_t count = ~std::size_t{0});

/// Zeroes M_a of every particle before the pre-pass.
void clear_kgc_matrices(ParticleSet& ps);

/// L_a = M_a^-1 for fluid particles whose M_a is well conditioned
/// (|det M_a| > 0.01 and every |M_kk| > 0.25, docs/PHYSICS.md); L_a = I otherwise and
/// for boundary and out particles. Returns how many fluid particles fell back to I.
/// Only particles [0, count) (a distributed run's own; its ghosts get L_a from
/// their owners).
std::size_t invert_kgc_matrices(ParticleSet& ps, std::size_t count = ~std::size_t{0});

}  // namespace sphnl
