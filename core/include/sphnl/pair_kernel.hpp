#pragma once
// The one pair kernel: the physics of a pair (a, b) with r_ab < 2h, evaluated
// once per pair and applied to both particles (symmetric, as SPHysics does).
// Pair sources (cell-linked list, Verlet lists) only decide WHICH pairs; this
// file alone decides what a pair computes. Equations: momentum (eq. 2) with the
// tensile correction and artificial viscosity (eq. 3), continuity (eq. 4),
// XSPH (eq. 6); the viscous term of the time step (eq. 7) is reduced here.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <type_traits>

#include "sphnl/neighbours/pair_operation.hpp"
#include "sphnl/particle_view.hpp"
#include "sphnl/physics.hpp"

namespace sphnl {

/// Pair operation of the main loop. `Kgc` selects the corrected gradients
/// L_a grad_a W_ab (Bonet & Lok 1999) in pressure, viscosity and continuity.
/// `Simd` = false keeps the compiler from vectorising the loop over the
/// neighbours (the ablation `simd=off`, README.md); the arithmetic is the same.
/// `Real` is the arithmetic of the pair (the option `precision`): double, or
/// float for `precision=mixed`. In mixed precision the kernel, the pressure,
/// viscosity and XSPH terms of the pair are float, and the operation reads
/// what it is given: from the cell-linked list a ParticleViewF (the gather
/// buffer's float copy, positions relative to its first entry, so float
/// keeps nearby particles' differences to a few 1e-9 m), its partial sums over one
/// home cell's pairs then float, added to the particles' double totals once
/// per home cell; from a Verlet list the particles' own double arrays, the
/// differences taken in double and rounded to float, the sums double. The
/// time integration is double in both.
template <bool Kgc, bool Simd = true, class Real = double>
struct ForceOp {
  static constexpr unsigned kFields = fields::position | fields::mass_rho | fields::force_in | fields::force_out |
                                     (Kgc ? fields::kgc_l : 0u) |
                                     (std::is_same_v<Real, float> ? fields::float_copy : 0u);
  const PhysicsParams* phys = nullptr;
  double max_mu = 0;  // max_ab |h v_ab . r_ab / (r^2 + eta^2)|, for dt_cv (eq. 7)

