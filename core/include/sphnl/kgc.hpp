#pragma once
// Kernel gradient correction (KGC, Bonet & Lok 1999; docs/PHYSICS.md): the second
// loop over the pairs of a step that paper §3.4 / Fig. 17 measures. A pre-pass
// accumulates M_a = sum_b V_b (r_b - r_a) (x) grad_a W_ab over the same pairs as
// the main loop; L_a = M_a^-1 then corrects grad_a W_ab in ForceOp<true>.
#include <cmath>
#include <cstddef>
#include <cstdint>

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
    const double inv_h = k.inv_h;
    const double xa = v.x[i], ya = v.y[i], za = v.z[i];
    const double va = v.mass[i] / v.rho[i];
    double mxx = 0, mxy = 0, mxz = 0, myy = 0, myz = 0, mzz = 0;
#pragma omp simd reduction(+ : mxx, mxy, mxz, myy, myz, mzz) if(simd : Simd)
    for (int p = 0; p < n; ++p) {
      const std::uint32_t j = js[p];
      const double dx = xa - v.x[j], dy = ya - v.y[j], dz = za - v.z[j];
      const double r = std::sqrt(dx * dx + dy * dy + dz * dz);
      const double f = k.dwdr_of_q(r * inv_h) / r;  // F = (dW/dr)/r
      const double vb = v.mass[j] / v.rho[j];
      const double sa = -vb * f, sb = -va * f;  // coefficients of r_ab (x) r_ab
      const double xx = dx * dx, xy = dx * dy, xz = dx * dz, yy = dy * dy, yz = dy * dz, zz = dz * dz;
      mxx += sa * xx; mxy += sa * xy; mxz += sa * xz; myy += sa * yy; myz += sa * yz; mzz += sa * zz;
      v.m_kgc[0][j] += sb * xx; v.m_kgc[1][j] += sb * xy; v.m_kgc[2][j] += sb * xz;
      v.m_kgc[3][j] += sb * yy; v.m_kgc[4][j] += sb * yz; v.m_kgc[5][j] += sb * zz;
    }
    v.m_kgc[0][i] += mxx; v.m_kgc[1][i] += mxy; v.m_kgc[2][i] += mxz;
    v.m_kgc[3][i] += myy; v.m_kgc[4][i] += myz; v.m_kgc[5][i] += mzz;
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
