#pragma once
// The physics of SPHysics' formulation (paper §2.1, docs/PHYSICS.md): constants,
// the equation of state (eq. 5) and per-particle derived quantities.
#include <cmath>
#include <cstddef>

#include "sphnl/kernel.hpp"
#include "sphnl/particles.hpp"

namespace sphnl {

struct PhysicsParams {
  double rho0 = 1000.0;
  double gravity = 9.81;           // g = (0, 0, -gravity), fluid only
  double depth = 0.30;             // H: maximum still-water depth, sets c0
  double sound_speed_coef = 10.0;  // c0 = coef * sqrt(g H)
  double c0 = 0, b_eos = 0;        // c0 and B = c0^2 rho0 / gamma
  static constexpr double gamma = 7.0;
  double alpha = 0.1;              // artificial viscosity (eq. 3), beta = 0
  double eta2 = 0;                 // 0.01 h^2
  double xsph_epsilon = 0.5;       // eq. 6
  double cfl = 0.3;                // eq. 7
  bool clamp_boundary_density = false;
  CubicSpline kernel;

  static PhysicsParams make(double h, double depth, double sound_speed_coef, double alpha,
                            double xsph_epsilon, double cfl, bool clamp_boundary_density) {
    PhysicsParams p;
    p.depth = depth;
    p.sound_speed_coef = sound_speed_coef;
    p.c0 = sound_speed_coef * std::sqrt(p.gravity * depth);
    p.b_eos = p.c0 * p.c0 * p.rho0 / gamma;
    p.alpha = alpha;
    p.eta2 = 0.01 * h * h;
    p.xsph_epsilon = xsph_epsilon;
    p.cfl = cfl;
    p.clamp_boundary_density = clamp_boundary_density;
    p.kernel = CubicSpline(h);
    return p;
  }
  double h() const { return kernel.h; }

  /// Tait equation of state, eq. 5: P = B [(rho/rho0)^7 - 1].
  double pressure(double rho) const {
    const double r = rho / rho0, r2 = r * r, r3 = r2 * r;
    return b_eos * (r3 * r3 * r - 1.0);
  }
  /// c = c0 (rho/rho0)^3, the sound speed consistent with eq. 5.
  double sound_speed(double rho) const {
    const double r = rho / rho0;
    return c0 * r * r * r;
  }
  /// Density whose pressure is rho0 g d (hydrostatic initial condition).
  double hydrostatic_density(double depth_below_surface) const {
    return rho0 * std::pow(1.0 + rho0 * gravity * depth_below_surface / b_eos, 1.0 / gamma);
  }
};

/// Recomputes P, c, P/rho^2 and the tensile coefficient R (Monaghan 2000) of
/// particles [begin, end) from their density.
inline void update_derived(const PhysicsParams& phys, ParticleSet& ps, std::size_t begin, std::size_t end) {
  for (std::size_t i = begin; i < end; ++i) {
    const double rho = ps.rho[i];
    const double p = phys.pressure(rho);
    const double inv_rho2 = 1.0 / (rho * rho);
    ps.pressure[i] = p;
    ps.sound_speed[i] = phys.sound_speed(rho);
    ps.p_over_rho2[i] = p * inv_rho2;
    ps.tensile_r[i] = (p > 0 ? 0.01 * p : -0.2 * p) * inv_rho2;
    ps.is_fluid[i] = ps.type[i] == ParticleType::fluid ? 1.0 : 0.0;
  }
}

}  // namespace sphnl