  /// Particle i interacts with js[0..n) (all distinct, all with r < 2h).
  template <class T>
  void interact(const BasicParticleView<T>& v, std::uint32_t i, const std::uint32_t* __restrict js, int n) {
    using R = Real;
    using Sum = T;  // the view's own type: double sums for double views, float partial sums for the buffer's copy
    const CubicSpline k = phys->kernel;  // a local copy: the stores below cannot alias it
    const R h = static_cast<R>(k.h), inv_h = static_cast<R>(k.inv_h);
    const R inv_w_dp = static_cast<R>(k.inv_w_dp), eta2 = static_cast<R>(phys->eta2);
    const R alpha = static_cast<R>(phys->alpha), eps = static_cast<R>(phys->xsph_epsilon);
    const T xa = v.x[i], ya = v.y[i], za = v.z[i];
    const T vxa = v.vx[i], vya = v.vy[i], vza = v.vz[i];
    const R rhoa = static_cast<R>(v.rho[i]), ma = static_cast<R>(v.mass[i]);
    const R pra = static_cast<R>(v.p_over_rho2[i]), ra = static_cast<R>(v.tensile_r[i]);
    const R ca = static_cast<R>(v.sound_speed[i]), fluid_a = static_cast<R>(v.is_fluid[i]);
    R la[6] = {1, 0, 0, 1, 0, 1};
    if constexpr (Kgc)
      for (int c = 0; c < 6; ++c) la[c] = static_cast<R>(v.kgc[c][i]);

    Sum axa = 0, aya = 0, aza = 0, drhoa = 0, uxa = 0, uya = 0, uza = 0;
    R mu_max = static_cast<R>(max_mu);
#pragma omp simd reduction(+ : axa, aya, aza, drhoa, uxa, uya, uza) reduction(max : mu_max) if(simd : Simd)
    for (int p = 0; p < n; ++p) {
      const std::uint32_t j = js[p];
      const R dx = static_cast<R>(xa - v.x[j]), dy = static_cast<R>(ya - v.y[j]), dz = static_cast<R>(za - v.z[j]);
      const R r2 = dx * dx + dy * dy + dz * dz;
      const R r = std::sqrt(r2), inv_r = R(1) / r;
      const R q = r * inv_h;
      // Kernel (eq. 1) and F = (dW/dr)/r; both branches computed, then selected.
      const R w = k.w_of_q(q);
      const R f = k.dwdr_of_q(q) * inv_r;
      // Tensile correction (Monaghan 2000): (R_a + R_b) (W/W(dp))^4, plain W.
      const R fw = w * inv_w_dp, fw2 = fw * fw;
      const R dvx = static_cast<R>(vxa - v.vx[j]), dvy = static_cast<R>(vya - v.vy[j]),
              dvz = static_cast<R>(vza - v.vz[j]);
      const R vdotr = dvx * dx + dvy * dy + dvz * dz;
      const R mu = h * vdotr / (r2 + eta2);
      const R rho_bar = R(0.5) * (rhoa + static_cast<R>(v.rho[j]));
      const R inv_rho_bar = R(1) / rho_bar;
      // Artificial viscosity (eq. 3), beta = 0: only approaching pairs.
      const R pi_ab = vdotr < R(0) ? -alpha * R(0.5) * (ca + static_cast<R>(v.sound_speed[j])) * mu * inv_rho_bar : R(0);
      const R pterm = pra + static_cast<R>(v.p_over_rho2[j]) + (ra + static_cast<R>(v.tensile_r[j])) * fw2 * fw2 + pi_ab;
      mu_max = std::max(mu_max, std::fabs(mu));

      const R gx = f * dx, gy = f * dy, gz = f * dz;  // grad_a W_ab = -grad_b W_ba
      R gax = gx, gay = gy, gaz = gz, gbx = gx, gby = gy, gbz = gz;
      if constexpr (Kgc) {  // L_a grad_a W_ab for a, -(L_b grad_b W_ba) for b
        gax = la[0] * gx + la[1] * gy + la[2] * gz;
        gay = la[1] * gx + la[3] * gy + la[4] * gz;
        gaz = la[2] * gx + la[4] * gy + la[5] * gz;
        const R lb0 = static_cast<R>(v.kgc[0][j]), lb1 = static_cast<R>(v.kgc[1][j]), lb2 = static_cast<R>(v.kgc[2][j]);
        const R lb3 = static_cast<R>(v.kgc[3][j]), lb4 = static_cast<R>(v.kgc[4][j]), lb5 = static_cast<R>(v.kgc[5][j]);
        gbx = lb0 * gx + lb1 * gy + lb2 * gz;
        gby = lb1 * gx + lb3 * gy + lb4 * gz;
        gbz = lb2 * gx + lb4 * gy + lb5 * gz;
      }
      const R mb = static_cast<R>(v.mass[j]);
      // Momentum (eq. 2): a_a -= m_b T grad_a W_ab,  a_b -= m_a T grad_b W_ba.
      const R tb = mb * pterm, ta = ma * pterm;
      axa -= tb * gax; aya -= tb * gay; aza -= tb * gaz;
      v.ax[j] += ta * gbx; v.ay[j] += ta * gby; v.az[j] += ta * gbz;
      // Continuity (eq. 4): v_ba . grad_b W_ba = v_ab . (-grad_b W_ba).
      drhoa += mb * (dvx * gax + dvy * gay + dvz * gaz);
      v.drho[j] += ma * (dvx * gbx + dvy * gby + dvz * gbz);
      // XSPH (eq. 6) between fluid particles only: walls must not drag the
      // positions of the fluid (as in SPHysics and DualSPHysics).
      const R xs = eps * w * inv_rho_bar * fluid_a * static_cast<R>(v.is_fluid[j]);
      const R xb = mb * xs, xa_ = ma * xs;
      uxa -= xb * dvx; uya -= xb * dvy; uza -= xb * dvz;
      v.ux[j] += xa_ * dvx; v.uy[j] += xa_ * dvy; v.uz[j] += xa_ * dvz;
    }
    v.ax[i] += axa; v.ay[i] += aya; v.az[i] += aza; v.drho[i] += drhoa;
    v.ux[i] += uxa; v.uy[i] += uya; v.uz[i] += uza;
    max_mu = mu_max;
  }
};

static_assert(PairOperation<ForceOp<false>> && PairOperation<ForceOp<true>> && PairOperation<ForceOp<false, false>> &&
              PairOperation<ForceOp<false, true, float>>);

}  // namespace sphnl
