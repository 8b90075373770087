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

#include "sphnl/neighbours/pair_operation.hpp"
#include "sphnl/particle_view.hpp"
#include "sphnl/physics.hpp"

namespace sphnl {

/// Pair operation of the main loop. `Kgc` selects the corrected gradients
/// L_a grad_a W_ab (Bonet & Lok 1999) in pressure, viscosity and continuity.
/// `Simd` = false keeps the compiler from vectorising the loop over the
/// neighbours (the ablation `simd=off`, README.md); the arithmetic is the same.
template <bool Kgc, bool Simd = true>
struct ForceOp {
  static constexpr unsigned kFields = fields::position | fields::mass_rho | fields::force_in | fields::force_out |
                                     (Kgc ? fields::kgc_l : 0u);
  const PhysicsParams* phys = nullptr;
  double max_mu = 0;  // max_ab |h v_ab . r_ab / (r^2 + eta^2)|, for dt_cv (eq. 7)

  /// Particle i interacts with js[0..n) (all distinct, all with r < 2h).
  void interact(const ParticleView& v, std::uint32_t i, const std::uint32_t* __restrict js, int n) {
    const CubicSpline k = phys->kernel;  // a local copy: the stores below cannot alias it
    const double h = k.h, inv_h = k.inv_h;
    const double inv_w_dp = k.inv_w_dp, eta2 = phys->eta2, alpha = phys->alpha, eps = phys->xsph_epsilon;
    const double xa = v.x[i], ya = v.y[i], za = v.z[i];
    const double vxa = v.vx[i], vya = v.vy[i], vza = v.vz[i];
    const double rhoa = v.rho[i], ma = v.mass[i], pra = v.p_over_rho2[i], ra = v.tensile_r[i];
    const double ca = v.sound_speed[i], fluid_a = v.is_fluid[i];
    double la[6] = {1, 0, 0, 1, 0, 1};
    if constexpr (Kgc)
      for (int c = 0; c < 6; ++c) la[c] = v.kgc[c][i];

    double axa = 0, aya = 0, aza = 0, drhoa = 0, uxa = 0, uya = 0, uza = 0, mu_max = max_mu;
#pragma omp simd reduction(+ : axa, aya, aza, drhoa, uxa, uya, uza) reduction(max : mu_max) if(simd : Simd)
    for (int p = 0; p < n; ++p) {
      const std::uint32_t j = js[p];
      const double dx = xa - v.x[j], dy = ya - v.y[j], dz = za - v.z[j];
      const double r2 = dx * dx + dy * dy + dz * dz;
      const double r = std::sqrt(r2), inv_r = 1.0 / r;
      const double q = r * inv_h;
      // Kernel (eq. 1) and F = (dW/dr)/r; both branches computed, then selected.
      const double w = k.w_of_q(q);
      const double f = k.dwdr_of_q(q) * inv_r;
      // Tensile correction (Monaghan 2000): (R_a + R_b) (W/W(dp))^4, plain W.
      const double fw = w * inv_w_dp, fw2 = fw * fw;
      const double dvx = vxa - v.vx[j], dvy = vya - v.vy[j], dvz = vza - v.vz[j];
      const double vdotr = dvx * dx + dvy * dy + dvz * dz;
      const double mu = h * vdotr / (r2 + eta2);
      const double rho_bar = 0.5 * (rhoa + v.rho[j]);
      const double inv_rho_bar = 1.0 / rho_bar;
      // Artificial viscosity (eq. 3), beta = 0: only approaching pairs.
      const double pi_ab = vdotr < 0.0 ? -alpha * 0.5 * (ca + v.sound_speed[j]) * mu * inv_rho_bar : 0.0;
      const double pterm = pra + v.p_over_rho2[j] + (ra + v.tensile_r[j]) * fw2 * fw2 + pi_ab;
      mu_max = std::max(mu_max, std::fabs(mu));

      const double gx = f * dx, gy = f * dy, gz = f * dz;  // grad_a W_ab = -grad_b W_ba
      double gax = gx, gay = gy, gaz = gz, gbx = gx, gby = gy, gbz = gz;
      if constexpr (Kgc) {  // L_a grad_a W_ab for a, -(L_b grad_b W_ba) for b
        gax = la[0] * gx + la[1] * gy + la[2] * gz;
        gay = la[1] * gx + la[3] * gy + la[4] * gz;
        gaz = la[2] * gx + la[4] * gy + la[5] * gz;
        gbx = v.kgc[0][j] * gx + v.kgc[1][j] * gy + v.kgc[2][j] * gz;
        gby = v.kgc[1][j] * gx + v.kgc[3][j] * gy + v.kgc[4][j] * gz;
        gbz = v.kgc[2][j] * gx + v.kgc[4][j] * gy + v.kgc[5][j] * gz;
      }
      const double mb = v.mass[j];
      // Momentum (eq. 2): a_a -= m_b T grad_a W_ab,  a_b -= m_a T grad_b W_ba.
      axa -= mb * pterm * gax; aya -= mb * pterm * gay; aza -= mb * pterm * gaz;
      v.ax[j] += ma * pterm * gbx; v.ay[j] += ma * pterm * gby; v.az[j] += ma * pterm * gbz;
      // Continuity (eq. 4): v_ba . grad_b W_ba = v_ab . (-grad_b W_ba).
      drhoa += mb * (dvx * gax + dvy * gay + dvz * gaz);
      v.drho[j] += ma * (dvx * gbx + dvy * gby + dvz * gbz);
      // XSPH (eq. 6) between fluid particles only: walls must not drag the
      // positions of the fluid (as in SPHysics and DualSPHysics).
      const double xs = eps * w * inv_rho_bar * fluid_a * v.is_fluid[j];
      uxa -= mb * xs * dvx; uya -= mb * xs * dvy; uza -= mb * xs * dvz;
      v.ux[j] += ma * xs * dvx; v.uy[j] += ma * xs * dvy; v.uz[j] += ma * xs * dvz;
    }
    v.ax[i] += axa; v.ay[i] += aya; v.az[i] += aza; v.drho[i] += drhoa;
    v.ux[i] += uxa; v.uy[i] += uya; v.uz[i] += uza;
    max_mu = mu_max;
  }
};

static_assert(PairOperation<ForceOp<false>> && PairOperation<ForceOp<true>> && PairOperation<ForceOp<false, false>>);

}  // namespace sphnl
