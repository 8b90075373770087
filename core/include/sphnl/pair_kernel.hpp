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

#include "sphnl/neighbours/pair_filter.hpp"
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
    const Constants c(*phys);
    const Home<T> a(v, i);
    // Every reduction in the view's type, mu_max too: GCC sizes the omp simd
    // reductions' lane arrays per type, and with double sums beside a float
    // maximum (a Verlet list's loop in precision=mixed) it finds no vector
    // type for the mix and leaves the loop scalar.
    Sum<T> axa = 0, aya = 0, aza = 0, drhoa = 0, uxa = 0, uya = 0, uza = 0;
    Sum<T> mu_max = static_cast<Sum<T>>(max_mu);
#pragma omp simd reduction(+ : axa, aya, aza, drhoa, uxa, uya, uza) reduction(max : mu_max) if(simd : Simd)
    for (int p = 0; p < n; ++p) {
      const Terms t = pair(c, a, v, gather_index(js[p]), true);
      axa -= t.ax; aya -= t.ay; aza -= t.az; drhoa += t.drho;
      uxa -= t.ux; uya -= t.uy; uza -= t.uz;
      const Sum<T> mu_abs = std::fabs(static_cast<Sum<T>>(t.mu));
      mu_max = mu_max < mu_abs ? mu_abs : mu_max;
    }
    finish(v, i, axa, aya, aza, drhoa, uxa, uya, uza, mu_max);
  }

  /// `pair_loop=masked` on a Verlet list: particle i against every stored
  /// candidate js[0..n) (all distinct, none boundary-boundary), the distance
  /// test 1e-18 < r^2 < support2 a lane mask in the same vector loop instead
  /// of a compaction pass before it. r^2 is rounded as filter_list rounds
  /// it, so exactly its survivors are pairs; the others contribute exact
  /// zeros. Returns the number of pairs.
  template <class T>
  int interact_candidates(const BasicParticleView<T>& v, std::uint32_t i, const std::uint32_t* __restrict js, int n,
                          double support2) {
    const Constants c(*phys);
    const Home<T> a(v, i);
    Sum<T> axa = 0, aya = 0, aza = 0, drhoa = 0, uxa = 0, uya = 0, uza = 0;
    Sum<T> mu_max = static_cast<Sum<T>>(max_mu);
    Sum<T> pairs = 0;  // in the sums' type: a mix of types keeps GCC from vectorising (above)
#pragma omp simd reduction(+ : axa, aya, aza, drhoa, uxa, uya, uza, pairs) reduction(max : mu_max) if(simd : Simd)
    for (int p = 0; p < n; ++p) {
      const bool live = within_support(a, v, gather_index(js[p]), support2);
      const Terms t = pair(c, a, v, gather_index(js[p]), live);
      axa -= t.ax; aya -= t.ay; aza -= t.az; drhoa += t.drho;
      uxa -= t.ux; uya -= t.uy; uza -= t.uz;
      const Sum<T> mu_abs = std::fabs(static_cast<Sum<T>>(t.mu));
      mu_max = mu_max < mu_abs ? mu_abs : mu_max;
      pairs += live ? Sum<T>(1) : Sum<T>(0);
    }
    finish(v, i, axa, aya, aza, drhoa, uxa, uya, uza, mu_max);
    return static_cast<int>(pairs);
  }

  /// `pair_loop=masked`: particle i against whole blocks of kPairBlock
  /// consecutive entries, block b starting at first[b], its lane k a pair
  /// when bit k of lanes[b] is set (filter_blocks). Every lane is evaluated
  /// with plain vector loads and stores, no gather or scatter; the lanes
  /// that are not pairs contribute exact zeros. Entries up to first[b] + 7
  /// must be readable and finite (the gather buffer's slack).
  template <class T>
  void interact_blocks(const BasicParticleView<T>& v, std::uint32_t i, const std::uint32_t* __restrict first,
                       const std::uint8_t* __restrict lanes, int blocks) {
    const Constants c(*phys);
    const Home<T> a(v, i);
    // Per-lane partial sums across the blocks: one horizontal sum per
    // particle i, not one per block.
    Sum<T> acc[7][kPairBlock] = {};
    Real mu_lane[kPairBlock] = {};
    using Lane = BlockLane<Real>;
    for_each_block_lane<Simd, Real>(first, lanes, blocks, [&](Lane p, std::size_t j, bool live) SPHNL_INLINE_LANE {
      const Terms t = pair(c, a, v, j, live);
      acc[0][p] -= t.ax; acc[1][p] -= t.ay; acc[2][p] -= t.az; acc[3][p] += t.drho;
      acc[4][p] -= t.ux; acc[5][p] -= t.uy; acc[6][p] -= t.uz;
      const R mu_abs = std::fabs(t.mu);
      mu_lane[p] = mu_lane[p] < mu_abs ? mu_abs : mu_lane[p];
    });
    Sum<T> total[7] = {};
    Real mu_max = static_cast<Real>(max_mu);
    for (int p = 0; p < kPairBlock; ++p) {
      for (int q = 0; q < 7; ++q) total[q] += acc[q][p];
      mu_max = std::max(mu_max, mu_lane[p]);
    }
    finish(v, i, total[0], total[1], total[2], total[3], total[4], total[5], total[6], mu_max);
  }

 private:
  using R = Real;
  // The view's own type: double sums for double views, float partial sums for
  // the buffer's float copy.
  template <class T>
  using Sum = T;

  /// The constants of the pair, in the pair's arithmetic.
  struct Constants {
    CubicSpline::Polynomials<R> k;  // a local copy: the stores of the loop cannot alias it
    R h, inv_h, inv_w_dp, eta2, alpha, eps;
    explicit Constants(const PhysicsParams& ph)
        : k(ph.kernel.polynomials<R>()), h(static_cast<R>(ph.kernel.h)), inv_h(static_cast<R>(ph.kernel.inv_h)), inv_w_dp(static_cast<R>(ph.kernel.inv_w_dp)),
          eta2(static_cast<R>(ph.eta2)), alpha(static_cast<R>(ph.alpha)), eps(static_cast<R>(ph.xsph_epsilon)) {}
  };

  /// What the loop over i's partners reads of particle i.
  template <class T>
  struct Home {
    T x, y, z, vx, vy, vz;
    R rho, m, pr, tr, c, fluid;
    R l[6] = {1, 0, 0, 1, 0, 1};
    Home(const BasicParticleView<T>& v, std::uint32_t i)
        : x(v.x[i]), y(v.y[i]), z(v.z[i]), vx(v.vx[i]), vy(v.vy[i]), vz(v.vz[i]), rho(static_cast<R>(v.rho[i])),
          m(static_cast<R>(v.mass[i])), pr(static_cast<R>(v.p_over_rho2[i])), tr(static_cast<R>(v.tensile_r[i])),
          c(static_cast<R>(v.sound_speed[i])), fluid(static_cast<R>(v.is_fluid[i])) {
      if constexpr (Kgc)
        for (int k = 0; k < 6; ++k) l[k] = static_cast<R>(v.kgc[k][i]);
    }
  };

  /// Particle i's terms of one pair, to be subtracted (ax..az, ux..uz) or
  /// added (drho) to its sums; mu for the time step.
  struct Terms {
    R ax, ay, az, drho, ux, uy, uz, mu;
  };

  /// The one pair: (i, j) with r < 2h, applied to j in place and returned for
  /// i; j is a gather_index (compacted loop) or a size_t (masked loop). With
  /// `live` false (a lane of a block that is not a pair) every term is an
  /// exact zero; r^2 is replaced first so nothing divides by zero.
  template <class T, class Index>
  [[gnu::always_inline]] static inline Terms pair(const Constants& c, const Home<T>& a, const BasicParticleView<T>& v,
                                                  Index j, bool live) {
    const R dx = static_cast<R>(a.x - v.x[j]), dy = static_cast<R>(a.y - v.y[j]), dz = static_cast<R>(a.z - v.z[j]);
    const R r2_pair = dx * dx + dy * dy + dz * dz;
    const R r2 = live ? r2_pair : R(1);
    const R r = std::sqrt(r2), inv_r = R(1) / r;
    const R q = r * c.inv_h;
    // Kernel (eq. 1) and F = (dW/dr)/r; both branches computed, then selected.
    const R w = live ? c.k.w_of_q(q) : R(0);
    const R f = live ? c.k.dwdr_of_q(q) * inv_r : R(0);
    // Tensile correction (Monaghan 2000): (R_a + R_b) (W/W(dp))^4, plain W.
    const R fw = w * c.inv_w_dp, fw2 = fw * fw;
    const R dvx = static_cast<R>(a.vx - v.vx[j]), dvy = static_cast<R>(a.vy - v.vy[j]),
            dvz = static_cast<R>(a.vz - v.vz[j]);
    const R vdotr = dvx * dx + dvy * dy + dvz * dz;
    const R mu = live ? c.h * vdotr / (r2 + c.eta2) : R(0);
    const R rho_bar = R(0.5) * (a.rho + static_cast<R>(v.rho[j]));
    const R inv_rho_bar = R(1) / rho_bar;
    // Read for every pair, outside the select below: a load made only for
    // approaching pairs is a masked gather in the compacted loop, which GCC 12
    // emulates and then cannot mask, so it left that whole loop scalar in
    // double (docs/PERFORMANCE.md, "The compacted loop in double"). Halving
    // is exact, so the value is the same bit for bit.
    const R c_bar = R(0.5) * (a.c + static_cast<R>(v.sound_speed[j]));
    // Artificial viscosity (eq. 3), beta = 0: only approaching pairs.
    const R pi_ab = vdotr < R(0) ? -c.alpha * c_bar * mu * inv_rho_bar : R(0);
    const R pterm = a.pr + static_cast<R>(v.p_over_rho2[j]) + (a.tr + static_cast<R>(v.tensile_r[j])) * fw2 * fw2 + pi_ab;

    const R gx = f * dx, gy = f * dy, gz = f * dz;  // grad_a W_ab = -grad_b W_ba
    R gax = gx, gay = gy, gaz = gz, gbx = gx, gby = gy, gbz = gz;
    if constexpr (Kgc) {  // L_a grad_a W_ab for a, -(L_b grad_b W_ba) for b
      const R* la = a.l;
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
    const R tb = mb * pterm, ta = a.m * pterm;
    Terms t;
    t.ax = tb * gax; t.ay = tb * gay; t.az = tb * gaz;
    v.ax[j] += ta * gbx; v.ay[j] += ta * gby; v.az[j] += ta * gbz;
    // Continuity (eq. 4): v_ba . grad_b W_ba = v_ab . (-grad_b W_ba).
    t.drho = mb * (dvx * gax + dvy * gay + dvz * gaz);
    v.drho[j] += a.m * (dvx * gbx + dvy * gby + dvz * gbz);
    // XSPH (eq. 6) between fluid particles only: walls must not drag the
    // positions of the fluid (as in SPHysics and DualSPHysics).
    const R xs = c.eps * w * inv_rho_bar * a.fluid * static_cast<R>(v.is_fluid[j]);
    const R xb = mb * xs, xa_ = a.m * xs;
    t.ux = xb * dvx; t.uy = xb * dvy; t.uz = xb * dvz;
    v.ux[j] += xa_ * dvx; v.uy[j] += xa_ * dvy; v.uz[j] += xa_ * dvz;
    t.mu = mu;
    return t;
  }

  /// The distance test of filter_list, on one lane: 1e-18 < r^2 < support2
  /// with r^2 in double, rounded as distance2().
  template <class T, class Index>
  [[gnu::always_inline]] static inline bool within_support(const Home<T>& a, const BasicParticleView<T>& v, Index j,
                                                           double support2) {
    const double r2 = distance2(static_cast<double>(a.x) - static_cast<double>(v.x[j]),
                                static_cast<double>(a.y) - static_cast<double>(v.y[j]),
                                static_cast<double>(a.z) - static_cast<double>(v.z[j]));
    return (r2 < support2) & (r2 > CubicSpline::kMinR2);
  }

  template <class T>
  void finish(const BasicParticleView<T>& v, std::uint32_t i, Sum<T> axa, Sum<T> aya, Sum<T> aza, Sum<T> drhoa,
              Sum<T> uxa, Sum<T> uya, Sum<T> uza, Sum<T> mu_max) {
    v.ax[i] += axa; v.ay[i] += aya; v.az[i] += aza; v.drho[i] += drhoa;
    v.ux[i] += uxa; v.uy[i] += uya; v.uz[i] += uza;
    max_mu = mu_max;
  }
};

static_assert(PairOperation<ForceOp<false>> && PairOperation<ForceOp<true>> && PairOperation<ForceOp<false, false>> &&
              PairOperation<ForceOp<false, true, float>>);

}  // namespace sphnl
